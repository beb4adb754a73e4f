"""Seeded fuzzing helpers: damage a file in one of a few ways, run a command on it in-process, and check the
outcome is clean: exit 0, or exit 1 with exactly one line on stderr; never a traceback (an exception escaping
``main``) or a signal (which would take the test process down with it); never a stray file.

A case is ``(name, make)``: ``make(tmp_path, rng)`` writes the damaged input and returns the argv to run.
Video cases are in tests/test_fuzz.py; model-file cases plug in the same way (a damaged copy of a model file,
run with ``aamtrack run CLIP --model DAMAGED``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aamtrack.cli import main


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


def check_clean_run(argv: list[str], capsys, *, workdir: Path, allowed_new: set[str], what: str = "") -> int:
    """Run ``main(argv)``; assert a clean outcome (see the module docstring) and return the exit code.

    ``workdir`` is the folder all inputs and outputs of the case live in; after exit 0 only ``allowed_new``
    files may have appeared in it, after exit 1 nothing at all.
    """
    before = listing(workdir)
    capsys.readouterr()
    code = main(argv)  # an exception escaping here is the traceback a user would have seen
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    after = listing(workdir)
    new = after - before
    errors = [line for line in err if ": error:" in line]
    assert code in (0, 1), (what, code, err)
    if code == 1:
        assert len(errors) == 1 and err[-1] == errors[0], (what, err)
        assert new == set(), (what, sorted(new))
    else:
        assert errors == [], (what, err)
        assert new <= allowed_new, (what, sorted(new - allowed_new))
    assert not any(".tmp" in name for name in after), (what, sorted(after))  # no temporary file left
    return code
