"""benchmarks/occlusion.py: each occluder covers the part of the face it is named for and moves with the points; the
covered stretches and the scores count what they say."""

import sys
from pathlib import Path

import numpy as np
import pytest
import synth

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import occlusion as oc  # noqa: E402

SIZE = (320, 400)  # (H, W)


def _face(cx=200.0, cy=150.0, width=120.0) -> np.ndarray:
    """(68, 2) a face's points (package pixels) at (cx, cy)."""
    return synth.project2d(synth.face_layout(), 0.0, width, cx, cy) + 1.0


def _covered(mask, pts, idx) -> float:
    xy = np.rint(pts[idx] - 1.0).astype(int)
    return float(mask[xy[:, 1], xy[:, 0]].mean())


def test_each_occluder_covers_its_part_of_the_face_and_moves_with_it():
    pts = _face()
    mouth = oc.occluder_mask("mouth", pts, SIZE)
    assert _covered(mouth, pts, range(48, 68)) == 1.0 and _covered(mouth, pts, range(36, 48)) == 0.0
    eye = oc.occluder_mask("eye", pts, SIZE)
    assert _covered(eye, pts, range(36, 42)) == 1.0 and _covered(eye, pts, range(42, 48)) == 0.0  # one eye only
    half = oc.occluder_mask("half", pts, SIZE)
    assert _covered(half, pts, range(36, 42)) == 1.0 and _covered(half, pts, range(42, 48)) == 0.0
    mic = oc.occluder_mask("mic", pts, SIZE)
    assert mic[-1].any() and _covered(mic, pts, range(36, 48)) == 0.0  # a stem to the frame's bottom, eyes free
    moved = oc.occluder_mask("mouth", pts + [30.0, -20.0], SIZE)
    assert np.array_equal(np.roll(np.roll(mouth, 30, axis=1), -20, axis=0), moved)


def test_covered_stretches_and_visible_points():
    n = 420
    covered = oc.covered_frames(n)
    assert covered[oc.START:oc.START + oc.SPAN].all() and not covered[:oc.START].any()
    assert covered.sum() == 2 * oc.SPAN  # 100-149 and 300-349: a third would end past the last frame
    frames = [np.full((*SIZE, 3), 90, np.uint8) for _ in range(n)]
    ref = np.stack([_face() for _ in range(n)])
    images, cov, visible, shown = oc.occluded_video(frames, ref, "mouth")
    assert np.array_equal(cov, covered) and images[0] is frames[0] and np.array_equal(shown, ref)
    assert (images[oc.START] == oc.SKIN).all(axis=2).any() and not (images[0] == oc.SKIN).all(axis=2).any()
    assert not visible[oc.START, 48:68].any() and visible[oc.START, 36:48].all() and visible[0].all()


def test_scores_count_what_they_say():
    n = 420
    ref = np.stack([_face() for _ in range(n)])
    covered = oc.covered_frames(n)
    visible = np.ones((n, 68), bool)
    visible[covered, 48:] = False
    landmarks = ref.copy()
    eye = float(np.linalg.norm(ref[0, 45] - ref[0, 36]))
    landmarks[oc.START:oc.START + 10, 48:] += [0.0, -0.5 * eye]  # 10 frames with the mouth pulled up
    success = np.ones(n, bool)
    success[oc.START + 10:oc.START + 20] = False  # 10 lost
    confidence = np.where(success, 0.9, 0.1)
    clean = np.zeros(n)
    row = oc.score(success, landmarks, confidence, ref, covered, visible, clean)
    assert row["covered_frames"] == 100 and abs(row["covered_tracked"] - 0.9) < 1e-12
    assert row["covered_above_010"] == 10  # 20 of 68 points off by 0.5: NME 0.147
    assert abs(row["covered_nme"] - 10 * 0.5 * 20 / 68 / 90) < 1e-9
    assert row["covered_visible_nme"] == 0.0 and abs(row["covered_confidence"] - 0.9) < 1e-12
    assert row["after_tracked"] == 1.0 and row["uncovered_nme"] == 0.0


