"""3D mesh and point cloud files: Wavefront ``.obj``, ``.ply`` point clouds, and mesh ``.npz`` files.

A comment line ``# landmark68 i0 i1 ... i67`` in an ``.obj`` carries the iBUG-68 landmark vertices (0-based);
:func:`write_obj` writes it when given landmarks. A mesh ``.npz`` holds ``vertices`` (M, 3), optional ``faces``
(F, k) 0-based and ``landmark68`` (68,), or the ICT FaceKit layout (``neutral``, ``quads``,
``landmark68_vertex_idx``). Every reader checks what it returns (finite coordinates of a sane size, faces of at
least 3 corners that name existing vertices, 68 distinct landmark vertices) and raises InputError naming the
file. Writing goes to temporary names, renamed when complete (:func:`write_obj_frames` renames a whole sequence
together).
"""

from __future__ import annotations

import re
import zipfile
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_write, commit_temporary, discard_temporary, temporary_path
from .pts import N_LANDMARKS
MAX_COORDINATE = 1e6  # |coordinate| above this is a unit or file error (a face is ~0.2 m, 20 cm, 200 mm)
MIN_EXTENT = 1e-6  # a mesh smaller than this across is degenerate
NPZ_MESH_KEYS = "`vertices` (M, 3) [+ `faces`, `landmark68`] or ICT FaceKit's `neutral`, `quads`, `landmark68_vertex_idx`"


@dataclass(frozen=True)
class ObjMesh:
    """vertices : (n_vertices, 3) float64; faces : (n_faces, max_corners) int64, 0-based, padded with -1;
    landmark68 : (68,) int64 or None."""

    vertices: np.ndarray
    faces: np.ndarray
    landmark68: np.ndarray | None = None


