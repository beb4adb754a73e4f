"""Per-frame timing of the tracker on a recorded input at several resolutions (``aamtrack bench``).

Stages per frame: decode (reading and resizing the frame), detect (Haar, only on frames without a track),
pyramid (crop, pyramid, contrast normalisation), search (all couples), output (CSV row). Numba compile /
cache-load time is measured apart by a warm-up before the first frame. Single-core by default: OpenCV is
asked for one thread and numba kernels are serial.
"""

from __future__ import annotations

import itertools
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from ..io.csvout import TrackingCsvWriter
from ..io.frames import open_frames
from ..model import load_model
from .events import annotate
from .pipeline import grey_frames, run_pipeline
from .smooth import SmoothConfig, smooth_results
from .timing import ms_stats, timed
from .tracker import Tracker


def warmup(tracker: Tracker) -> float:
    """Compile (or load from numba's cache) every kernel the tracker uses; returns seconds. A fit of an image of
    noise runs the search's kernels and the landmark cascade's (as for a noisy face, whose descriptors are read
    smoothed: ``landmark_cascade.descriptor_view``); what a tracked frame does with a fit then (its next start,
    the person's shape estimate, the reported pose, the shape check) runs on that fit too, so that no kernel is
    left to compile on a video's first tracked frame (about 6 s there on a first run, 2026-12-01) or a first
    noisy still."""
    t = time.perf_counter()
    noise = np.random.default_rng(0).normal(0.0, 20.0, (240, 320))  # (noise: a noisy face's path, smoothed)
    img = np.clip(128.0 + noise, 0, 255).astype(np.uint8)
    res, _ = tracker.fit_roi(img, tracker.detection_starts((110.0, 70.0, 100.0, 100.0)))
    tracker.tracked_start(res)
    tracker.shape_sample(res)
    tracker.reported_pose(res)
    if tracker.model.shape_prior is not None:
        tracker.model.shape_prior.score(res.landmarks)
    return time.perf_counter() - t


def bench_one(input_, model_path: Path, size: tuple[int, int], *, max_frames: int = 300) -> dict:
    """Timings of one model at one resolution over the first ``max_frames`` frames.

    Two passes over the same frames, each decoding as it goes (frames are streamed, never all held): first every
    stage in one thread, timed per frame (decode, detect, pyramid, search, output); then the pipelined run of
    ``aamtrack run`` (decoding ahead and smoothing + writing the CSV in threads), timed end to end."""
    model = load_model(model_path)
    tracker = Tracker(model)
    t_warm = warmup(tracker)
    sm = model.shape
    csv_args = dict(anim_names=sm.coef_names if sm.kind == "3d" else (),
                    shape_names=sm.shape_names if sm.kind == "3d" else sm.coef_names, with_3d=sm.kind == "3d")
    t_dec = []
    stages = {"detect": [], "pyramid": [], "search": [], "output": []}
    track_only, n, n_ok = [], 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        with open_frames(input_, resize=size) as src, TrackingCsvWriter(Path(tmp) / "b.csv", **csv_args) as w:
            t_all = time.perf_counter()
            for res in tracker.track(itertools.islice(timed(src, t_dec), max_frames)):
                t = time.perf_counter()
                w.write(res)
                stages["output"].append(time.perf_counter() - t)
                for k in ("detect", "pyramid", "search"):
                    if k in res.timings:
                        stages[k].append(res.timings[k])
                if res.status == "tracked":
                    track_only.append(res.timings["pyramid"] + res.timings["search"])
                n += 1
                n_ok += res.success
            t_single = time.perf_counter() - t_all
        with open_frames(input_, resize=size) as src, TrackingCsvWriter(Path(tmp) / "p.csv", **csv_args) as w:
            t_all = time.perf_counter()
            times = run_pipeline(grey_frames(itertools.islice(src, max_frames)),
                                 lambda frames: annotate(tracker.track(frames)), w.write,
                                 smooth=lambda results: smooth_results(results, SmoothConfig()),
                                 depth=int(max(2, min(32, 64e6 // (3 * size[0] * size[1])))))  # ~64 MB ahead
            t_pipe = time.perf_counter() - t_all
    track_med = float(np.median(track_only)) if track_only else float("nan")
    return {
        "model": str(model_path), "kind": sm.kind, "size": f"{size[0]}x{size[1]}", "frames": n,
        "frames_tracked": int(n_ok), "warmup_s": t_warm,
        "ms": {"decode": ms_stats(t_dec), **{k: ms_stats(v) for k, v in stages.items()}, "track": ms_stats(track_only)},
        "fps_tracking": 1.0 / track_med if track_only else float("nan"),
        "fps_end_to_end": n / t_single if n else float("nan"),
        "fps_pipelined": times.n_frames / t_pipe if times.n_frames else float("nan"),
    }


def run_bench(input_, model_paths: list[Path], sizes: list[tuple[int, int]], *, max_frames: int = 300,
              threads: int = 1) -> list[dict]:
    cv2.setNumThreads(threads)
    return [bench_one(input_, m, s, max_frames=max_frames) for m in model_paths for s in sizes]


def format_table(rows: list[dict]) -> str:
    head = (f"{'model':<6}{'size':>10}{'frames':>7}{'ok':>6}{'warmup s':>9} | "
            + " | ".join(f"{k:^17}" for k in ("decode", "detect", "pyramid", "search", "output", "track"))
            + f" | {'fps track':>9}{'fps e2e':>8}{'pipelined':>10}")
    sub = " " * 38 + " | " + " | ".join(f"{'med':>5} {'p90':>5} {'max':>5}" for _ in range(6)) + " |"
    lines = [head, sub]
    for r in rows:
        cells = []
        for k in ("decode", "detect", "pyramid", "search", "output", "track"):
            s = r["ms"][k]
            cells.append(f"{s['median']:5.2f} {s['p90']:5.2f} {s['max']:5.1f}" if s else f"{'-':>17}")
        lines.append(f"{r['kind']:<6}{r['size']:>10}{r['frames']:>7}{r['frames_tracked']:>6}{r['warmup_s']:>9.2f} | "
                     + " | ".join(cells) + f" | {r['fps_tracking']:>9.0f}{r['fps_end_to_end']:>8.0f}"
                     f"{r['fps_pipelined']:>10.0f}")
    lines.append("times in ms per frame, all stages in one thread; 'track' = pyramid + search on frames already "
                 "tracked (face found);\n'fps e2e' = decode + track + CSV in one thread; 'pipelined' = as aamtrack "
                 "run: decoding ahead, smoothing and CSV in threads")
    return "\n".join(lines)
