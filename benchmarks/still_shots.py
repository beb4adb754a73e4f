"""Tracking faces the model has never seen: held-out photos played as video shots, cut one to the next.

    python benchmarks/still_shots.py --model models/3d.npz [--model models/2d.npz] [--shots 40] [--frames 60]
        [--config 'tracked_start="search",landmark_stages_tracked=2,cut_below=0'] [--json OUT]

Each shot is one helen_test photo (held out from training; photos whose outer eye corners are at least 40 px
apart and in which Haar finds one face only, drawn with a fixed seed) scaled so the outer eye corners are 90 px apart in a 640x480 frame, with a slow
pan (30 px) and zoom (8%) over ``--frames`` frames; the shots follow one another with hard cuts, a new person at
each. The labels move with the image. The frame is filled by reflecting the photo at its borders, so mirrored
parts of the photo (sometimes of the face) appear towards the frame's edges. One ``Tracker.track`` runs over the whole sequence, as ``aamtrack run``
would (no smoothing).

Reports per model and tracker configuration: the share of all frames tracked with NME <= 0.08, the mean NME over
those, the tracked frames with NME > 0.10 and how many of them are fits of a reflected copy of the face (within
0.10 of a copy's points, ``reflected_copies``: a real face, followed where the shot shows it, but not the labelled
one), and the median over the shots of each shot's mean NME. ``--config`` adds a run with
``TrackerConfig`` fields changed (repeatable; values are Python literals), next to the default. The cap12 video
shows one person; this is the check that tracked frames of other faces keep the accuracy of a detection's fit.
Photos stand still, so it says nothing of motion blur or expression changes.
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from aamtrack.detector import HaarDetector
from aamtrack.io.dataset import find_pairs, load_pair
from aamtrack.io.frames import Frame
from aamtrack.mesh.landmarks import IBUG_MIRROR, affine_points
from aamtrack.metrics import PIXEL_ORIGIN, nme
from aamtrack.model import load_model
from aamtrack.track.tracker import Tracker, TrackerConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_name, write_json  # noqa: E402

SIZE = (640, 480)
EYE_PX = 90.0


def reflected_copies(points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(8, 68, 2): where the labelled face's copies lie that ``cv2.BORDER_REFLECT`` shows around a photo of
    ``size`` (w, h) (left, right, above, below and the corners; OpenCV reflects about the outer pixels' edges,
    x -> -1 - x and 2 w - 1 - x in its pixels), in the package's convention, each labelled as a tracker labels the
    face it sees: a copy mirrored once has its left and right swapped (``IBUG_MIRROR``), a corner's (mirrored
    twice: turned by 180 degrees) not. Order: (x side, y side) over (-1, 0, 1)^2 less (0, 0), y fastest."""
    w, h = size
    x, y = points[:, 0] - PIXEL_ORIGIN, points[:, 1] - PIXEL_ORIGIN
    xs, ys = {-1: -1.0 - x, 0: x, 1: 2.0 * w - 1.0 - x}, {-1: -1.0 - y, 0: y, 1: 2.0 * h - 1.0 - y}
    out = []
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            if i == j == 0:
                continue
            q = np.stack([xs[i], ys[j]], axis=1) + PIXEL_ORIGIN
            out.append(q[IBUG_MIRROR] if (i == 0) != (j == 0) else q)
    return np.array(out)


