"""``aamtrack refine TEMPLATE SCANS --out OUT.npz``: make a person's neutral mesh follow a sequence of 3D scans
(point clouds without correspondence between frames) with the help of 68 landmarks per frame (Akagi et al.)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..errors import InputError, OutputError
from ..io.atomic import check_replaceable
from ..io.csvout import read_tracking_csv
from ..io.obj import N_LANDMARKS, check_landmark_spread, check_points, frame_files, load_npz, read_mesh, read_point_cloud, save_animation

DESCRIPTION = """Track a 3D scan sequence with a template mesh (Akagi et al.: RBF deformation driven by key points
refined by GMM registration). TEMPLATE is the person's neutral mesh, frame 0 of the sequence: an .obj (landmarks
from a `# landmark68 ...` comment line or --template-landmarks) or an .npz with `vertices` (M, 3), optional
`faces` and `landmark68` (68,) vertex indices (or ICT FaceKit's `neutral`, `quads`, `landmark68_vertex_idx`).
SCANS is an .npz with `points` (T, N, 3) and `landmarks` (T, 68, 3), or a folder of one .obj/.ply point cloud per
frame (name order, any sizes) with the landmarks in a CSV of columns X_0..X_67, Y_0..Y_67, Z_0..Z_67, one row per
frame (--landmarks, default the one .csv in the folder). Point order may change from frame to frame; scan frame 0
is the template's. OUT.npz holds `frames` (T, M, 3) float32 (frame 0 is the template), `key_index` (K,) the
template vertices used as key points (the first 68 are the landmarks), `key_positions` (T, K, 3), `faces`.

example:
  aamtrack refine neutral.obj scans.npz --out tracked.npz --obj-dir tracked_obj"""


def register(sub) -> None:
    p = sub.add_parser("refine", help="track a 3D scan sequence with a template mesh", description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("template", type=Path, help="neutral mesh: .obj or .npz")
    p.add_argument("scans", type=Path, help=".npz with `points` and `landmarks`, or a folder of .obj/.ply scans")
    p.add_argument("--out", type=Path, required=True, help="output .npz (frames, key points)")
    p.add_argument("--obj-dir", type=Path, help="also write one .obj per frame into this folder")
    p.add_argument("--landmarks", type=Path, help="landmark CSV for a folder of scans (X_i, Y_i, Z_i columns)")
    p.add_argument("--template-landmarks", type=Path, help="text file of the template's 68 landmark vertices")
    p.add_argument("--seed", type=int, default=0, help="seed of the key point sampler (default 0)")
    p.add_argument("--smooth-frames", type=float, default=2.0, metavar="SIGMA",
                   help="smooth the key points' scan corrections over time by a Gaussian of SIGMA frames (default 2: "
                        "for noisy, partial scans; 0: off, for clean scans of fast motion)")
    p.set_defaults(func=run)


def _landmark_csv(path: Path) -> np.ndarray:
    """(T, 68, 3) float64 landmarks from a CSV with X_i, Y_i, Z_i columns, one row per frame."""
    cols = read_tracking_csv(path)
    names = [f"{a}_{i}" for a in "XYZ" for i in range(N_LANDMARKS)]
    missing = [c for c in names if c not in cols]
    if missing:
        raise InputError(f"{path}: missing columns {', '.join(missing[:3])}{' ...' if len(missing) > 3 else ''} "
                         f"(expected X_0..X_67, Y_0..Y_67, Z_0..Z_67)")
    lms = np.stack([cols[c] for c in names], 1).reshape(-1, 3, N_LANDMARKS).transpose(0, 2, 1)
    if len(lms) == 0:
        raise InputError(f"{path}: no rows")
    bad = ~np.isfinite(lms).all(axis=(1, 2))
    if bad.any():
        raise InputError(f"{path}: row {int(np.argmax(bad)) + 2}: empty or non-finite landmark coordinates")
    return lms


def load_scans(path: Path, landmarks_path: Path | None = None) -> tuple[list, np.ndarray]:
    """(list of T (N_t, 3) float64 point clouds, (T, 68, 3) float64 landmarks); InputError when anything is bad."""
    if path.is_dir():
        files = frame_files(path)
        if not files:
            raise InputError(f"{path}: no .obj or .ply scans in the folder")
        if landmarks_path is None:
            csvs = sorted(path.glob("*.csv"))
            if len(csvs) != 1:
                raise InputError(f"{path}: pass --landmarks CSV ({len(csvs)} .csv files in the folder, need exactly 1)")
            landmarks_path = csvs[0]
        landmarks = _landmark_csv(landmarks_path)
        if len(landmarks) != len(files):
            raise InputError(f"{landmarks_path}: {len(landmarks)} landmark rows for {len(files)} scans in {path}")
        scans = [read_point_cloud(f) for f in files]
    else:
        data = load_npz(path)
        missing = [k for k in ("points", "landmarks") if k not in data]
        if missing:
            raise InputError(f"{path}: missing {' and '.join(f'`{k}`' for k in missing)} (expected `points` "
                             f"(T, N, 3) and `landmarks` (T, 68, 3))")
        points, landmarks = data["points"], data["landmarks"]
        if points.ndim != 3 or points.shape[2] != 3 or points.shape[0] == 0 or points.shape[1] == 0:
            raise InputError(f"{path}: `points` must be (T, N, 3) with T, N >= 1, got {points.shape}")
        scans = [check_points(path, p, f"`points` of frame {t}") for t, p in enumerate(points)]
        if landmarks_path is not None:
            landmarks = _landmark_csv(landmarks_path)
    landmarks = np.asarray(landmarks)
    if landmarks.shape != (len(scans), N_LANDMARKS, 3):
        raise InputError(f"{landmarks_path or path}: landmarks must be ({len(scans)}, {N_LANDMARKS}, 3) for "
                         f"{len(scans)} scans, got {landmarks.shape}")
    for t, lm in enumerate(landmarks):
        check_points(landmarks_path or path, lm, f"landmarks of frame {t}")
    return scans, landmarks.astype(np.float64)


def _check_obj_dir(path: Path) -> None:
    """OutputError unless ``path`` is a folder or can be made one (no file on it or on a parent)."""
    p = path
    while not p.exists() and not p.is_symlink() and p != p.parent:
        p = p.parent
    if not p.is_dir():
        raise OutputError(f"{p}: exists and is not a folder (--obj-dir {path})")


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from ..refine.sampler import KeyPoints, SamplerConfig, deform_frames, refine_key_points

    mesh = read_mesh(args.template, args.template_landmarks)
    scans, landmarks = load_scans(args.scans, args.landmarks)
    check_landmark_spread(args.template_landmarks or args.template, mesh.vertices[mesh.landmark68], "template")
    if len(scans) < 2:
        raise InputError(f"{args.scans}: one frame only: nothing to track (frame 0 is the template)")
    if not args.out.parent.is_dir():
        raise InputError(f"{args.out}: folder {args.out.parent} does not exist")
    # the outputs are checked before the (long) tracking, not only when they are written
    check_replaceable(args.out)
    if args.obj_dir is not None:
        _check_obj_dir(args.obj_dir)
    if min(len(s) for s in scans) < 4:
        raise InputError(f"{args.scans}: a scan has fewer than 4 points")
    if not args.smooth_frames >= 0:
        raise InputError(f"--smooth-frames must be 0 or more, got {args.smooth_frames}")
    config = SamplerConfig(seed=args.seed, temporal=args.smooth_frames)
    n_reg = len(scans) - 1
    with tqdm(total=n_reg, desc="round 1", unit="frame", file=sys.stderr, disable=None) as bar:
        state = {"round": 1}

        def progress(n: int) -> None:
            if bar.n >= n_reg:  # a new sampler round registers every frame again
                state["round"] += 1
                bar.reset(total=n_reg)
                bar.set_description(f"round {state['round']}")
            bar.update(n)

        keys = refine_key_points(mesh.vertices, scans, landmarks, mesh.landmark68, config=config, progress=progress)
    frames = np.empty((len(scans), len(mesh.vertices), 3), np.float32)
    for a in range(0, len(frames), 64):  # in chunks of frames: float64 only for 64 frames at a time
        part = KeyPoints(keys.index, keys.positions[a:a + 64], keys.n_fixed)
        frames[a:a + 64] = deform_frames(mesh.vertices, part, kernel=config.kernel, smoothing=config.smoothing)
    frames[0] = mesh.vertices  # exactly the template (float32)
    if not np.isfinite(frames).all():
        raise InputError(f"{args.template}: degenerate template (the deformation is not finite)")
    faces = mesh.faces if len(mesh.faces) else None
    arrays = {"frames": frames, "key_index": keys.index,
              "key_positions": keys.positions.astype(np.float32), "landmark68": mesh.landmark68,
              "faces": mesh.faces}
    with tqdm(total=len(frames) if args.obj_dir else 0, desc="writing .obj", unit="file", file=sys.stderr,
              disable=None if args.obj_dir else True) as bar:
        save_animation(args.out, arrays, obj_dir=args.obj_dir, faces=faces, progress=bar.update)
    print(f"{len(frames)} frames, {len(keys.index)} key points ({keys.n_fixed} landmarks); scan distance "
          f"{keys.errors[0]:.4g} -> {keys.errors[-1]:.4g} -> {args.out}"
          + (f" and {args.obj_dir}/" if args.obj_dir else ""))
    return 0
