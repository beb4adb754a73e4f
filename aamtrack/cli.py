"""Command line: ``aamtrack train|run|bench|transfer``. Parses, hands off to the library, and turns bad input
into one line on stderr with a non-zero exit."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from . import __version__
from .commands import COMMANDS
from .errors import AamtrackError


DESCRIPTION = """Track faces in recorded video with Active Appearance Models (2D, or 3D Candide-3), and transfer the
tracked motion to other 3D faces."""

EPILOG = """examples:
  aamtrack run samples/cap12_first12s.mp4 --out-dir out/sample     track the bundled sample: CSV + JSON summary
  aamtrack run clip.mp4 --video --report     also an overlay video and report.html
  aamtrack -v run clip.mp4                   log detections, re-detections and why frames were lost
  aamtrack bench clip.mp4                    per-stage timings at 320x240, 640x480, 1280x720
  aamtrack train --data faces/ --kind 2d --out my2d.npz
  aamtrack transfer out/sample/cap12_first12s.csv face.obj --out anim.npz

'aamtrack COMMAND --help' describes each command's options and outputs."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="aamtrack", description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"aamtrack {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log details to stderr: input, face detections and re-detections, why frames were "
                             "lost, files written")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f".commands.{name}", __package__)
        except ModuleNotFoundError as exc:  # a command not built yet in this checkout
            if exc.name != f"{__package__}.commands.{name}":
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except AamtrackError as exc:
        print(f"aamtrack {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"aamtrack {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