def build_shots(data: Path, n_shots: int, n_frames: int, seed: int = 3) -> tuple:
    """(frames BGR, references (n, 68, 2), shot index per frame, the reflected copies' points per frame (n, 8, 68,
    2): ``reflected_copies``)."""
    pairs = sorted(find_pairs(data), key=lambda t: t[0].name)
    order = np.random.default_rng(seed).permutation(len(pairs))
    frames, refs, shot, mirrored = [], [], [], []
    W, H = SIZE
    detector = HaarDetector()
    k = 0
    for i in order:
        if k == n_shots:
            break
        img, P = load_pair(*pairs[i])
        eye = float(np.linalg.norm(P[45] - P[36]))
        if eye < 40:
            continue
        c = P.mean(0)
        s0 = EYE_PX / eye
        first = cv2.warpAffine(img, np.array([[s0, 0.0, W / 2 - s0 * c[0]], [0.0, s0, H / 2 - s0 * c[1]]]), (W, H),
                               flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        if len(detector.detect_all(first)) > 1:
            continue  # a second face (or a reflected copy): which face a track follows is not the question here
        for t in range(n_frames):
            u = t / max(n_frames - 1, 1)
            s = EYE_PX / eye * (1.0 + 0.08 * u)
            A = np.array([[s, 0.0, W / 2 + 30 * np.sin(2 * np.pi * u + k) - s * c[0]],
                          [0.0, s, H / 2 + 15 * np.cos(2 * np.pi * u + k) - s * c[1]]])
            frames.append(cv2.warpAffine(img, A, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT))
            refs.append(affine_points(P, A))
            shot.append(k)
            mirrored.append(affine_points(reflected_copies(P, (img.shape[1], img.shape[0])), A))
        k += 1
    return frames, np.array(refs), np.array(shot), np.array(mirrored)


def evaluate(model, frames, refs, shot, copies, config: TrackerConfig) -> dict:
    results = list(Tracker(model, config=config).track(Frame(i, i / 25.0, f) for i, f in enumerate(frames)))
    ok = np.array([r.success for r in results])
    err = np.array([nme(r.landmarks, refs[i]) if r.success else np.inf for i, r in enumerate(results)])
    good = err <= 0.08
    # tracked frames above 0.10 whose fit lies within 0.10 of a reflected copy of the face
    on_copy = sum(min(nme(results[i].landmarks, c) for c in copies[i]) <= 0.10 for i in np.flatnonzero(ok & (err > 0.10)))
    shot_means = [float(err[(shot == k) & ok].mean()) for k in range(shot.max() + 1) if ((shot == k) & ok).any()]
    return {"frames": len(frames), "tracked": int(ok.sum()), "share_within_0.08": float(good.mean()),
            "nme_mean_within_0.08": float(err[good].mean()) if good.any() else float("nan"),
            "tracked_above_0.10": int((ok & (err > 0.10)).sum()), "of_those_on_a_copy": int(on_copy),
            "median_shot_mean": float(np.median(shot_means)) if shot_means else float("nan")}


def parse_config(text: str) -> dict:
    out = {}
    for item in text.split(","):
        key, _, value = item.partition("=")
        out[key.strip()] = ast.literal_eval(value.strip())
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, action="append", required=True)
    ap.add_argument("--data", type=Path, default=Path("../shared/data/300w/helen_test"))
    ap.add_argument("--shots", type=int, default=40)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--config", action="append", default=[], help="TrackerConfig changes, e.g. cut_below=0")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    frames, refs, shot, copies = build_shots(args.data, args.shots, args.frames)
    print(f"{machine_name()}; {shot.max() + 1} shots, {len(frames)} frames")
    print("| model | tracker | tracked | within 0.08 | NME mean (within) | tracked > 0.10 | of those on a reflected copy "
          "| median shot mean |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for path in args.model:
        model = load_model(path)
        for text in ["default"] + args.config:
            cfg = TrackerConfig() if text == "default" else replace(TrackerConfig(), **parse_config(text))
            r = evaluate(model, frames, refs, shot, copies, cfg)
            rows.append({"model": str(path), "config": text, **r})
            print(f"| {path.name} | {text} | {r['tracked']} / {r['frames']} | {r['share_within_0.08']:.1%} | "
                  f"{r['nme_mean_within_0.08']:.4f} | {r['tracked_above_0.10']} | {r['of_those_on_a_copy']} | "
                  f"{r['median_shot_mean']:.4f} |", flush=True)
    if args.json:
        write_json(args.json, {"machine": machine_name(), "shots": int(shot.max() + 1), "rows": rows})
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "still_shots")
