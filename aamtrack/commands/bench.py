"""``aamtrack bench INPUT``: per-stage frame times and fps at several resolutions, both models."""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

from ..errors import InputError
from ..io.atomic import check_replaceable
from ..io.frames import open_frames
from ..io.summary import write_summary_json
from ..models import default_model_path
from ..track.benchmark import format_table, run_bench
from ..track.pipeline import keep_freed_memory


def register(sub) -> None:
    p = sub.add_parser("bench", help="time the tracker per stage at several resolutions",
                       description="Median, p90 and max per-frame times (decode, detect, pyramid, search, output), "
                                   "tracking and end-to-end fps in one thread, and the end-to-end fps of the "
                                   "pipelined run (as aamtrack run); numba warm-up reported apart. Frames are "
                                   "streamed, not held in memory.",
                       epilog="examples:\n"
                              "  OMP_NUM_THREADS=1 aamtrack bench samples/cap12_first12s.mp4\n"
                              "  aamtrack bench clip.mp4 --model my2d.npz --sizes 640x480 --frames 100 --json b.json",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="video file or folder of frames")
    p.add_argument("--model", type=Path, action="append", help="model file (repeatable; default: both shipped)")
    p.add_argument("--sizes", default="320x240,640x480,1280x720", help="resolutions WxH, comma-separated")
    p.add_argument("--frames", type=int, default=300, help="frames per run (default 300)")
    p.add_argument("--threads", type=int, default=1, help="OpenCV threads (default 1: single-core figures)")
    p.add_argument("--json", type=Path, help="also write the results as JSON")
    p.set_defaults(func=run)


MAX_SIDE = 7680  # 8K UHD width: larger frames are a typo (100000x100000 would need 30 GB per frame)
MAX_FRAMES = 1_000_000


def _sizes(text: str) -> list[tuple[int, int]]:
    try:
        sizes = [tuple(int(v) for v in s.lower().split("x")) for s in text.split(",")]
        if any(len(s) != 2 or min(s) < 16 or max(s) > MAX_SIDE for s in sizes):
            raise ValueError
    except ValueError:
        raise InputError(f"--sizes {text!r}: expected WxH[,WxH...] such as 640x480, "
                         f"each side 16..{MAX_SIDE} px") from None
    return sizes


def run(args: argparse.Namespace) -> int:
    if not 1 <= args.frames <= MAX_FRAMES:
        raise InputError(f"--frames {args.frames}: expected a number of frames in 1..{MAX_FRAMES}")
    if not 1 <= args.threads <= 1024:
        raise InputError(f"--threads {args.threads}: expected at least 1")
    if args.json:  # checked before the long work
        if not args.json.parent.is_dir():
            raise InputError(f"{args.json.parent}: output folder does not exist")
        check_replaceable(args.json)
    sizes = _sizes(args.sizes)
    with open_frames(args.input):  # a bad input fails here, before the models' warm-up
        pass
    keep_freed_memory()  # as aamtrack run does
    models = args.model or [default_model_path("3d"), default_model_path("2d")]
    rows = run_bench(args.input, models, sizes, max_frames=args.frames, threads=args.threads)
    print(f"machine: {platform.node()} {platform.machine()} {_cpu_name()}, python {platform.python_version()}")
    print(format_table(rows))
    if args.json:
        write_summary_json(args.json, {"machine": _cpu_name(), "rows": rows})
    return 0


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"
