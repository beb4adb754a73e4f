"""Command line: ``aamtrack train|run|bench|transfer``. Parses, hands off to the library, and turns bad input
into one line on stderr with a non-zero exit."""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import logging
import os
import signal
import sys

from . import __version__
from .commands import COMMANDS
from .errors import AamtrackError

#: Signals that end a run the way Ctrl-C does: temporary files removed, nothing half-written, exit 128 + n.
STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n))


class Stopped(KeyboardInterrupt):
    """Raised in the main thread by a stop signal, so the cleanup that Ctrl-C triggers runs for it too."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line usage error (exit 2), like every other error of the command line."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} -h')\n")


DESCRIPTION = """Track faces in recorded video with Active Appearance Models (2D, or 3D Candide-3), and transfer the
tracked motion to other 3D faces."""

EPILOG = """examples:
  aamtrack run samples/cap12_first12s.mp4 --out-dir out/sample     track the bundled sample: CSV + JSON summary
  aamtrack run clip.mp4 --video --report     also an overlay video and report.html
  aamtrack -v run clip.mp4                   log detections, re-detections and why frames were lost
  aamtrack fit photos/ --pts                 fit each still image on its own: CSV with a 'file' column
  aamtrack bench clip.mp4                    per-stage timings at 320x240, 640x480, 1280x720
  aamtrack train --data faces/ --kind 2d --out my2d.npz
  aamtrack transfer out/sample/cap12_first12s.csv face.obj --out anim.npz

'aamtrack COMMAND --help' describes each command's options and outputs."""


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="aamtrack", description=DESCRIPTION, epilog=EPILOG,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"aamtrack {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log details to stderr: input, face detections and re-detections, why frames were "
                             "lost, files written, and FFmpeg's and OpenCV's own warnings")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f".commands.{name}", __package__).register(sub)
    return parser


@contextlib.contextmanager
def quiet_native_logs(verbose: bool):
    """Within the block, silence FFmpeg's and OpenCV's own log lines (decoder warnings around our one-line
    error) unless ``verbose``. FFmpeg reads its level once, when OpenCV first opens a video in the process, so
    this works for a command run as a program (not for a later ``main()`` call in a process that already read
    videos). A level the user set in ``OPENCV_FFMPEG_LOGLEVEL`` / ``OPENCV_LOG_LEVEL`` is kept."""
    if verbose or "OPENCV_FFMPEG_LOGLEVEL" in os.environ or "OPENCV_LOG_LEVEL" in os.environ:
        yield
        return
    import cv2

    cv_log = getattr(getattr(cv2, "utils", None), "logging", None)  # absent from old OpenCV builds
    os.environ["OPENCV_FFMPEG_LOGLEVEL"] = "-8"  # AV_LOG_QUIET
    previous = cv_log.getLogLevel() if cv_log else None
    if cv_log:
        cv_log.setLogLevel(cv_log.LOG_LEVEL_SILENT)
    try:
        yield
    finally:  # leave the process as found (tests call main() many times)
        os.environ.pop("OPENCV_FFMPEG_LOGLEVEL", None)
        if cv_log:
            cv_log.setLogLevel(previous)


@contextlib.contextmanager
def stop_signals_raise():
    """Within the block, SIGTERM and SIGHUP raise :class:`Stopped` (main thread only; elsewhere a no-op)."""
    def handler(signum, frame):
        raise Stopped(signum)

    previous = {}
    try:
        for sig in STOP_SIGNALS:
            previous[sig] = signal.signal(sig, handler)
    except ValueError:  # not the main thread
        pass
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        print(f"aamtrack: error: no command given: one of {', '.join(COMMANDS)} (see 'aamtrack -h')",
              file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        with quiet_native_logs(args.verbose), stop_signals_raise():
            return int(args.func(args) or 0)
    except AamtrackError as exc:
        print(f"aamtrack {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # an I/O failure no command turned into a message of its own
        where = f"{os.fsencode(exc.filename).decode('utf-8', 'backslashreplace')}: " if exc.filename else ""
        print(f"aamtrack {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except MemoryError:
        print(f"aamtrack {args.command}: error: out of memory (input or options too large for this machine)",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        name = "interrupted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}"
        print(f"aamtrack {args.command}: {name}", file=sys.stderr)
        return 128 + int(signum)


def run_program(argv: list[str] | None = None) -> int:
    """``main`` as the ``aamtrack`` program runs it (console script, ``python -m aamtrack``): the same, and then
    the objects alive at the end are frozen out of the garbage collector (``gc.freeze``), so the interpreter's
    final collection does not walk numba's and LLVM's object graphs: 0.2 s less from every command's exit on
    this project's VM (of about 0.9 s for a short ``run``). Nothing is lost: outputs are closed and committed
    before ``main`` returns, and no finalizer of ours waits for the collector. Tests call ``main``."""
    code = main(argv)
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(run_program())
