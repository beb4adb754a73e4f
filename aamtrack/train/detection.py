"""Detector calibration at training time: where the landmarks sit in a Haar box, and how far the rough pose
from a box lies from the true fit (the capture range the cascade must learn)."""

from __future__ import annotations

import logging

import cv2
import numpy as np

from ..detector import HaarDetector

log = logging.getLogger(__name__)


def training_boxes(images, points: np.ndarray, detector: HaarDetector | None = None) -> np.ndarray:
    """(n, 4) Haar box (x, y, w, h) of the annotated face in each image (box centre within a quarter box of the
    landmarks' centre), NaN where the detector does not find it."""
    detector = detector or HaarDetector()
    out = np.full((len(points), 4), np.nan)
    for i, (img, pts) in enumerate(zip(images, points)):
        gray = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        centre = pts.mean(0)
        for x, y, w, h in detector.detect_all(gray):
            if np.hypot(x + w / 2 - centre[0], y + h / 2 - centre[1]) < 0.25 * w:
                out[i] = (x, y, w, h)
                break
    return out


def box_geometry(boxes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(68, 2) mean landmark positions in box units over the images with a box. Without any (e.g. synthetic
    faces), the landmarks' own square box stands in (logged)."""
    ok = np.isfinite(boxes[:, 0])
    if not ok.any():
        log.warning("the Haar detector found none of the training faces; box geometry taken from the landmarks")
        c = points.mean(1, keepdims=True)
        side = np.ptp(points, axis=1).max(1)[:, None, None]
        return ((points - (c - side / 2)) / side).mean(0)
    b = boxes[ok]
    rel = (points[ok] - b[:, None, :2]) / b[:, None, 2:]
    return rel.mean(0)