def check_points(path, points: np.ndarray, what: str = "coordinates") -> np.ndarray:
    """(n, 3) float64 points, or InputError: wrong shape, empty, non-finite, huge or all in one place."""
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise InputError(f"{path}: {what} must be (n >= 1, 3), got shape {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number) or np.iscomplexobj(pts):
        raise InputError(f"{path}: {what} are not real numbers (dtype {pts.dtype})")
    pts = pts.astype(np.float64)
    if not np.isfinite(pts).all():
        raise InputError(f"{path}: non-finite {what}")
    if np.abs(pts).max() > MAX_COORDINATE:
        raise InputError(f"{path}: {what} up to {np.abs(pts).max():.3g}, beyond {MAX_COORDINATE:g} (wrong units?)")
    if len(pts) > 1 and np.ptp(pts, axis=0).max() < MIN_EXTENT:
        raise InputError(f"{path}: {what} all within {MIN_EXTENT:g} of each other (degenerate)")
    return pts


def check_faces(path, faces, n_vertices: int) -> np.ndarray:
    """(F, k) int64 faces padded with -1, or InputError: not integers, fewer than 3 corners, unknown vertices."""
    arr = np.asarray(faces)
    if arr.size == 0:
        return np.zeros((0, 3), np.int64)
    if arr.ndim != 2 or arr.shape[1] < 3:
        raise InputError(f"{path}: faces must be (F, k >= 3), got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{path}: faces must be integer vertex indices (dtype {arr.dtype})")
    arr = arr.astype(np.int64)
    valid = arr >= 0
    if (arr[~valid] != -1).any() or (arr >= n_vertices).any():
        raise InputError(f"{path}: a face refers to a vertex that does not exist (0..{n_vertices - 1})")
    if (valid.sum(1) < 3).any():
        raise InputError(f"{path}: face {int(np.argmax(valid.sum(1) < 3))} has fewer than 3 corners")
    if (np.diff(valid.astype(np.int8), axis=1) > 0).any():
        raise InputError(f"{path}: faces must be padded with -1 at the end only")
    return arr


def check_landmarks(path, index, n_vertices: int) -> np.ndarray:
    """(68,) int64 distinct vertex indices in range, or InputError."""
    idx = np.asarray(index).ravel()
    if len(idx) != N_LANDMARKS:
        raise InputError(f"{path}: landmark68 has {len(idx)} indices, expected {N_LANDMARKS}")
    if not np.issubdtype(idx.dtype, np.integer) or idx.min() < 0 or idx.max() >= n_vertices:
        raise InputError(f"{path}: landmark68 indices must be integers in 0..{n_vertices - 1}")
    if len(np.unique(idx)) != N_LANDMARKS:
        raise InputError(f"{path}: landmark68 names the same vertex twice")
    return idx.astype(np.int64)


def check_landmark_spread(path, points: np.ndarray, what: str) -> None:
    """InputError unless the landmark positions (68, 3) span 3D (a similarity and an RBF need that): not collapsed,
    not all on one line or plane."""
    sv = np.linalg.svd(points - points.mean(0), compute_uv=False)
    if len(np.unique(points, axis=0)) < 4 or sv[2] <= 1e-9 * sv[0]:
        raise InputError(f"{path}: {what} landmarks are degenerate (collapsed or all in one plane)")


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
                if 0 in corners:
                    raise ValueError("vertex index 0 (.obj indices start at 1)")
                faces.append([c - 1 if c > 0 else len(vertices) + c for c in corners])
            elif parts[0] == "#" and len(parts) > 1 and parts[1] == "landmark68":
                landmarks = np.array([int(v) for v in parts[2:]], dtype=np.int64)
        except ValueError as exc:
            raise InputError(f"{path}: line {number}: malformed {parts[0]!r} record ({exc})") from None
    if not vertices:
        raise InputError(f"{path}: no vertices (not an .obj mesh?)")
    verts = check_points(path, np.array(vertices, dtype=np.float64), "vertex coordinates")
    width = max((len(f) for f in faces), default=3)
    face_arr = np.full((len(faces), width), -1, dtype=np.int64)
    for i, f in enumerate(faces):
        face_arr[i, : len(f)] = f
    if len(faces) and (face_arr.max() >= len(verts) or (face_arr[face_arr != -1] < 0).any()):
        raise InputError(f"{path}: a face refers to a vertex that does not exist")
    if landmarks is not None:
        landmarks = check_landmarks(path, landmarks, len(verts))
    return ObjMesh(verts, face_arr, landmarks)


ZIP_MAGICS = (b"PK\x03\x04", b"PK\x05\x06")  # how an .npz (a zip archive; the second: one with no arrays) starts
NPY_MAGIC = b"\x93NUMPY"  # how a bare .npy array starts


def npz_problem(fh) -> str | None:
    """Why the binary file ``fh`` (read from its start, left there) is not an ``.npz`` archive ("empty file", "a
    bare array, not an .npz archive", "not an .npz archive"), or None. ``np.load`` takes anything else for a
    pickle and says the file holds pickled data, and hands a bare ``.npy`` array back instead of an archive."""
    head = fh.read(len(NPY_MAGIC))
    fh.seek(0)
    if not head:
        return "empty file"
    if head == NPY_MAGIC:
        return "a bare array, not an .npz archive"
    if not head.startswith(ZIP_MAGICS):
        return "not an .npz archive"
    return None


@contextmanager
def open_npz(path: str | Path, what: str = ".npz") -> Iterator:
    """``np.load``'s lazy archive of the ``.npz`` at path (no pickles), closed on leaving; InputError naming the
    file for a missing, empty, truncated or corrupt file or one that is not an archive (``what`` names what it
    should have been in the message)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:  # our handle: closed on a bad zip too
            problem = npz_problem(fh)
            if problem:
                raise InputError(f"{path}: cannot read {what} ({problem})")
            with np.load(fh, allow_pickle=False) as data:
                yield data
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error,
            NotImplementedError) as exc:  # zipfile: compression or flags it does not support
        raise InputError(f"{path}: cannot read {what} ({type(exc).__name__}: {exc})") from None


def load_npz(path: str | Path) -> dict:
    """Every array of an ``.npz`` (no pickles), or InputError for a missing, empty, truncated or corrupt file or
    one that is not an ``.npz`` archive (``open_npz``)."""
    with open_npz(path) as data:
        return {k: data[k] for k in data.files}


def read_mesh(path: str | Path, landmarks_path: str | Path | None = None, *, need_landmarks: bool = True) -> ObjMesh:
    """A mesh from an ``.obj`` or a mesh ``.npz`` (see the module docstring), with its 68 landmark vertices from
    the file or from ``landmarks_path`` (a text file of 68 indices). A 68-vertex mesh without landmarks gets
    0..67. Raises InputError naming the file and what is wrong or missing."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        mesh = read_obj(path)
        verts, faces, lm = mesh.vertices, mesh.faces, mesh.landmark68
    else:
        data = load_npz(path)
        if "vertices" in data:
            verts, faces, lm = data["vertices"], data.get("faces"), data.get("landmark68")
        elif "neutral" in data:  # ICT FaceKit
            verts, lm = data["neutral"], data.get("landmark68_vertex_idx")
            faces = data.get("quads", data.get("tris"))
        else:
            raise InputError(f"{path}: no mesh in it: expected {NPZ_MESH_KEYS}; found {', '.join(data) or 'nothing'}")
        verts = check_points(path, verts, "vertex coordinates")
        faces = check_faces(path, np.zeros((0, 3), np.int64) if faces is None else faces, len(verts))
    if landmarks_path is not None:
        try:
            lm = np.loadtxt(landmarks_path, dtype=np.int64).ravel()
        except (OSError, ValueError) as exc:
            raise InputError(f"{landmarks_path}: cannot read landmark indices ({exc})") from None
        path = Path(landmarks_path)
    if lm is None and len(verts) == N_LANDMARKS:
        lm = np.arange(N_LANDMARKS)
    if lm is None:
        if need_landmarks:
            raise InputError(f"{path}: missing landmark68 (68 landmark vertex indices)")
    else:
        lm = check_landmarks(path, lm, len(verts))
    return ObjMesh(verts, faces, lm)


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _read_ply(path: Path) -> np.ndarray:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise InputError(f"{path}: not a PLY file (no 'ply' ... 'end_header' header)")
    header = raw[:end].decode("ascii", errors="replace").splitlines()
    body = raw[end + len(b"end_header"):]
    body = body[2:] if body.startswith(b"\r\n") else body[1:]
    fmt, elements = None, []
    for line in header:
        parts = line.split()
        if parts[:1] == ["format"] and len(parts) >= 2:
            fmt = parts[1]
        elif parts[:1] == ["element"] and len(parts) == 3:
            elements.append((parts[1], int(parts[2]) if parts[2].isdigit() else -1, []))
        elif parts[:1] == ["property"] and elements:
            elements[-1][2].append(parts[1:])
    if not elements or elements[0][0] != "vertex" or elements[0][1] < 0:
        raise InputError(f"{path}: PLY without a leading 'vertex' element")
    _, n, props = elements[0]
    names = [p[-1] for p in props]
    if any(p[0] == "list" for p in props) or not {"x", "y", "z"} <= set(names):
        raise InputError(f"{path}: PLY vertices need x, y, z properties (and no lists)")
    try:
        if fmt == "ascii":
            lines = body.decode("ascii").split("\n")[:n]
            table = np.array([[float(v) for v in ln.split()[: len(names)]] for ln in lines], np.float64)
            if table.shape != (n, len(names)):
                raise ValueError("short vertex list")
            cols = table
        elif fmt in ("binary_little_endian", "binary_big_endian"):
            order = "<" if fmt == "binary_little_endian" else ">"
            dtype = np.dtype([(nm, order + _PLY_TYPES[p[0]]) for nm, p in zip(names, props, strict=True)])
            if len(body) < n * dtype.itemsize:
                raise ValueError(f"{len(body)} bytes for {n} vertices of {dtype.itemsize}")
            rec = np.frombuffer(body, dtype=dtype, count=n)
            cols = np.stack([rec[nm].astype(np.float64) for nm in names], 1)
        else:
            raise ValueError(f"unknown format {fmt!r}")
    except (ValueError, KeyError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: malformed PLY ({exc})") from None
    return cols[:, [names.index(a) for a in "xyz"]]


def read_point_cloud(path: str | Path) -> np.ndarray:
    """(n, 3) float64 points of an ``.obj`` (its vertices) or ``.ply`` (ASCII or binary) file; InputError if bad."""
    path = Path(path)
    if path.suffix.lower() == ".ply":
        return check_points(path, _read_ply(path), "point coordinates")
    if path.suffix.lower() == ".obj":
        return read_obj(path).vertices
    raise InputError(f"{path}: not a point cloud file (.obj or .ply)")


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


def obj_frame_name(t: int) -> str:
    return f"frame_{t:05d}.obj"


def stage_obj_frames(folder: str | Path, frames: np.ndarray, faces: np.ndarray | None = None, *,
                     progress=None) -> list:
    """Write one ``.obj`` per frame (``frame_00000.obj``, ...) into ``folder`` under temporary names; returns the
    (temporary, final) pairs for :func:`commit_staged` (or :func:`discard_staged`). frames : (T, M, 3).
    progress : called with 1 per file written."""
    folder = Path(folder)
    staged = []
    try:
        for t, frame in enumerate(frames):
            final = folder / obj_frame_name(t)
            tmp = temporary_path(final)
            staged.append((tmp, final))
            tmp.write_text(format_obj(frame, faces), encoding="utf-8")
            if progress is not None:
                progress(1)
    except BaseException:
        discard_staged(staged)
        raise
    return staged


def commit_staged(staged: list) -> None:
    for tmp, final in staged:
        commit_temporary(tmp, final)


def discard_staged(staged: list) -> None:
    for tmp, _ in staged:
        discard_temporary(tmp)


def frame_files(folder: str | Path) -> list:
    """The ``.obj`` / ``.ply`` files of a folder in natural name order (``scan2`` before ``scan10``)."""
    key = lambda p: [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", p.name)]  # noqa: E731
    return sorted((p for p in Path(folder).iterdir() if p.suffix.lower() in (".obj", ".ply") and p.is_file()), key=key)


def save_animation(out: str | Path, arrays: dict, *, obj_dir: str | Path | None = None, faces=None,
                   progress=None) -> None:
    """Write ``arrays`` (``frames`` (T, M, 3) among them) to the ``.npz`` ``out`` (compressed, atomically: see
    :func:`aamtrack.io.atomic.save_npz`) and, with ``obj_dir``, one ``.obj`` per frame there; the ``.obj`` files are
    staged first and renamed only once the ``.npz`` is in place, so a failure leaves nothing new behind.
    Raises OutputError when a file cannot be written."""
    from ..errors import OutputError
    from .atomic import save_npz

    out = Path(out)
    staged, created = [], None
    try:
        if obj_dir is not None:
            obj_dir = Path(obj_dir)
            if not obj_dir.exists():
                obj_dir.mkdir(parents=True)
                created = obj_dir
            staged = stage_obj_frames(obj_dir, arrays["frames"], faces, progress=progress)
        save_npz(out, **arrays)
    except BaseException as exc:
        discard_staged(staged)
        if created is not None:
            created.rmdir()
        if isinstance(exc, OSError):
            raise OutputError(f"{exc.filename or out}: cannot write ({exc.strerror or exc})") from None
        raise
    commit_staged(staged)
