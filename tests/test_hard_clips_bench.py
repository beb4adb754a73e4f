"""benchmarks/hard_clips.py: a face clip moves a rendered marker exactly as it moves the points, black frames sit in
the middle with NaN references, a room clip has the asked size and count, and the scores count what they say."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import hard_clips as hc  # noqa: E402
from test_robustness_bench import _centroid, _marker  # noqa: E402


def _face_points(centre) -> np.ndarray:
    """(68, 2): points around ``centre`` with the outer eye corners (36, 45) 60 px apart and point 30 at centre."""
    rng = np.random.default_rng(0)
    pts = centre + rng.uniform(-40.0, 40.0, (68, 2))
    pts[36], pts[45], pts[30] = centre + [-30.0, -20.0], centre + [30.0, -20.0], centre
    return pts


def test_face_clip_moves_a_marker_as_it_moves_the_points():
    """Frames (400x300) each with a blob at point 30 of its reference; the clip (rolled, panned, shrunk to 30 px
    between the eyes, no blur or noise) puts the blob where it puts point 30: within 0.3 px (sub-pixel)."""
    n = 40
    centres = np.array([[200.0 + 2 * t, 150.0 - t] for t in range(n)])
    refs = np.array([_face_points(c) for c in centres])
    frames = [_marker(c, size=(400, 300), sigma=3.0) for c in centres]
    clip = hc.Clip("t", (320, 240), ((0, n),), eye=30.0, roll=20.0)
    out, moved = hc.face_clip(frames, refs, clip)
    black = np.flatnonzero(np.isnan(moved[:, 0, 0]))
    assert list(black) == list(range(n // 2, n // 2 + hc.N_BLACK))
    assert all(not out[i].any() for i in black)
    face = np.flatnonzero(~np.isnan(moved[:, 0, 0]))
    assert len(face) == n and all(im.shape == (240, 320, 3) for im in out)
    eye = np.linalg.norm(moved[face, 45] - moved[face, 36], axis=1)
    assert np.allclose(eye, 30.0)  # the median eye distance is 60 px in every frame: shrunk by 1/2
    err = []
    for i in face:
        g = out[i].astype(np.float64)
        g = np.clip(g - 90.0, 0.0, None)  # the blob's core only (the border is 60-80 grey levels)
        err.append(np.linalg.norm(_centroid(g) - moved[i, 30]))
    print(f"marker error max {max(err):.3f} px")
    assert max(err) < 0.3  # sub-pixel


def test_room_clip_size_and_count():
    frame = np.full((300, 400, 3), 120, np.uint8)
    face = _face_points(np.array([200.0, 150.0]))
    out = hc.room_clip(frame, face, hc.Clip("r", (320, 240), seed=1), n=5)
    assert len(out) == 5 and all(im.shape == (240, 320, 3) and im.dtype == np.uint8 for im in out)
    assert 10 < float(np.mean(out[0])) < 60  # dark: 120 x (0.45, 0.2, 0.3)


def test_score_clip_counts_tracked_frames_above_the_bar():
    ref = np.stack([_face_points(np.array([100.0, 100.0]))] * 4)
    ref[1] = np.nan  # a black frame
    lm = ref.copy()
    lm[2] += 60.0 * 0.2  # 0.2 x 60 px in x and y: NME 0.28 > 0.10
    lm[1] = 5.0
    row = hc.score_clip(np.array([True, True, True, False]), lm, ref)
    assert row["above"] == 1
    assert row["blank_tracked"] == 1
    assert row["n_face"] == 3 and abs(row["tracked"] - 2 / 3) < 1e-12
