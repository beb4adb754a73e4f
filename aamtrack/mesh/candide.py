"""Reader for Ahlberg's Candide ``.wfm`` wireframe format (Candide-3, LiTH-ISY-R-2326, 2001).

The file is a sequence of ``#``-headed blocks: VERTEX LIST, FACE LIST, ANIMATION UNITS LIST, SHAPE UNITS LIST,
then parameter/texture/global-motion blocks that are all zero in the standard file and are not read. Each unit
is a comment line with its name, a count, then ``vertex dx dy dz`` lines.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Candide:
    """A Candide wireframe.

    vertices : (n_vertices, 3) float64 -- the mean shape M (x right, y up, z towards the viewer)
    triangles : (n_triangles, 3) int32
    anim_units : (n_anim, n_vertices, 3) float64 -- dense animation unit displacements A
    anim_names : tuple of str, e.g. "AUV11 Jaw drop (AU26/27)", "FAP 3 open_jaw"
    shape_units : (n_shape, n_vertices, 3) float64 -- dense shape unit displacements S
    shape_names : tuple of str, e.g. "Head height"
    """

    vertices: np.ndarray
    triangles: np.ndarray
    anim_units: np.ndarray
    anim_names: tuple
    shape_units: np.ndarray
    shape_names: tuple

    def anim_index(self, prefix: str) -> int:
        """Index of the animation unit whose name starts with ``prefix + ' '`` (e.g. ``"AUV11"``)."""
        for i, name in enumerate(self.anim_names):
            if name.split()[0] == prefix:
                return i
        raise KeyError(f"no animation unit {prefix!r}")


class _Lines:
    """Cursor over the file's lines that keeps the last comment seen (unit names are comments)."""

    def __init__(self, text: str, path: Path):
        self.lines = text.splitlines()
        self.i = 0
        self.path = path
        self.comments: list[str] = []

    def next_data(self) -> list[str]:
        self.comments = []
        while self.i < len(self.lines):
            line = self.lines[self.i].strip()
            self.i += 1
            if not line:
                continue
            if line.startswith("#"):
                self.comments.append(line.lstrip("#").strip())
                continue
            return line.split()
        raise InputError(f"{self.path}: unexpected end of file")

    def count(self, what: str) -> int:
        tok = self.next_data()
        try:
            return int(tok[0])
        except (ValueError, IndexError):
            raise InputError(f"{self.path}: line {self.i}: expected the number of {what}, got {' '.join(tok)!r}") from None

    def numbers(self, n: int, what: str) -> list[float]:
        tok = self.next_data()
        try:
            vals = [float(t) for t in tok[:n]]
        except ValueError:
            vals = []
        if len(vals) != n:
            raise InputError(f"{self.path}: line {self.i}: expected {n} numbers for {what}, got {' '.join(tok)!r}") from None
        return vals


def _read_units(cur: _Lines, n_vertices: int, what: str) -> tuple[np.ndarray, list[str]]:
    n_units = cur.count(what)
    dense = np.zeros((n_units, n_vertices, 3))
    names = []
    for u in range(n_units):
        n_moved = cur.count(f"{what} entries")
        names.append(cur.comments[0] if cur.comments else f"{what}{u}")
        for _ in range(n_moved):
            v, dx, dy, dz = cur.numbers(4, what)
            if not 0 <= int(v) < n_vertices:
                raise InputError(f"{cur.path}: line {cur.i}: vertex {int(v)} out of range in {names[-1]!r}")
            dense[u, int(v)] = dx, dy, dz
    return dense, names


def read_wfm(path: str | Path) -> Candide:
    """Read a Candide ``.wfm`` file; raises InputError naming the file and line on malformed input."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    cur = _Lines(text, path)
    n_v = cur.count("vertices")
    vertices = np.array([cur.numbers(3, "a vertex") for _ in range(n_v)], dtype=np.float64)
    n_t = cur.count("faces")
    triangles = np.array([cur.numbers(3, "a face") for _ in range(n_t)], dtype=np.int32)
    if n_t and (triangles.min() < 0 or triangles.max() >= n_v):
        raise InputError(f"{path}: a face refers to a vertex outside 0..{n_v - 1}")
    anim, anim_names = _read_units(cur, n_v, "animation units")
    shape, shape_names = _read_units(cur, n_v, "shape units")
    return Candide(vertices, triangles.reshape(-1, 3), anim, tuple(anim_names), shape, tuple(shape_names))
