"""``aamtrack fit INPUT``: fit every image of a file, folder or quoted glob on its own (a detection on each), as
OpenFace's image tool does for stills; one CSV row per image, a JSON summary, optionally one .pts per fit."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tqdm import tqdm

from ..errors import InputError
from ..io.atomic import OutputSet
from ..io.csvout import TrackingCsvWriter
from ..io.frames import ImageFrames, display_name, open_frames
from ..io.pts import write_pts
from ..io.summary import write_summary_json
from ..model import load_model
from ..models import default_model_path
from ..track.replay import ReplayFrame
from ..track.tracker import Tracker
from .run import model_and_output_arguments, output_base, output_dir

EXAMPLES = """examples:
  aamtrack fit photo.jpg
  aamtrack fit photos/ --out-dir fits --pts
  aamtrack fit 'shots/*.png' --kind 2d"""


def register(sub) -> None:
    p = sub.add_parser("fit", help="fit the face in each of a set of still images, independently",
                       description="Fit the largest face of every image (a file, a folder read in name order, or "
                                   "a quoted glob), each on its own from its own face detection. Writes "
                                   "<name>.csv (a 'file' column, then the columns of 'aamtrack run') and "
                                   "<name>.json in the output folder.",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="image file, folder of images, or a quoted glob such as 'photos/*.jpg'")
    model_and_output_arguments(p)
    p.add_argument("--pts", action="store_true", help="also write one iBUG .pts file per fitted image "
                   "(<out-dir>/<name>_pts/<image stem>.pts)")
    p.add_argument("--no-mirror", action="store_true", help="fit each image once; by default the mirrored image "
                   "is fitted too and the two fits' points averaged (more accurate, twice the time)")
    p.set_defaults(func=run)


def fit_images(input_: str, *, model_path: Path, out_dir: Path, pts: bool = False, progress: bool = True,
               mirror: bool = True) -> dict:
    """Fit each image of ``input_`` (``Tracker.fit_still``: with ``mirror``, the mirrored image too, the points
    averaged) and write the outputs; returns the summary. The input and the output folder
    are checked before the work, and all outputs are committed together at the end (``io.atomic.OutputSet``)."""
    t_start = time.perf_counter()
    source = open_frames(input_)
    if not isinstance(source, ImageFrames):
        source.close()
        raise InputError(f"{display_name(input_)}: a video; 'aamtrack fit' takes images "
                         "(track videos with 'aamtrack run')")
    with source, OutputSet(out_dir) as outputs:
        model = load_model(model_path)
        tracker = Tracker(model)
        outputs.prepare()
        stem = output_base(input_)[1]
        folder = outputs.folder
        csv_path, json_path = folder / f"{stem}.csv", folder / f"{stem}.json"
        pts_tmp = outputs.folder_output(f"{stem}_pts") if pts else None
        sm = model.shape
        is3d = sm.kind == "3d"
        counts = dict(images=0, fitted=0, rejected=0, no_face=0, unreadable=0)
        with TrackingCsvWriter(outputs.file(csv_path.name), anim_names=sm.coef_names if is3d else (),
                               shape_names=sm.shape_names if is3d else sm.coef_names, with_3d=is3d,
                               leading=("file",)) as csv_w:
            for frame in tqdm(source, total=source.n_frames, unit="img", file=sys.stderr,
                              disable=not progress or None, desc=display_name(stem)):
                path = source.paths[frame.index]
                res = tracker.fit_still(ReplayFrame(frame.index, 0.0, frame.image), mirror=mirror)
                csv_w.write(res, leading=(display_name(path.name),))
                counts["images"] += 1
                if res.status == "unreadable":
                    counts["unreadable"] += 1
                elif res.success:
                    counts["fitted"] += 1
                    if pts_tmp is not None:
                        write_pts(pts_tmp / f"{path.stem}.pts", res.landmarks)
                elif "search" in res.timings:
                    counts["rejected"] += 1
                else:
                    counts["no_face"] += 1
        if counts["fitted"] == 0:  # bad input: one line, nothing written
            which = f"any of its {counts['images']} images" if counts["images"] > 1 else "it"
            raise InputError(f"{display_name(input_)}: no face fitted in {which} ({counts['rejected']} rejected, "
                             f"{counts['no_face']} without a face found, {counts['unreadable']} unreadable)")
        summary = {"input": display_name(input_), "model": str(model_path), "model_kind": sm.kind, "mirror": mirror,
                   **counts, "wall_s": time.perf_counter() - t_start,
                   "outputs": {"csv": str(csv_path), "summary": str(json_path),
                               **({"pts": str(folder / f"{stem}_pts")} if pts else {})}}
        write_summary_json(outputs.file(json_path.name), summary)
        outputs.commit()
    return summary


def run(args: argparse.Namespace) -> int:
    model_path = args.model or default_model_path(args.kind)
    s = fit_images(args.input, model_path=model_path, out_dir=output_dir(args.input, args.out_dir), pts=args.pts,
                   mirror=not args.no_mirror)
    print(f"{s['images']} images: {s['fitted']} fitted, {s['rejected']} rejected (low confidence), "
          f"{s['no_face']} without a face found, {s['unreadable']} unreadable -> "
          + ", ".join(display_name(v) for v in s["outputs"].values()))
    return 0
