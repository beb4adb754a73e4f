"""``aamtrack transfer SOURCE TARGET --out OUT.npz``: animate a 3D target face with tracked or dense source motion."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from ..io.obj import read_obj, write_obj

N_LANDMARKS = 68

DESCRIPTION = """Transfer facial motion from SOURCE to the neutral 3D face TARGET (Akagi et al.).
SOURCE is a tracking CSV of `aamtrack run` with the 3D model (columns frame, success, X_0..X_67, Y_0..Y_67,
Z_0..Z_67; the first successful row is the neutral face; rows with success=0 take the last good frame's landmarks;
rows before the first success are dropped) or an .npz with `frames` (T, N, 3), frame 0 neutral, and `landmark68`
(68,) vertex indices (optional when N = 68). TARGET is an .obj (landmarks from a `# landmark68 ...` comment line
or --target-landmarks) or an .npz with `vertices` (M, 3) and optionally `faces` and `landmark68`. Only the 68
landmarks are assumed to correspond; sizes, vertex order and units may differ. OUT.npz holds `frames` (T, M, 3)
float32."""


def _read_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read CSV ({exc})") from None
    reader = csv.DictReader(io.StringIO(text))
    cols = [f"{a}_{i}" for a in "XYZ" for i in range(N_LANDMARKS)]
    missing = [c for c in ["success"] + cols if c not in (reader.fieldnames or [])]
    if missing:
        raise InputError(f"{path}: missing columns {', '.join(missing[:3])}{' ...' if len(missing) > 3 else ''}")
    frames, last = [], None
    for number, row in enumerate(reader, 2):
        try:
            ok = int(float(row["success"])) == 1
            pts = np.array([float(row[c]) for c in cols]).reshape(3, N_LANDMARKS).T if ok else None
        except (TypeError, ValueError):
            raise InputError(f"{path}: line {number}: malformed number") from None
        if ok and np.isfinite(pts).all():
            last = pts
        if last is not None:
            frames.append(last)
    if not frames:
        raise InputError(f"{path}: no successful frame (empty sequence)")
    return np.stack(frames), np.arange(N_LANDMARKS)


def _load_npz(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{path}: cannot read .npz ({exc})") from None


def _landmarks(path: Path, idx, n_vertices: int) -> np.ndarray:
    if idx is None:
        if n_vertices == N_LANDMARKS:
            return np.arange(N_LANDMARKS)
        raise InputError(f"{path}: missing landmark68 (68 landmark vertex indices)")
    idx = np.asarray(idx).ravel()
    if len(idx) != N_LANDMARKS:
        raise InputError(f"{path}: landmark68 has {len(idx)} indices, expected {N_LANDMARKS}")
    if not np.issubdtype(idx.dtype, np.integer) or idx.min() < 0 or idx.max() >= n_vertices:
        raise InputError(f"{path}: landmark68 indices must be integers in 0..{n_vertices - 1}")
    return idx.astype(np.int64)


def load_source(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(frames (T, N, 3) float64, landmark68 (68,) int64) from a tracking CSV or an .npz."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return _read_csv(path)
    data = _load_npz(path)
    if "frames" not in data:
        raise InputError(f"{path}: missing `frames` (T, N, 3)")
    frames = np.asarray(data["frames"], dtype=np.float64)
    if frames.ndim != 3 or frames.shape[2] != 3:
        raise InputError(f"{path}: `frames` must be (T, N, 3), got {frames.shape}")
    if len(frames) == 0 or frames.shape[1] == 0:
        raise InputError(f"{path}: empty sequence")
    if not np.isfinite(frames).all():
        raise InputError(f"{path}: non-finite coordinates in `frames`")
    return frames, _landmarks(path, data.get("landmark68"), frames.shape[1])


def load_target(path: str | Path, landmarks_path: str | Path | None = None) -> tuple:
    """(vertices (M, 3) float64, faces (F, k) int64 or None, landmark68 (68,) int64) from an .obj or .npz."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        mesh = read_obj(path)
        verts, faces, lm = mesh.vertices, mesh.faces, mesh.landmark68
    else:
        data = _load_npz(path)
        if "vertices" not in data:
            raise InputError(f"{path}: missing `vertices` (M, 3)")
        verts = np.asarray(data["vertices"], dtype=np.float64)
        if verts.ndim != 2 or verts.shape[1] != 3 or len(verts) == 0:
            raise InputError(f"{path}: `vertices` must be (M, 3), got {verts.shape}")
        faces, lm = data.get("faces"), data.get("landmark68")
    if landmarks_path is not None:
        try:
            lm = np.loadtxt(landmarks_path, dtype=np.int64).ravel()
        except (OSError, ValueError) as exc:
            raise InputError(f"{landmarks_path}: cannot read landmark indices ({exc})") from None
        path = Path(landmarks_path)
    return verts, faces, _landmarks(path, lm, len(verts))


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "transfer", help="transfer facial motion to a 3D face", description=DESCRIPTION
    )
    parser.add_argument("source", type=Path, help="tracking CSV (3D model) or .npz with `frames`")
    parser.add_argument("target", type=Path, help="neutral target face: .obj or .npz with `vertices`")
    parser.add_argument("--out", type=Path, required=True, help="output .npz with `frames` (T, M, 3) float32")
    parser.add_argument("--obj-dir", type=Path, help="also write one .obj per frame into this folder")
    parser.add_argument("--target-landmarks", type=Path, help="text file of the target's 68 landmark vertices")
    parser.add_argument("--seed", type=int, default=0, help="seed of the key point sampler (default 0)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from tqdm import tqdm

    from ..refine.sampler import SamplerConfig
    from ..refine.transfer import TransferConfig, transfer

    frames, s_lm = load_source(args.source)
    verts, faces, t_lm = load_target(args.target, args.target_landmarks)
    if len(np.unique(verts[t_lm], axis=0)) < 4 or len(np.unique(frames[0, s_lm], axis=0)) < 4:
        raise InputError(f"{args.target}: landmarks collapse to fewer than 4 distinct points")
    if not args.out.parent.is_dir():
        raise InputError(f"{args.out}: folder {args.out.parent} does not exist")
    config = TransferConfig(sampler=SamplerConfig(seed=args.seed))
    with tqdm(desc="registering", unit="frame", leave=False) as bar:
        result = transfer(frames, s_lm, verts, t_lm, config=config, progress=bar.update)
    try:
        with atomic_write(args.out, "wb") as fh:
            np.savez_compressed(fh, frames=result.frames)
    except OSError as exc:
        raise InputError(f"{args.out}: cannot write ({exc.strerror or exc})") from None
    if args.obj_dir is not None:
        try:
            args.obj_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{args.obj_dir}: cannot create folder ({exc.strerror or exc})") from None
        obj_faces = None if faces is None else np.asarray(faces, dtype=np.int64)
        for t, frame in enumerate(tqdm(result.frames, desc="writing .obj", unit="frame", leave=False)):
            write_obj(args.obj_dir / f"frame_{t:05d}.obj", frame, obj_faces)
    return 0
