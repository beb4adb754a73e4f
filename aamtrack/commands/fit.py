"""``aamtrack fit INPUT``: fit every image of a file, folder or quoted glob on its own (a detection on each), as
OpenFace's image tool does for stills; one CSV row per image, a JSON summary, optionally one .pts per fit."""

from __future__ import annotations

import argparse
import sys
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from tqdm import tqdm

from ..errors import AamtrackError, InputError
from ..io.atomic import OutputSet
from ..io.csvout import TrackingCsvWriter
from ..io.frames import IMAGE_SUFFIXES, ImageFrames, display_name, open_frames, read_image
from ..io.pts import write_pts
from ..io.summary import write_summary_json
from ..model import load_model
from ..models import default_model_path
from ..result import FrameResult
from ..track.replay import ReplayFrame
from ..track.tracker import Tracker
from .batch import default_jobs, warm_tracker, worker_pool
from .run import model_and_output_arguments, output_base, output_dir

EXAMPLES = """examples:
  aamtrack fit photo.jpg
  aamtrack fit photos/ --out-dir fits --pts
  aamtrack fit 'shots/*.png' --kind 2d
  aamtrack fit photos/ --jobs 1                 one image at a time, in this process"""


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
    p.add_argument("--jobs", type=int, metavar="N",
                   help="images fitted at once, in worker processes (default: the number of cores, "
                        f"{default_jobs()} here); the outputs are the same for any N")
    p.set_defaults(func=run)


def _fit_image(tracker: Tracker, index: int, path: Path, readable: bool, mirror: bool) -> FrameResult:
    """Image ``index`` (the file ``path``) fitted on its own (``Tracker.fit_still``); a file that cannot be read
    (read here unless ``readable`` is False: one of the files before the first readable one, warned of already
    when the input was opened) gives its ``unreadable`` row."""
    image = read_image(path) if readable else None
    return tracker.fit_still(ReplayFrame(index, 0.0, image), mirror=mirror)


def _worker_fit(model_path: str, index: int, path: Path, readable: bool, mirror: bool) -> FrameResult:
    """``_fit_image`` in a worker process of ``--jobs N`` (its tracker made once per process, or inherited from
    the parent when forked)."""
    return _fit_image(warm_tracker(Path(model_path)), index, path, readable, mirror)


@contextmanager
def _fitting(tasks: list, tracker: Tracker, model_path: Path, jobs: int) -> Iterator[Iterator[FrameResult]]:
    """The fits of ``tasks`` ((index, path, readable, mirror) each), in their order: in this process, or with
    ``jobs`` > 1 in that many worker processes (``batch.worker_pool``: started on entering, before the caller
    starts a progress bar's thread; stopped on a failure in the ``with`` block)."""
    if jobs <= 1 or len(tasks) <= 1:
        yield (_fit_image(tracker, *task) for task in tasks)
        return
    warm_tracker(model_path)  # made and warmed up here, before the workers are forked: they start with it
    try:
        with worker_pool(min(jobs, len(tasks))) as (pool, _):
            yield _in_order(pool, tasks, model_path, jobs)
    except BrokenProcessPool as exc:  # a worker killed (out of memory, a signal): the run stops, nothing written
        raise AamtrackError(f"a worker process failed ({exc}); try fewer --jobs") from None


def _in_order(pool, tasks: list, model_path: Path, jobs: int) -> Iterator[FrameResult]:
    """The workers' fits of ``tasks`` in their order, at most two per worker queued ahead (each worker reads its
    own images)."""
    ahead = deque()
    for task in tasks:
        ahead.append(pool.submit(_worker_fit, str(model_path), *task))
        if len(ahead) >= 2 * jobs:
            yield ahead.popleft().result()
    while ahead:
        yield ahead.popleft().result()


def fit_images(input_: str, *, model_path: Path, out_dir: Path, pts: bool = False, progress: bool = True,
               mirror: bool = True, jobs: int = 1) -> dict:
    """Fit each image of ``input_`` (``Tracker.fit_still``: with ``mirror``, the mirrored image too, the points
    averaged) and write the outputs; returns the summary. ``jobs`` > 1 fits that many images at once in worker
    processes, with the same outputs (each image is fitted on its own). The input and the output folder
    are checked before the work, and all outputs are committed together at the end (``io.atomic.OutputSet``)."""
    t_start = time.perf_counter()
    try:
        source = open_frames(input_)
    except InputError:
        path = Path(input_)
        if path.is_file() and path.suffix.lower() not in IMAGE_SUFFIXES:  # tried as a video: say what fit wanted
            raise InputError(f"{display_name(input_)}: not an image OpenCV can read (nor a video)") from None
        raise
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
            tasks = [(k, path, k >= source.first_readable, mirror) for k, path in enumerate(source.paths)]
            with (_fitting(tasks, tracker, model_path, jobs) as fits,
                  tqdm(fits, total=len(tasks), unit="img", file=sys.stderr, disable=not progress or None,
                       desc=display_name(stem)) as bar):
                for path, res in zip(source.paths, bar):
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
                   "jobs": 1 if jobs <= 1 or len(tasks) <= 1 else min(jobs, len(tasks)),
                   **counts, "wall_s": time.perf_counter() - t_start,
                   "outputs": {"csv": str(csv_path), "summary": str(json_path),
                               **({"pts": str(folder / f"{stem}_pts")} if pts else {})}}
        write_summary_json(outputs.file(json_path.name), summary)
        outputs.commit()
    return summary


def run(args: argparse.Namespace) -> int:
    if args.jobs is not None and not 1 <= args.jobs <= 1024:
        raise InputError(f"--jobs {args.jobs}: expected a number of worker processes, 1 or more")
    model_path = args.model or default_model_path(args.kind)
    s = fit_images(args.input, model_path=model_path, out_dir=output_dir(args.input, args.out_dir), pts=args.pts,
                   mirror=not args.no_mirror, jobs=args.jobs or default_jobs())
    print(f"{s['images']} images: {s['fitted']} fitted, {s['rejected']} rejected, "
          f"{s['no_face']} without a face found, {s['unreadable']} unreadable -> "
          + ", ".join(display_name(v) for v in s["outputs"].values()))
    return 0
