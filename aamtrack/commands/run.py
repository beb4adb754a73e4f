"""``aamtrack run INPUT``: track the face in a recorded video or a folder/glob of frames; write a CSV (one row
per frame), a JSON summary and optionally an overlay video and per-frame .pts files."""

from __future__ import annotations

import argparse
import glob
import logging
import os
import sys
import time
from pathlib import Path

from tqdm import tqdm

from ..errors import InputError
from ..io.csvout import TrackingCsvWriter
from ..io.atomic import OutputSet
from ..io.frames import display_name, open_frames
from ..io.overlay import OverlayWriter
from ..io.pts import write_pts_per_frame
from ..io.summary import write_summary_json
from ..model import load_model
from ..models import default_model_path
from ..track.replay import realtime
from ..track.timing import ms_stats, timed
from ..track.tracker import Tracker

log = logging.getLogger(__name__)


def register(sub) -> None:
    p = sub.add_parser("run", help="track a face in a video file or a folder of frames",
                       description="Track the largest face in a recorded video (or a folder / glob of images read "
                                   "in name order) and write one CSV row per frame plus a JSON summary.")
    p.add_argument("input", help="video file, folder of images, or a quoted glob such as 'frames/*.png'")
    p.add_argument("--model", type=Path, help="model file (default: the shipped 3D model)")
    p.add_argument("--kind", choices=("3d", "2d"), default="3d", help="which shipped model when --model is not given")
    p.add_argument("--out-dir", type=Path, help="output folder (default: <input>_aamtrack next to the input)")
    p.add_argument("--video", action="store_true", help="also write an overlay video with the fitted mesh")
    p.add_argument("--pts", action="store_true", help="also write one iBUG .pts file per tracked frame")
    p.add_argument("--realtime", action="store_true",
                   help="replay at the video's frame rate; frames that arrive while the tracker is busy are dropped")
    p.add_argument("--fps", type=float, help="frame rate of an image folder (default 25)")
    p.set_defaults(func=run)


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


def track_file(input_: str, *, model_path: Path, out_dir: Path, overlay: bool = False, pts: bool = False,
               replay: bool = False, fps: float | None = None, progress: bool = True) -> dict:
    """Track one input and write its outputs; returns the summary. The input and the output folder are checked
    before the work; every output is written under a temporary name and all are committed together at the
    end, so a failed or interrupted run leaves nothing behind (and earlier outputs as they were)."""
    t_start = time.perf_counter()
    source = open_frames(input_, fps=fps)
    with source, OutputSet(out_dir) as outputs:
        summary = _track(source, outputs, input_, t_start=t_start, model_path=model_path, overlay=overlay,
                         pts=pts, replay=replay, progress=progress)
        outputs.commit()
    return summary


def _track(source, outputs: OutputSet, input_: str, *, t_start: float, model_path: Path, overlay: bool,
           pts: bool, replay: bool, progress: bool) -> dict:
    model = load_model(model_path)
    tracker = Tracker(model)
    outputs.prepare()
    out_dir = outputs.folder
    stem = output_base(input_)[1]
    csv_path, json_path = out_dir / f"{stem}.csv", out_dir / f"{stem}.json"
    pts_dir = outputs.folder_output(f"{stem}_pts") if pts else None
    sm = model.shape
    is3d = sm.kind == "3d"
    counts = dict(read=0, tracked=0, detected=0, lost=0, dropped=0, unreadable=0)
    t_decode, per_frame = [], {"detect": [], "pyramid": [], "search": [], "output": []}
    frames = realtime(timed(source, t_decode), source.fps) if replay else timed(source, t_decode)
    t_first = None
    with TrackingCsvWriter(outputs.file(csv_path.name), anim_names=sm.coef_names if is3d else (),
                           shape_names=sm.shape_names if is3d else sm.coef_names, with_3d=is3d) as csv_w:
        ov_tmp = outputs.file(f"{stem}_overlay.mp4") if overlay else None
        ov = OverlayWriter(ov_tmp, source.fps, (source.width, source.height),
                           triangles=sm.triangles) if overlay else None
        try:
            bar = tqdm(total=source.n_frames, unit="frame", file=sys.stderr, disable=not progress or None,
                       desc=display_name(stem))
            images = {}
            for res in tracker.track(_remember(frames, images) if ov else frames):
                t_first = t_first or time.perf_counter()
                t = time.perf_counter()
                csv_w.write(res)
                if ov is not None:
                    ov.write(images.pop(res.frame, None), res)
                if pts and res.success:
                    write_pts_per_frame(pts_dir, res)
                per_frame["output"].append(time.perf_counter() - t)
                for k in ("detect", "pyramid", "search"):
                    if k in res.timings:
                        per_frame[k].append(res.timings[k])
                counts["read"] += 1
                counts[res.status] += 1
                bar.update(1)
            bar.close()
        except BaseException:
            if ov is not None:
                ov.abort()
            raise
        if ov is not None:
            ov.close()
            video_path = outputs.written(ov_tmp, ov.path)  # .avi if the writer fell back to MJPG
    if counts["read"] == 0:
        raise InputError(f"{input_}: no frames")
    wall = time.perf_counter() - t_start

    track_times = [a + b for a, b in zip(per_frame["pyramid"], per_frame["search"], strict=False)]
    summary = {
        "input": str(input_), "model": str(model_path), "model_kind": sm.kind,
        "frames_read": counts["read"], "frames_tracked": counts["tracked"] + counts["detected"],
        "frames_lost": counts["lost"], "frames_dropped": counts["dropped"], "frames_unreadable": counts["unreadable"],
        "detections": counts["detected"], "re_detections": max(0, counts["detected"] - 1),
        "realtime": replay, "video_fps": source.fps,
        "timing_ms": {"decode": ms_stats(t_decode), **{k: ms_stats(v) for k, v in per_frame.items()},
                      "track": ms_stats(track_times)},
        "start_to_first_result_s": (t_first - t_start) if t_first else None,
        "wall_s": wall, "fps_end_to_end": counts["read"] / wall,
        "outputs": {"csv": str(csv_path), "summary": str(json_path)},
    }
    if ov is not None:
        summary["outputs"]["video"] = str(video_path)
    if pts:
        summary["outputs"]["pts"] = str(out_dir / f"{stem}_pts")
    write_summary_json(outputs.file(json_path.name), summary)
    return summary


def _remember(frames, images: dict):
    for f in frames:
        images[f.index] = f.image
        yield f


def run(args: argparse.Namespace) -> int:
    model_path = args.model or default_model_path(args.kind)
    s = track_file(args.input, model_path=model_path, out_dir=output_dir(args.input, args.out_dir),
                   overlay=args.video, pts=args.pts, replay=args.realtime, fps=args.fps)
    print(f"{s['frames_read']} frames: {s['frames_tracked']} tracked, {s['frames_lost']} lost, "
          f"{s['frames_dropped']} dropped, {s['frames_unreadable']} unreadable, {s['re_detections']} re-detections; "
          f"{s['fps_end_to_end']:.0f} fps end to end -> {display_name(s['outputs']['csv'])}")
    if s["frames_tracked"] == 0:
        print(f"aamtrack run: warning: no face found in any frame of {display_name(args.input)}", file=sys.stderr)
    return 0
