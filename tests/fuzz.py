"""Seeded fuzzing helpers: damage a file in one of a few ways, run commands on the damaged files, and check
each outcome is clean: exit 0, or exit 1 with exactly one line on stderr; never a traceback (an exception
escaping ``main``) or a signal; never a stray file.

:func:`run_batch` runs many cases in one child process (one import of numba and OpenCV for all of them), so
a crash by a signal is reported with the case that caused it instead of taking the test session down, and
FFmpeg's own output on the child's stderr is seen too. :func:`check_outcome` then checks one case.

Video cases are in tests/test_fuzz.py. Model-file cases plug in the same way: ``damage(model, dst, rng)``,
then a :class:`Case` with ``["run", CLIP, "--model", dst, "--out-dir", ...]``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np



def _overwrite(data: bytearray, rng) -> str:
    n = int(rng.integers(1, 400))
    at = int(rng.integers(0, max(1, len(data) - n)))
    data[at : at + n] = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
    return f"overwrite {n} B at {at}"


def _truncate(data: bytearray, rng) -> str:
    at = int(rng.integers(1, len(data)))
    del data[at:]
    return f"truncate at {at}"


def _flip_bits(data: bytearray, rng) -> str:
    k = int(rng.integers(1, 40))
    for at in rng.integers(0, len(data), k):
        data[at] ^= 1 << int(rng.integers(0, 8))
    return f"flip {k} bits"


def _zero_block(data: bytearray, rng) -> str:
    n = int(rng.integers(16, max(17, len(data) // 8)))
    at = int(rng.integers(0, max(1, len(data) - n)))
    data[at : at + n] = bytes(n)
    return f"zero {n} B at {at}"


def _delete_block(data: bytearray, rng) -> str:
    n = int(rng.integers(1, max(2, len(data) // 10)))
    at = int(rng.integers(0, max(1, len(data) - n)))
    del data[at : at + n]
    return f"delete {n} B at {at}"


def _insert_bytes(data: bytearray, rng) -> str:
    n = int(rng.integers(1, 300))
    at = int(rng.integers(0, len(data)))
    data[at:at] = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
    return f"insert {n} B at {at}"


def _header(data: bytearray, rng) -> str:
    n = int(rng.integers(1, 64))
    at = int(rng.integers(0, 64))
    data[at : at + n] = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
    return f"header: overwrite {n} B at {at}"


def _swap_blocks(data: bytearray, rng) -> str:
    n = max(1, len(data) // 16)
    a, b = sorted(int(v) for v in rng.integers(0, len(data) - n, 2))
    if b - a < n:
        return _overwrite(data, rng)
    data[a : a + n], data[b : b + n] = data[b : b + n], data[a : a + n]
    return f"swap {n} B at {a} and {b}"


MUTATIONS = (_overwrite, _truncate, _flip_bits, _zero_block, _delete_block, _insert_bytes, _header, _swap_blocks)


def damage(src: Path, dst: Path, rng: np.random.Generator) -> str:
    """Write a damaged copy of ``src`` to ``dst`` (mutation chosen by ``rng``); returns what was done."""
    data = bytearray(Path(src).read_bytes())
    what = MUTATIONS[int(rng.integers(len(MUTATIONS)))](data, rng)
    Path(dst).write_bytes(bytes(data))
    return what


def listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in Path(folder).rglob("*")}


@dataclass
class Case:
    """One fuzz case: ``argv`` for ``aamtrack``, run with everything it reads and writes inside ``workdir``;
    after exit 0 only ``allowed_new`` paths (relative to ``workdir``) may have appeared there."""

    name: str
    argv: list[str]
    workdir: Path
    allowed_new: set[str] = field(default_factory=set)
    before: set[str] = field(default_factory=set)
    code: object = None
    err: list[str] = field(default_factory=list)


_CHILD = r"""
import contextlib, io, json, sys, traceback
from aamtrack.cli import main
for line in sys.stdin:
    case = json.loads(line)
    print(json.dumps({"start": case["name"]}), flush=True)
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(case["argv"])
        except SystemExit as exc:
            code = exc.code
        except BaseException:
            code = "traceback"
            err.write(traceback.format_exc())
    print(json.dumps({"name": case["name"], "code": code, "err": err.getvalue()}), flush=True)
"""


def run_batch(cases: list[Case], *, timeout: float = 300) -> str:
    """Run every case in one child process (in order); fill ``code``, ``err`` and ``before`` of each.
    Returns the child's own stderr (file-descriptor level: FFmpeg, OpenCV, crashes). Raises AssertionError
    naming the case if the child dies by a signal."""
    for c in cases:
        c.before = listing(c.workdir)
    env = {k: v for k, v in os.environ.items() if not k.startswith("OPENCV_")}
    stdin = "".join(json.dumps({"name": c.name, "argv": [str(a) for a in c.argv]}) + "\n" for c in cases)
    proc = subprocess.run([sys.executable, "-c", _CHILD], input=stdin, capture_output=True, text=True,
                          timeout=timeout, env=env)
    by_name = {c.name: c for c in cases}
    running = None
    for line in proc.stdout.splitlines():
        msg = json.loads(line)
        if "start" in msg:
            running = msg["start"]
            continue
        case = by_name[msg["name"]]
        case.code, case.err = msg["code"], [s for s in msg["err"].splitlines() if s.strip()]
        running = None
    assert proc.returncode == 0, (f"child died (exit {proc.returncode}) in case {running}", proc.stderr[-2000:])
    return proc.stderr


def check_outcome(case: Case) -> None:
    """Assert the clean outcome of a case :func:`run_batch` ran (see the module docstring)."""
    what, err = case.name, case.err
    assert case.code in (0, 1), (what, case.code, err)
    after = listing(case.workdir)
    new = after - case.before
    errors = [line for line in err if ": error:" in line]
    if case.code == 1:
        assert len(errors) == 1 and err[-1] == errors[0], (what, err)
        assert new == set(), (what, sorted(new))
    else:
        assert errors == [], (what, err)
        assert new <= case.allowed_new, (what, sorted(new - case.allowed_new))
    assert not any(".tmp" in name for name in after), (what, sorted(after))  # no temporary file left
