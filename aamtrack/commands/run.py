"""``aamtrack run INPUT``: track the face in a recorded video or a folder/glob of frames; write a CSV (one row
per frame), a JSON summary and optionally an overlay video and per-frame .pts files."""

from __future__ import annotations

import argparse
import dataclasses
import glob
import logging
import os
import sys
import threading
import time
from collections import Counter
from pathlib import Path

from tqdm import tqdm

from ..errors import InputError
from .batch import default_jobs, expand_inputs, run_batch, run_options, summary_line
from ..io.csvout import TrackingCsvWriter
from ..io.atomic import OutputSet
from ..io.frames import display_name, open_frames
from ..io.overlay import OverlayWriter, mesh_edges
from ..io.pts import write_pts_per_frame
from ..io.summary import write_summary_json
from ..model import load_model
from ..models import default_model_path
from ..track.benchmark import warmup
from ..track.events import annotate, reason_kind
from ..track.replay import realtime
from ..track.smooth import SmoothConfig, smooth_results
from ..track.pipeline import grey_frames, keep_freed_memory, run_pipeline
from ..track.timing import ms_stats
from ..track.tracker import Tracker

log = logging.getLogger(__name__)
DEFAULT_SMOOTH = SmoothConfig()
READ_AHEAD_BYTES = 64e6


EPILOG = """examples:
  aamtrack run samples/cap12_first12s.mp4 --out-dir out/sample
  aamtrack run clip.mp4 --video --report          overlay video and report.html next to the CSV
  aamtrack run 'frames/*.png' --fps 30 --pts      a glob of images (quoted), one .pts per tracked frame
  aamtrack run clip.mp4 --kind 2d --no-smooth     the 2D model, raw (unsmoothed) landmarks
  aamtrack -v run clip.mp4                        log detections, re-detections and why frames were lost
  aamtrack run videos/ --out-dir out --jobs 2     every video in videos/, two at a time; out/batch.csv
  aamtrack run 'day*/*.mp4' --scheduler tcp://head:8786 --out-dir /shared/out   on a Dask cluster

outputs (in --out-dir, default <input>_aamtrack/ next to the input):
  <name>.csv            one row per frame: status, confidence, pose, 68 landmarks (and 3D points, units)
  <name>.json           summary: frames read / tracked / lost, re-detections, timings, outputs
  <name>_overlay.mp4    with --video: H.264 with PyAV installed (pip install "aamtrack[video]"), else
                        <name>_overlay.webm (OpenCV's VP8, several times slower to write)
  <name>_overlay.mp4    with --fast-video (mp4v)
  <name>_pts/           with --pts: one iBUG .pts file per tracked frame
  report.html           with --report: plots, lost stretches with thumbnails, summary (needs matplotlib)

a batch (several inputs, or a folder / glob of videos): each input's outputs in <out-dir>/<name>/ (its safe
stem; inputs sharing a stem get a hash of their path appended), and <out-dir>/batch.csv: input, frames,
tracked, lost, fps, status (done / skipped / failed), error. A failed input does not stop the others; the exit
status is 1 if any failed. Inputs finished by an earlier run with the same model and options are skipped
unless --overwrite. Several arguments need --out-dir.

smoothing: landmarks and pose pass through a One Euro filter (Casiez et al., CHI 2012), run forwards and, from
--smooth-look-ahead frames ahead, backwards, the two averaged (no lag; --realtime: forwards only), reset on every
detection and after lost frames. Lower --smooth-beta smooths more and lags more on slow motion; see README."""


