"""Image pyramids and the choice of octave for each couple (image resolution x texture resolution).

An image resolution is defined relative to the face: a couple with ``face_px = F`` runs on the coarsest
octave o (image downsampled by 2**o with cv2.pyrDown) at which the face is still at least F pixels wide, so
the same learned update matrix serves faces of any size. Octave 0 is the input image.
"""

from __future__ import annotations

import math

import cv2
import numpy as np


def to_gray32(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 grey image from a BGR/grey uint8 or float image."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(image, dtype=np.float32)


def octave_for(face_px: float, couple_face_px: float, n_octaves: int) -> int:
    """Coarsest octave at which a face ``face_px`` wide stays at least ``couple_face_px`` wide."""
    if not np.isfinite(face_px) or face_px <= couple_face_px:
        return 0
    return int(min(max(math.floor(math.log2(face_px / couple_face_px)), 0), n_octaves - 1))


def local_contrast(img: np.ndarray, sigma: float) -> np.ndarray:
    """(I - G*I) / sqrt(G*(I - G*I)^2 + eps): local contrast normalisation (lighting invariance)."""
    d = img - cv2.GaussianBlur(img, (0, 0), sigma)
    return d / np.sqrt(cv2.GaussianBlur(d * d, (0, 0), sigma) + 25.0)


def build_pyramid(gray: np.ndarray, n_octaves: int, *, lcn_sigma: float = 0.0) -> list[np.ndarray]:
    """[octave 0, 1, ...] float32 images; stops early when an octave would be smaller than 8 pixels.
    With ``lcn_sigma`` > 0 every octave is locally contrast-normalised with that Gaussian (pixels of the
    octave, hence a fixed share of the face at the octave a couple runs on)."""
    levels = [gray]
    for _ in range(n_octaves - 1):
        if min(levels[-1].shape) < 16:
            break
        levels.append(cv2.pyrDown(levels[-1]))
    if lcn_sigma > 0:
        levels = [local_contrast(lv, lcn_sigma) for lv in levels]
    return levels