def test_occluded_stills_and_their_scores():
    pts = np.stack([_face(), _face(cx=180.0, width=100.0)])
    images = [np.full((*SIZE, 3), 90, np.uint8) for _ in range(2)]
    out, visible, shown = oc.occluded_stills(images, pts, "eye")
    assert np.array_equal(shown, pts)
    assert all((o == oc.SKIN).all(axis=2).any() for o in out) and (images[0] == 90).all()  # drawn on copies
    assert not visible[:, 36:42].any() and visible[:, 42:48].all() and visible[:, 48:].all()
    eye = np.linalg.norm(pts[:, 45] - pts[:, 36], axis=1)
    landmarks = pts.copy()
    landmarks[0, 36:42] += [0.0, 0.6 * eye[0]]  # the hidden eye's 6 points off by 0.6: NME 0.053
    landmarks[1] += [0.12 * eye[1], 0.0]  # all off by 0.12
    row = oc.score_stills(np.array([True, True]), landmarks, np.array([0.9, 0.7]), pts, visible)
    assert row["within"] == 0.5 and row["fitted"] == 2 and row["above_010"] == 1
    assert abs(row["nme"] - 0.5 * (6 * 0.6 / 68 + 0.12)) < 1e-9
    assert abs(row["visible_nme"] - 0.5 * (0.0 + 0.12)) < 1e-9 and abs(row["above_010_confidence"] - 0.7) < 1e-12
    lost = oc.score_stills(np.array([False, True]), landmarks, np.array([0.0, 0.7]), pts, visible)
    assert lost["within"] == 0.0 and lost["fitted"] == 1 and abs(lost["nme"] - 0.12) < 1e-9  # not fitted: a failure
    assert np.isnan(row["spearman_confidence_nme"])  # under 3 fits: no rank correlation
    three = np.concatenate([pts, pts[:1]])
    # every point moved by (k, k) eye distances: NME rising, 0.028, 0.071, 0.21
    off = three + np.array([0.02, 0.05, 0.15])[:, None, None] * eye[[0, 1, 0], None, None]
    vis3 = np.ones(three.shape[:2], bool)
    assert oc.score_stills(np.ones(3, bool), off, np.array([0.9, 0.8, 0.3]), three, vis3)[
        "spearman_confidence_nme"] == pytest.approx(-1.0)  # the more confident, the closer
    assert oc.score_stills(np.ones(3, bool), off, np.array([0.3, 0.8, 0.9]), three, vis3)[
        "spearman_confidence_nme"] == pytest.approx(1.0)


def test_the_frames_edge_slides_the_face_out_and_back_with_its_reference():
    """``edge``: over each covered stretch the picture moves left until EDGE_SHARE of the face's width lies past the
    frame's edge (at the stretch's middle) and back; the reference moves with the picture (a dot drawn at a point
    is where the moved point says), the points past the edge count as hidden, the frames outside the stretches
    are untouched."""
    n = 420
    ref = np.stack([_face() for _ in range(n)])
    frames = []
    for p in ref:
        im = np.full((*SIZE, 3), 90, np.uint8)
        x, y = np.rint(p[30] - 1.0).astype(int)  # a dot at the nose tip (OpenCV's pixels)
        im[y - 1:y + 2, x - 1:x + 2] = 250
        frames.append(im)
    images, covered, visible, shown = oc.occluded_video(frames, ref, "edge")
    assert images[0] is frames[0] and np.array_equal(shown[~covered], ref[~covered]) and visible[~covered].all()
    mid = oc.START + oc.SPAN // 2
    width = np.ptp(ref[mid, :, 0])
    past = -(shown[mid, :, 0].min() - 1.0) / width  # the share of the width past the edge
    assert abs(past - oc.EDGE_SHARE) < 0.01
    assert 0.2 < 1 - visible[mid].mean() < 0.6 and not visible[mid][shown[mid, :, 0] < 1.0].any()
    first = oc.START
    assert np.abs(shown[first] - ref[first]).max() < 0.05 * width  # the slide starts where the face is
    for i in (first + 5, mid, first + oc.SPAN - 5):
        x, y = np.rint(shown[i, 30] - 1.0).astype(int)
        assert x >= 1 and images[i][y, x].max() > 200  # the dot (in the frame: 40% out at most) moved with the point
    out, vis, pts = oc.occluded_stills([frames[0]], ref[:1], "edge")
    assert abs(-(pts[0, :, 0].min() - 1.0) / np.ptp(ref[0, :, 0]) - oc.EDGE_SHARE) < 1e-9 and not vis[0].all()