def register(sub) -> None:
    p = sub.add_parser("run", help="track a face in a video file or a folder of frames",
                       description="Track the largest face in a recorded video (or a folder / glob of images read\n"
                                   "in name order) and write one CSV row per frame plus a JSON summary.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", nargs="+",
                   help="video file, folder of images, or a quoted glob such as 'frames/*.png'; several, or a "
                        "folder / glob of videos, make a batch (outputs in <out-dir>/<name>/, see below)")
    model_and_output_arguments(p)
    b = p.add_argument_group("many inputs (a batch)")
    b.add_argument("--jobs", type=int, metavar="N",
                   help=f"track N inputs at once in worker processes (default: the number of cores, "
                        f"{default_jobs()} here)")
    b.add_argument("--scheduler", metavar="ADDRESS",
                   help="send the inputs to a Dask distributed scheduler (tcp://host:8786), one task per input; the "
                        "workers write to --out-dir, which they must share (pip install 'aamtrack[dask]')")
    b.add_argument("--overwrite", action="store_true",
                   help="redo inputs already finished with the same model and options (default: skip them)")
    p.add_argument("--video", action="store_true",
                   help="also write an overlay video: mesh, landmarks, pose axes, frame number, status, confidence")
    p.add_argument("--fast-video", action="store_true",
                   help="the same overlay video in mp4v (.mp4): without PyAV about 10x faster to write than "
                        "OpenCV's VP8 (.webm), which bounds a run with --video at larger sizes; VLC, mpv and "
                        "QuickTime play it, web browsers do not (implies --video). With PyAV (pip install "
                        "\"aamtrack[video]\") --video writes H.264 about as fast")
    p.add_argument("--pts", action="store_true", help="also write one iBUG .pts file per tracked frame")
    p.add_argument("--report", action="store_true",
                   help="also write report.html: pose, animation units and confidence over time, lost and "
                        "low-confidence stretches with thumbnails (needs matplotlib: pip install 'aamtrack[plot]')")
    p.add_argument("--realtime", action="store_true",
                   help="replay at the video's frame rate; frames that arrive while the tracker is busy are dropped")
    p.add_argument("--fps", type=float, help="frame rate of an image folder (default 25)")
    d = SmoothConfig()
    p.add_argument("--no-smooth", action="store_true", help="write the raw tracker output (no One Euro smoothing)")
    p.add_argument("--smooth-min-cutoff", type=float, default=d.min_cutoff, metavar="HZ",
                   help=f"One Euro cutoff at rest; lower is calmer when still (default {d.min_cutoff:g})")
    p.add_argument("--smooth-beta", type=float, default=d.beta, metavar="BETA",
                   help=f"how fast the cutoff rises with speed (Hz per face width per second); higher lags less "
                        f"in motion, lower jitters less (default {d.beta:g})")
    p.add_argument("--smooth-look-ahead", type=int, default=d.look_ahead, metavar="N",
                   help=f"also filter backwards from N frames ahead and average, which takes out the filter's lag "
                        f"(0: forwards only, as --realtime always is) (default {d.look_ahead})")
    p.set_defaults(func=run)


def model_and_output_arguments(p) -> None:
    """--model, --kind and --out-dir, as run and fit take them."""
    p.add_argument("--model", type=Path, help="model file (default: the shipped 3D model)")
    p.add_argument("--kind", choices=("3d", "2d"), default="3d", help="which shipped model when --model is not given")
    p.add_argument("--out-dir", type=Path, help="output folder (default: <input>_aamtrack next to the input)")


def output_base(input_: str) -> tuple[Path, str]:
    """(folder the input lives in, name for its outputs): a file's stem, a folder's name, and for a glob
    pattern the name of the folder its matches are in (``'shots/*.png'`` -> ``shots``). A name that exists is
    never read as a pattern, so ``my video [1].mp4`` is a file."""
    src = Path(input_)
    if not os.path.lexists(input_) and glob.has_magic(input_):
        src = next((p for p in src.parents if not glob.has_magic(str(p))), Path("."))
        src = src.resolve() if src == Path(".") else src
        return src.parent, src.name or "frames"
    if src.is_dir():
        src = src.resolve() if src.name in ("", ".", "..") else src
        return src.parent, src.name or "frames"
    return src.parent, src.stem or src.name


def output_dir(input_: str, out_dir: Path | None) -> Path:
    if out_dir is not None:
        return out_dir
    parent, stem = output_base(input_)
    return parent / f"{stem}_aamtrack"


