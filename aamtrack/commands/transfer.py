"""``aamtrack transfer SOURCE TARGET --out OUT.npz``: animate a 3D target face with tracked or dense source motion."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.csvout import read_tracking_csv
from ..io.obj import N_LANDMARKS, NPZ_MESH_KEYS, check_landmark_spread, check_landmarks, check_points, load_npz, read_mesh, save_animation

DESCRIPTION = ("""Transfer facial motion from SOURCE to the neutral 3D face TARGET (Akagi et al.).
SOURCE is a tracking CSV of `aamtrack run` with the 3D model (columns frame, success, X_0..X_67, Y_0..Y_67,
Z_0..Z_67; the first successful row is the neutral face; rows with success=0 take the last good frame's landmarks;
rows before the first success are dropped) or an .npz with `frames` (T, N, 3), frame 0 neutral, and `landmark68`
(68,) vertex indices (optional when N = 68). TARGET is an .obj (landmarks from a `# landmark68 ...` comment line
or --target-landmarks) or an .npz with {NPZ}. Only the 68 landmarks are assumed to correspond;
sizes, vertex order and units may differ. OUT.npz (compressed) holds `frames` (T, M, 3) float32 (frame 0 is the
target), `faces` and `landmark68`; --obj-dir adds one .obj per frame.

example (video -> 3D track -> animated face):
  aamtrack run video.mp4 --out-dir track
  aamtrack transfer track/video.csv face.obj --out anim.npz --obj-dir anim_obj""".replace("{NPZ}", NPZ_MESH_KEYS))


def _read_csv(path: Path) -> tuple[np.ndarray, np.ndarray]:
    cols = read_tracking_csv(path)
    names = [f"{a}_{i}" for a in "XYZ" for i in range(N_LANDMARKS)]
    missing = [c for c in ["success"] + names if c not in cols]
    if missing:
        raise InputError(f"{path}: missing columns {', '.join(missing[:3])}{' ...' if len(missing) > 3 else ''}")
    pts = np.stack([cols[c] for c in names], 1).reshape(-1, 3, N_LANDMARKS).transpose(0, 2, 1)
    good = (np.nan_to_num(cols["success"]) == 1) & np.isfinite(pts).all(axis=(1, 2))
    if not good.any():
        raise InputError(f"{path}: no successful frame (empty sequence)")
    # rows before the first success are dropped; a failed row repeats the last good frame
    last = np.maximum.accumulate(np.where(good, np.arange(len(good)), -1))
    return pts[last[last >= 0]], np.arange(N_LANDMARKS)


def load_source(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(frames (T, N, 3) float64, landmark68 (68,) int64) from a tracking CSV or an .npz."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        frames, lm = _read_csv(path)
    else:
        data = load_npz(path)
        if "frames" not in data:
            raise InputError(f"{path}: missing `frames` (T, N, 3) (keys found: {', '.join(data) or 'none'})")
        frames = np.asarray(data["frames"])
        if frames.ndim != 3 or frames.shape[2] != 3:
            raise InputError(f"{path}: `frames` must be (T, N, 3), got {frames.shape}")
        if len(frames) == 0 or frames.shape[1] == 0:
            raise InputError(f"{path}: empty sequence")
        lm = data.get("landmark68")
        if lm is None and frames.shape[1] == N_LANDMARKS:
            lm = np.arange(N_LANDMARKS)
        if lm is None:
            raise InputError(f"{path}: missing landmark68 (68 landmark vertex indices)")
        lm = check_landmarks(path, lm, frames.shape[1])
    frames = np.stack([check_points(path, f, f"coordinates of frame {t}") for t, f in enumerate(frames)])
    return frames, lm


def load_target(path: str | Path, landmarks_path: str | Path | None = None) -> tuple:
    """(vertices (M, 3) float64, faces (F, k) int64 (maybe empty), landmark68 (68,) int64) from an .obj or .npz."""
    mesh = read_mesh(path, landmarks_path)
    return mesh.vertices, mesh.faces, mesh.landmark68


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "transfer", help="transfer facial motion to a 3D face", description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
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
    check_landmark_spread(args.target_landmarks or args.target, verts[t_lm], "target")
    check_landmark_spread(args.source, frames[0, s_lm], "source")
    if not args.out.parent.is_dir():
        raise InputError(f"{args.out}: folder {args.out.parent} does not exist")
    config = TransferConfig(sampler=SamplerConfig(seed=args.seed))
    # D_fit registers one frame (the target) per sampler round
    with tqdm(desc="fitting the target", unit="round", total=config.sampler.max_rounds, file=sys.stderr,
              disable=None, leave=False) as bar:
        result = transfer(frames, s_lm, verts, t_lm, config=config, progress=bar.update)
    if not np.isfinite(result.frames).all():
        raise InputError(f"{args.target}: degenerate target (the transferred motion is not finite)")
    arrays = {"frames": result.frames, "faces": faces, "landmark68": t_lm}
    with tqdm(total=len(result.frames), desc="writing .obj", unit="file", file=sys.stderr,
              disable=None if args.obj_dir else True, leave=False) as bar:
        save_animation(args.out, arrays, obj_dir=args.obj_dir, faces=faces if len(faces) else None,
                       progress=bar.update)
    print(f"{len(result.frames)} frames, {len(result.key_index)} key points -> {args.out}"
          + (f" and {args.obj_dir}/" if args.obj_dir else ""))
    return 0
