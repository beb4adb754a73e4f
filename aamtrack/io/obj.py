"""Wavefront ``.obj`` meshes: vertices and polygon faces (other records are ignored).

A comment line ``# landmark68 i0 i1 ... i67`` carries the iBUG-68 landmark vertices (0-based); :func:`write_obj`
writes it when given landmarks. Writing goes to a temporary name in the same folder, renamed when complete.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_write


@dataclass(frozen=True)
class ObjMesh:
    """vertices : (n_vertices, 3) float64; faces : (n_faces, max_corners) int64, 0-based, padded with -1;
    landmark68 : (68,) int64 or None."""

    vertices: np.ndarray
    faces: np.ndarray
    landmark68: np.ndarray | None = None


def read_obj(path: str | Path) -> ObjMesh:
    """Read vertices, faces and an optional ``# landmark68`` line. Raises InputError naming the file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read mesh ({exc.strerror or exc})") from None
    vertices, faces, landmarks = [], [], None
    for number, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                vertices.append([float(v) for v in parts[1:4]])
                if len(vertices[-1]) != 3:
                    raise ValueError("a vertex needs 3 coordinates")
            elif parts[0] == "f":
                corners = [int(c.split("/")[0]) for c in parts[1:]]
                if len(corners) < 3:
                    raise ValueError("a face needs at least 3 corners")
                faces.append([c - 1 if c > 0 else len(vertices) + c for c in corners])
            elif parts[0] == "#" and len(parts) > 1 and parts[1] == "landmark68":
                landmarks = np.array([int(v) for v in parts[2:]], dtype=np.int64)
        except ValueError as exc:
            raise InputError(f"{path}: line {number}: malformed {parts[0]!r} record ({exc})") from None
    if not vertices:
        raise InputError(f"{path}: no vertices (not an .obj mesh?)")
    verts = np.array(vertices, dtype=np.float64)
    if not np.isfinite(verts).all():
        raise InputError(f"{path}: non-finite vertex coordinates")
    width = max((len(f) for f in faces), default=3)
    face_arr = np.full((len(faces), width), -1, dtype=np.int64)
    for i, f in enumerate(faces):
        face_arr[i, : len(f)] = f
    if len(faces) and (face_arr.max() >= len(verts) or (face_arr[face_arr != -1] < 0).any()):
        raise InputError(f"{path}: a face refers to a vertex that does not exist")
    return ObjMesh(verts, face_arr, landmarks)


def format_obj(vertices: np.ndarray, faces: np.ndarray | None = None, landmark68: np.ndarray | None = None) -> str:
    """The ``.obj`` text of a mesh (faces 0-based, padded with -1)."""
    lines = ["# written by aamtrack"]
    if landmark68 is not None:
        lines.append("# landmark68 " + " ".join(str(int(i)) for i in landmark68))
    lines.extend(f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in np.asarray(vertices, dtype=np.float64))
    if faces is not None:
        for f in np.asarray(faces, dtype=np.int64):
            lines.append("f " + " ".join(str(int(c) + 1) for c in f if c >= 0))
    return "\n".join(lines) + "\n"


def write_obj(
    path: str | Path, vertices: np.ndarray, faces: np.ndarray | None = None, landmark68: np.ndarray | None = None
) -> None:
    """Write an ``.obj`` (atomically: temporary name, then rename)."""
    text = format_obj(vertices, faces, landmark68)
    try:
        with atomic_write(path, "w") as fh:
            fh.write(text)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror or exc})") from None