def track_file(input_: str, *, model_path: Path, out_dir: Path, overlay: bool | str = False, pts: bool = False,
               replay: bool = False, fps: float | None = None, progress: bool = True,
               smooth: SmoothConfig | None = DEFAULT_SMOOTH, report: bool = False, notify=None,
               name: str | None = None, pipelined: bool = True, on_frame=None, extra: dict | None = None,
               tracker: Tracker | None = None, decode_threads: int | None = None) -> dict:
    """Track one input and write its outputs; returns the summary. The input and the output folder are checked
    before the work; every output is written under a temporary name and all are committed together at the
    end, so a failed or interrupted run leaves nothing behind (and earlier outputs as they were).

    overlay: True for the overlay video, "fast" for it in mp4v (``OverlayWriter``'s ``fast``).
    smooth: One Euro smoothing of the results (None: raw tracker output). report: also write report.html
    (needs matplotlib). notify: called with a one-line message while numba compiles on a first run.
    name: stem of the output files (default: the input's, see :func:`output_base`). pipelined: decode ahead and
    write in threads (False: every stage in this thread; the same outputs). on_frame: called with 1 per frame
    (a batch's overall progress). extra: more entries for the summary (a batch's options record). tracker: a
    Tracker for ``model_path`` already made and warmed up (a batch worker keeps one). decode_threads: FFmpeg's
    decoding threads (default: one per core; see ``open_frames``)."""
    t_start = time.perf_counter()
    if report:
        from ..io.report import require_matplotlib

        require_matplotlib()
    source = open_frames(input_, fps=fps, decode_threads=decode_threads)
    with source, OutputSet(out_dir) as outputs:
        summary = _track(source, outputs, input_, t_start=t_start, model_path=model_path, overlay=overlay,
                         pts=pts, replay=replay, progress=progress, smooth=smooth, report=report, notify=notify,
                         name=name, pipelined=pipelined, on_frame=on_frame, extra=extra or {}, tracker=tracker)
        outputs.commit()
    return summary


