"""Face localisation for the first frame and after a loss (poster, "Face localization"): OpenCV's Haar
frontal face detector (the cascade shipped in the opencv wheel), the largest face, and a rough pose fitted to
feature points guessed from the box. Where the points sit in a Haar box is learned at training time
(``aamtrack.train.detection``: mean of the annotated landmarks in box units over the training images)."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from .errors import InputError

log = logging.getLogger(__name__)

CASCADE = "haarcascade_frontalface_default.xml"
DETECT_WIDTH = 320  # frames are detected at about this width (faster; faces over ~25% of the width)


ROLLED = (30.0, -30.0)  # degrees the frame is also turned by when no upright face is found


class HaarDetector:
    """``detect(gray)`` -> (x, y, w, h) float box of the largest face in pixels, or None; ``find(gray)`` also
    looks for faces rolled by about 30 degrees (the frontal cascade misses them), in turned copies of the frame."""

    def __init__(self, *, min_face_fraction: float = 0.08, scale_factor: float = 1.1, min_neighbors: int = 4,
                 rolled: tuple = ROLLED):
        path = Path(cv2.data.haarcascades) / CASCADE
        self.cascade = cv2.CascadeClassifier(str(path))
        if self.cascade.empty():
            raise InputError(f"{path}: cannot load OpenCV's Haar face cascade (opencv wheel without cascades?)")
        self.min_face_fraction = min_face_fraction
        self.scale_factor = scale_factor
        self.min_neighbors = min_neighbors
        self.rolled = tuple(rolled)

    def detect_all(self, gray: np.ndarray, angle: float = 0.0, width: int = 0) -> np.ndarray:
        """(n, 4) float boxes (x, y, w, h), largest first, in the frame turned by ``angle`` degrees
        (counterclockwise on screen) about its centre (``unturn`` maps points back), searched at ``width``
        pixels wide at most (default ``DETECT_WIDTH``)."""
        if gray.ndim == 3:
            gray = cv2.cvtColor(gray, cv2.COLOR_BGR2GRAY)
        if gray.dtype != np.uint8:
            gray = np.clip(gray, 0, 255).astype(np.uint8)
        f = min(1.0, (width or DETECT_WIDTH) / gray.shape[1])
        small = cv2.resize(gray, None, fx=f, fy=f, interpolation=cv2.INTER_AREA) if f < 1 else gray
        small = cv2.equalizeHist(small)
        if angle:
            h, w = small.shape
            M = cv2.getRotationMatrix2D((w / 2, h / 2), angle, 1.0)
            small = cv2.warpAffine(small, M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        m = max(20, int(self.min_face_fraction * min(small.shape)))
        boxes = self.cascade.detectMultiScale(small, scaleFactor=self.scale_factor,
                                              minNeighbors=self.min_neighbors, minSize=(m, m))
        if len(boxes) == 0:
            return np.zeros((0, 4))
        boxes = np.asarray(boxes, float) / f
        return boxes[np.argsort(-boxes[:, 2] * boxes[:, 3])]

    def detect(self, gray: np.ndarray):
        boxes = self.detect_all(gray)
        return boxes[0] if len(boxes) else None

    def find(self, gray: np.ndarray) -> tuple[np.ndarray, float] | None:
        """(box, angle): the largest upright face, else the largest upright one at twice the detection width
        (small faces: on cap12 shrunk to 30 px between the eyes, 20 of 60 frames found against 0), else the
        largest in the frame turned by each of ``rolled`` degrees (the box is in that turned frame: ``unturn``
        maps points back); None when there is none. A frame without a face costs all of these searches."""
        tries = [(0.0, DETECT_WIDTH)]
        if gray.shape[1] > DETECT_WIDTH:
            tries.append((0.0, 2 * DETECT_WIDTH))
        tries += [(angle, DETECT_WIDTH) for angle in self.rolled]
        for angle, width in tries:
            boxes = self.detect_all(gray, angle, width)
            if len(boxes):
                return boxes[0], angle
        return None


def unturn(points: np.ndarray, angle: float, shape: tuple) -> np.ndarray:
    """(n, 2) points of a frame turned by ``angle`` degrees about its centre (``HaarDetector.detect_all``),
    mapped back to the frame of ``shape`` (H, W[, C])."""
    if not angle:
        return np.asarray(points, float)
    H, W = shape[:2]
    inv = cv2.invertAffineTransform(cv2.getRotationMatrix2D((W / 2, H / 2), angle, 1.0))
    return np.asarray(points, float) @ inv[:, :2].T + inv[:, 2]


def guess_points(box, box_points: np.ndarray) -> np.ndarray:
    """(68, 2) landmarks guessed from a box with the learned mean positions ``box_points`` (box units)."""
    x, y, w, h = box
    return np.column_stack([x + w * box_points[:, 0], y + h * box_points[:, 1]])
