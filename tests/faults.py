"""Fault injection for the reliability tests: a disk that fills up, and a real tiny tmpfs where one can be mounted.

``disk_full`` simulates ENOSPC by wrapping the files Python opens for writing below a folder (``open`` and
``os.fdopen``): writes succeed until a byte budget is spent, then raise ``OSError(ENOSPC)``, as a full disk
does. It reaches everything written from Python (CSV, JSON, .pts, model .npz) but not native writers
(OpenCV's VideoWriter): those are tested on a real tmpfs (``tiny_tmpfs``, root only; skipped elsewhere).
"""

from __future__ import annotations

import builtins
import contextlib
import errno
import io
import os
import subprocess
from pathlib import Path

import pytest


class _FullRaw(io.RawIOBase):
    def __init__(self, raw, budget: list[int]):
        self.raw, self.budget = raw, budget

    def writable(self):
        return True

    def readable(self):
        return False

    def seekable(self):
        return self.raw.seekable()

    def seek(self, *a):
        return self.raw.seek(*a)

    def tell(self):
        return self.raw.tell()

    def fileno(self):
        return self.raw.fileno()

    def write(self, b):
        n = len(b)
        if n > self.budget[0]:
            self.budget[0] = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.budget[0] -= n
        return self.raw.write(b)

    def close(self):
        if not self.closed:
            self.raw.close()
        super().close()


def disk_full(monkeypatch, under: Path, budget: int) -> list[int]:
    """From now on, files opened for writing below ``under`` share ``budget`` bytes, then raise ENOSPC."""
    left = [int(budget)]
    real_open, real_fdopen = builtins.open, os.fdopen
    root = os.fsdecode(os.path.realpath(under))

    def wrap(raw, mode, encoding, newline):
        buffered = io.BufferedWriter(_FullRaw(raw, left))
        if "b" in mode:
            return buffered
        return io.TextIOWrapper(buffered, encoding=encoding or "utf-8", newline=newline)

    def fake_open(file, mode="r", buffering=-1, encoding=None, errors=None, newline=None, closefd=True,
                  opener=None):
        target = os.fsdecode(os.path.realpath(file)) if not isinstance(file, int) else ""
        if isinstance(file, int) or not any(c in mode for c in "wxa") or not target.startswith(root):
            return real_open(file, mode, buffering, encoding, errors, newline, closefd, opener)
        raw = real_open(file, mode.replace("t", "").replace("b", "") + "b", 0, closefd=closefd, opener=opener)
        return wrap(raw, mode, encoding, newline)

    def fake_fdopen(fd, mode="r", *args, **kw):
        if not any(c in mode for c in "wxa"):
            return real_fdopen(fd, mode, *args, **kw)
        path = os.readlink(f"/proc/self/fd/{fd}") if os.path.isdir("/proc/self/fd") else ""
        if not path.startswith(root):
            return real_fdopen(fd, mode, *args, **kw)
        raw = real_open(fd, mode.replace("t", "").replace("b", "") + "b", 0)
        return wrap(raw, mode, kw.get("encoding"), kw.get("newline"))

    monkeypatch.setattr(builtins, "open", fake_open)
    monkeypatch.setattr(os, "fdopen", fake_fdopen)
    return left


@contextlib.contextmanager
def tiny_tmpfs(folder: Path, size: str = "64k", *, read_only: bool = False):
    """Mount a tmpfs of ``size`` (read-only if asked) on ``folder`` for the block (needs root); skips the test
    where that is impossible."""
    folder.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    options = f"size={size}" + (",ro" if read_only else "")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode(errors='replace').strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def files_below(folder: Path) -> list[str]:
    """Every file and folder below ``folder`` (relative, sorted): to check nothing stray was left."""
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))
