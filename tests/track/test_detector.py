"""Haar detection on synthetic faces: upright, and rolled by 30 degrees (found in a turned copy of the frame)."""

import cv2
import numpy as np
import pytest

from aamtrack.detector import HaarDetector, unturn
import synth


@pytest.fixture(scope="module")
def face():
    ref = synth.face_layout()
    pts = synth.project2d(ref, 0.0, 110.0, 160.0, 120.0)  # a size at which the cascade fires on the synthetic face
    return synth.render(ref, pts, (320, 240)), pts


def test_upright_face_is_found_where_it_is(face):
    img, pts = face
    found = HaarDetector().find(img)
    assert found is not None and found[1] == 0.0
    x, y, w, h = found[0]
    assert abs(x + w / 2 - pts[:, 0].mean()) < 0.2 * w and abs(y + h / 2 - pts[:, 1].mean()) < 0.3 * h


@pytest.mark.parametrize("roll", [30.0, -30.0])
def test_rolled_face_is_found_in_a_turned_frame(face, roll):
    img, pts = face
    M = cv2.getRotationMatrix2D((160.0, 120.0), roll, 1.0)
    rolled = cv2.warpAffine(img, M, (320, 240), borderMode=cv2.BORDER_REPLICATE)
    rolled_pts = pts @ M[:, :2].T + M[:, 2]
    det = HaarDetector()
    found = det.find(rolled)
    assert found is not None
    box, angle = found
    assert angle == -roll  # found in the frame turned back upright
    corners = np.array([[box[0], box[1]], [box[0] + box[2], box[1] + box[3]]])
    centre = unturn(corners, angle, rolled.shape).mean(0)
    assert np.linalg.norm(centre - rolled_pts.mean(0)) < 0.25 * box[2]  # the box, turned back, is on the face


def test_unturn_inverts_the_turn():
    M = cv2.getRotationMatrix2D((50.0, 40.0), 30.0, 1.0)
    pts = np.array([[10.0, 20.0], [70.0, 5.0], [33.0, 61.0]])
    assert np.abs(unturn(pts @ M[:, :2].T + M[:, 2], 30.0, (80, 100)) - pts).max() < 1e-9


@pytest.mark.parametrize("width,expected_widths", [(640, (320, 640, 320, 320)), (320, (320, 320, 320))])
def test_find_searches_upright_then_wider_then_turned(width, expected_widths):
    """On a frame without a face every search runs, in order: upright at DETECT_WIDTH, upright at twice it (only
    for frames wider than DETECT_WIDTH: small faces), then turned by +30 and -30 degrees."""
    from aamtrack import detector as det_module

    calls = []

    class Recording(HaarDetector):
        def detect_all(self, gray, angle=0.0, width=0):
            calls.append((angle, width))
            return super().detect_all(gray, angle, width)

    assert Recording().find(np.full((width * 3 // 4, width), 128, np.uint8)) is None
    assert [w for _, w in calls] == [w * det_module.DETECT_WIDTH // 320 for w in expected_widths]
    assert [a for a, _ in calls] == [0.0] * (len(calls) - 2) + [30.0, -30.0]