def _track(source, outputs: OutputSet, input_: str, *, t_start: float, model_path: Path, overlay: bool | str,
           pts: bool, replay: bool, progress: bool, smooth, report: bool, notify, name, pipelined: bool, on_frame,
           extra: dict, tracker) -> dict:
    if replay and smooth is not None and smooth.look_ahead:  # a live clock gives no frames ahead
        smooth = dataclasses.replace(smooth, look_ahead=0)
    if tracker is None:
        tracker = Tracker(load_model(model_path))
        outputs.prepare()
        t_warm = _warm_up(tracker, notify)
    else:
        outputs.prepare()
        t_warm = 0.0
    model = tracker.model
    out_dir = outputs.folder
    stem = name or output_base(input_)[1]
    csv_path, json_path = out_dir / f"{stem}.csv", out_dir / f"{stem}.json"
    pts_dir = outputs.folder_output(f"{stem}_pts") if pts else None
    sm = model.shape
    is3d = sm.kind == "3d"
    counts = dict(read=0, tracked=0, detected=0, lost=0, dropped=0, unreadable=0, tracked_back=0)
    lost_by = Counter()  # lost frames by their reason's kind (``events.reason_kind``)
    per_frame = {"detect": [], "pyramid": [], "search": []}
    rep = None
    if report:
        from ..io.report import ReportBuilder

        rep = ReportBuilder(model_kind=sm.kind, anim_names=sm.coef_names if is3d else (),
                            min_confidence=tracker.config.min_confidence, edges=mesh_edges(sm.triangles))
    with TrackingCsvWriter(outputs.file(csv_path.name), anim_names=sm.coef_names if is3d else (),
                           shape_names=sm.shape_names if is3d else sm.coef_names, with_3d=is3d) as csv_w:
        ov_tmp = outputs.file(f"{stem}_overlay.mp4") if overlay else None
        ov = OverlayWriter(ov_tmp, source.fps, (source.width, source.height), triangles=sm.triangles,
                           fast=overlay == "fast") if overlay else None
        try:
            bar = tqdm(total=source.n_frames, unit="frame", file=sys.stderr, disable=not progress or None,
                       desc=display_name(stem))
            images = {}
            keep = ov is not None or rep is not None

            def results_of(frames):
                return annotate(tracker.track(_remember(frames, images) if keep else frames),
                                min_confidence=tracker.config.min_confidence)

            def write(res):  # the writer thread: CSV row, overlay frame, report, .pts
                csv_w.write(res)
                image = images.pop(res.frame, None) if keep else None
                if ov is not None:
                    ov.write(image, res)
                if rep is not None:
                    rep.add(res, image)
                if pts and res.success:
                    write_pts_per_frame(pts_dir, res)

            def on_result(res):  # the tracker's thread
                for k in ("detect", "pyramid", "search"):
                    if k in res.timings:
                        per_frame[k].append(res.timings[k])
                counts["read"] += 1
                counts[res.status] += 1
                counts["tracked_back"] += bool(res.success and res.reason)  # (tracked back from a detection)
                if res.status == "lost":
                    lost_by[reason_kind(res.reason)] += 1
                bar.update(1)
                if on_frame is not None:
                    on_frame(1)

            frames = source if keep else grey_frames(source)  # grey in the decoding thread when no colour is used
            # memory: about 64 MB of frames decoded ahead (32 at 640x480, 2 at 4K); with an overlay or a report
            # each result waiting for the writer holds its image, so few wait
            depth = int(max(2, min(32, READ_AHEAD_BYTES // max(1, source.width * source.height * 3))))
            times = run_pipeline(frames, results_of, write, depth=depth, write_depth=depth if keep else 64, on_result=on_result, pipelined=pipelined,
                                 smooth=(lambda s: smooth_results(s, smooth)) if smooth is not None else None,
                                 replay=(lambda f: realtime(f, source.fps)) if replay else None)
            bar.close()
        except BaseException:
            if ov is not None:
                ov.abort()
            raise
        if ov is not None:
            ov.close()
            video_path = outputs.written(ov_tmp, ov.path)  # another suffix if the writer fell back
    if counts["read"] == 0:
        raise InputError(f"{input_}: no frames")
    if counts["tracked"] + counts["detected"] == 0:  # bad input too: one line, nothing written
        if counts["unreadable"] + counts["dropped"] == counts["read"]:
            raise InputError(f"{input_}: none of its {counts['read']} frames could be searched "
                             f"({counts['unreadable']} unreadable, {counts['dropped']} dropped)")
        raise InputError(f"{input_}: no face found in any of its {counts['read']} frames" if counts["read"] > 1
                         else f"{input_}: no face found in its one frame")
    wall = time.perf_counter() - t_start

    track_times = [a + b for a, b in zip(per_frame["pyramid"], per_frame["search"], strict=False)]
    t_first = times.t_first
    summary = {
        "input": str(input_), "model": str(model_path), "model_kind": sm.kind,
        "frames_read": counts["read"], "frames_tracked": counts["tracked"] + counts["detected"],
        "frames_lost": counts["lost"], "frames_dropped": counts["dropped"], "frames_unreadable": counts["unreadable"],
        "detections": counts["detected"], "re_detections": max(0, counts["detected"] - 1),
        "frames_tracked_back": counts["tracked_back"],
        "frames_lost_by_reason": dict(sorted(lost_by.items(), key=lambda kv: -kv[1])),
        "realtime": replay, "video_fps": source.fps,
        "timing_ms": {"decode": ms_stats(times.decode), **{k: ms_stats(v) for k, v in per_frame.items()},
                      "output": ms_stats(times.output), "track": ms_stats(track_times)},
        "pipelined": pipelined,
        "thread_cpu_s": times.cpu_s,
        "start_to_first_result_s": (t_first - t_start) if t_first else None, "warmup_s": t_warm,
        "smoothing": None if smooth is None else {"filter": "one_euro", "min_cutoff_hz": smooth.min_cutoff,
                                                  "beta": smooth.beta, "d_cutoff_hz": smooth.d_cutoff,
                                                  "follow_jumps": smooth.follow_jumps,
                                                  "look_ahead_frames": smooth.look_ahead},
        "wall_s": wall, "fps_end_to_end": counts["read"] / wall,
        "outputs": {"csv": str(csv_path), "summary": str(json_path)},
        **extra,
    }
    if ov is not None:
        summary["outputs"]["video"] = str(video_path)
    if pts:
        summary["outputs"]["pts"] = str(out_dir / f"{stem}_pts")
    if rep is not None:
        summary["outputs"]["report"] = str(out_dir / "report.html")
        rep.write(outputs.file("report.html"), summary)
    write_summary_json(outputs.file(json_path.name), summary)
    return summary


def _warm_up(tracker: Tracker, notify, *, after: float = 1.5) -> float:
    """Compile (or load from numba's cache) the kernels before the first frame; if that takes longer than a
    cache load (``after`` seconds), ``notify`` says so while it runs (a first run compiles for several seconds)."""
    said = threading.Event()

    def say():
        said.set()
        notify("compiling kernels (first run only) ...")

    timer = threading.Timer(after, say) if notify is not None else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        seconds = warmup(tracker)
    finally:
        if timer is not None:
            timer.cancel()
    if said.is_set():
        notify(f"kernels ready in {seconds:.1f} s (cached for later runs)")
    return seconds


def _remember(frames, images: dict):
    for f in frames:
        images[f.index] = f.image
        yield f


def run(args: argparse.Namespace) -> int:
    keep_freed_memory()  # fewer page faults per frame (see there); batch workers inherit it
    model_path = args.model or default_model_path(args.kind)
    if args.jobs is not None and not 1 <= args.jobs <= 1024:
        raise InputError(f"--jobs {args.jobs}: expected a number of worker processes, 1 or more")
    if args.jobs is not None and args.scheduler is not None:
        raise InputError("--jobs and --scheduler exclude each other (the Dask cluster decides how many run at once)")
    items, batch = expand_inputs(args.input)
    batch = batch or args.scheduler is not None
    smooth = None
    if not args.no_smooth:
        try:
            smooth = SmoothConfig(min_cutoff=args.smooth_min_cutoff, beta=args.smooth_beta,
                                  look_ahead=args.smooth_look_ahead)
        except ValueError:
            raise InputError(f"--smooth-min-cutoff must be > 0, --smooth-beta >= 0 and --smooth-look-ahead >= 0, "
                             f"got {args.smooth_min_cutoff:g}, {args.smooth_beta:g} and "
                             f"{args.smooth_look_ahead}") from None
    if batch:
        return _run_batch(args, items, model_path, smooth)
    input_ = items[0]
    s = track_file(input_, model_path=model_path, out_dir=output_dir(input_, args.out_dir),
                   overlay=_overlay(args), pts=args.pts, replay=args.realtime, fps=args.fps, smooth=smooth,
                   report=args.report, notify=lambda text: print(text, file=sys.stderr, flush=True))
    print(f"{s['frames_read']} frames: {s['frames_tracked']} tracked, {s['frames_lost']} lost, "
          f"{s['frames_dropped']} dropped, {s['frames_unreadable']} unreadable, {s['re_detections']} re-detections; "
          f"{s['fps_end_to_end']:.0f} fps end to end -> {', '.join(_outputs(s['outputs']))}")
    return 0


def _run_batch(args, items: list[str], model_path: Path, smooth) -> int:
    if args.out_dir is None and len(args.input) > 1:
        raise InputError("several inputs need --out-dir (each input's outputs go to <out-dir>/<name>/)")
    out_dir = output_dir(args.input[0], args.out_dir)
    if args.report:
        from ..io.report import require_matplotlib

        require_matplotlib()
    options = run_options(model_path=model_path, overlay=_overlay(args), pts=args.pts, report=args.report,
                          replay=args.realtime, fps=args.fps, smooth=smooth)
    t0 = time.perf_counter()
    rows = run_batch(items, out_dir=out_dir, model_path=model_path, options=options,
                     jobs=args.jobs or default_jobs(), scheduler=args.scheduler, overwrite=args.overwrite,
                     say=lambda text: print(text, file=sys.stderr, flush=True))
    print(summary_line(rows, time.perf_counter() - t0, out_dir))
    return 1 if any(r["status"] == "failed" for r in rows) else 0


def _overlay(args: argparse.Namespace) -> bool | str:
    """``track_file``'s ``overlay`` from ``--video`` / ``--fast-video``."""
    return "fast" if args.fast_video else bool(args.video)


def _outputs(outputs: dict) -> list[str]:
    """Every output written, the folder's name once: 'out/a.csv', 'a.json', 'a_pts/ (20 files)', ..."""
    names = []
    for key in ("csv", "summary", "video", "pts", "report"):
        if key not in outputs:
            continue
        path = Path(outputs[key])
        text = display_name(path) if not names else display_name(path.name)
        if key == "pts":
            text += f"/ ({sum(1 for _ in path.glob('*.pts'))} files)"
        names.append(text)
    return names
