"""benchmarks/still_shots.py: the reflected copies of the labelled face that a shot's border shows lie where
OpenCV's reflection puts them, labelled as a tracker labels the face it sees."""

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import still_shots as ss  # noqa: E402

from aamtrack.mesh.landmarks import IBUG_MIRROR, affine_points  # noqa: E402


def _dot_at(image: np.ndarray) -> np.ndarray:
    """(x, y) of the brightest blob's centroid, package pixels."""
    ys, xs = np.nonzero(image > 100)
    w = image[ys, xs].astype(float)
    return np.array([(xs * w).sum() / w.sum(), (ys * w).sum() / w.sum()]) + 1.0


def test_reflected_copies_lie_where_the_reflected_border_shows_each_point():
    """A photo with one bright dot per probed point, moved by a shot's affine with BORDER_REFLECT so its copies
    show: each copy's point (before the permutation) falls on the copy of its dot within 0.05 px."""
    w, h = 90, 70
    points = np.zeros((68, 2))
    points[:, 0], points[:, 1] = np.linspace(12, 70, 68) + 0.5, np.linspace(15, 50, 68)  # package pixels
    copies = ss.reflected_copies(points, (w, h))
    assert copies.shape == (8, 68, 2)
    A = np.array([[1.0, 0.0, 100.0], [0.0, 1.0, 80.0]])  # the photo in the middle of a 290 x 230 frame
    for k in (0, 36, 67):
        img = np.zeros((h, w), np.uint8)
        x, y = np.rint(points[k] - 1.0).astype(int)
        img[y, x] = 255
        frame = cv2.warpAffine(img, A, (290, 230), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        here = affine_points(np.array([[x + 1.0, y + 1.0]]), A)[0]
        assert np.abs(_dot_at(frame[70:160, 90:200]) + [90, 70] - here).max() < 0.05  # the photo itself
        snapped = points.copy()
        snapped[k] = [x + 1.0, y + 1.0]
        moved = affine_points(ss.reflected_copies(snapped, (w, h)), A)
        for c in range(8):
            once = c in (1, 3, 4, 6)  # left, above, below, right: mirrored once (the corners twice)
            q = moved[c][np.argsort(IBUG_MIRROR)] if once else moved[c]  # undo the relabelling
            q = q[k]
            x0, y0 = int(q[0] - 6), int(q[1] - 6)
            assert 0 <= x0 and 0 <= y0 and x0 + 12 <= 290 and y0 + 12 <= 230
            assert np.abs(_dot_at(frame[y0:y0 + 12, x0:x0 + 12]) + [x0, y0] - q).max() < 0.05


def test_a_copy_mirrored_once_is_relabelled_and_a_corner_copy_not():
    """Left and right swap in a copy mirrored once (the tracker labels the eye on its left as the left eye), not
    in a corner's, which is turned by 180 degrees."""
    pts = np.random.default_rng(0).uniform(10, 60, (68, 2))
    copies = ss.reflected_copies(pts, (80, 80))
    above, corner = copies[3], copies[0]  # the copy above the photo; the top-left corner's
    flipped = -1.0 - (pts - 1.0) + 1.0  # each coordinate reflected about the first pixel's outer edge
    assert np.allclose(above[IBUG_MIRROR], np.stack([pts[:, 0], flipped[:, 1]], 1))  # relabelled
    assert np.allclose(corner, flipped)  # not relabelled
