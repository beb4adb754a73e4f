"""Image resolutions for the couples (image resolution x texture resolution), defined relative to the face.

When tracking, a couple with ``face_px = F`` runs on the image resampled (area interpolation) by
r = min(1, F / face_px), so the face is F pixels wide there whatever its size in the frame (never upsampled: a
smaller face is used as it is), and the contrast normalisation and texture sampling see every face at the same
pixel scale. (With dyadic octaves for tracking too, a 240-pixel face and a 120-pixel face ran the finest couple
at scales 2x apart, and cap12 upscaled to 640x480 lost 5 frames, 40 above NME 0.10; now none.) Training learns
each couple on dyadic octaves instead (``Octaves``, at the end of this module), which measured better.

``cv2.resize`` maps a source coordinate x to ``r * x + (0.5 * r - 0.5)``; the search folds the constant into the
translation (``level_offset``) so the kernels keep the plain ``scale * x`` of their convention.
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


def level_factor(face_px: float, couple_face_px: float) -> float:
    """r = min(1, couple_face_px / face_px): the resampling that makes the face ``couple_face_px`` wide."""
    if not np.isfinite(face_px) or face_px <= couple_face_px:
        return 1.0
    return float(couple_face_px / face_px)


def level_offset(r: float) -> float:
    """Translation (source pixels) to add to q before a search at factor r: r * (x + d) = r * x + 0.5 r - 0.5."""
    return 0.5 - 0.5 / r


def local_contrast(img: np.ndarray, sigma: float) -> np.ndarray:
    """(I - B*I) / sqrt(B*(I - B*I)^2 + eps): local contrast normalisation (lighting invariance), with B a
    box filter of the same standard deviation as a Gaussian of ``sigma`` (width sigma * sqrt(12), odd).
    Box filters cost the same at any width: 23x faster than the Gaussian at sigma 8 on a 480x480 crop,
    with outputs correlated at 0.9998."""
    k = max(3, int(round(sigma * math.sqrt(12.0))) | 1)
    d = img - cv2.blur(img, (k, k))
    return d / np.sqrt(cv2.blur(d * d, (k, k)) + 25.0)


class Levels:
    """The images one frame (or crop) offers the couples: ``get(r)`` resamples by r and contrast-normalises
    (``lcn_sigma`` pixels of the resampled image; 0 for none), once per factor."""

    def __init__(self, gray: np.ndarray, lcn_sigma: float = 0.0):
        self.gray = np.ascontiguousarray(gray, dtype=np.float32)
        self.lcn_sigma = float(lcn_sigma)
        self._cache: dict[float, np.ndarray] = {}
        self._raw: dict[float, np.ndarray] = {1.0: self.gray}

    def _resampled(self, r: float) -> np.ndarray:
        """The image resampled by r, from the nearest finer one already made (r/r' of a smaller image; the
        half-pixel mappings compose exactly: r/r' (r' x + r'/2 - 1/2 + 1/2) - 1/2 = r x + r/2 - 1/2)."""
        img = self._raw.get(r)
        if img is None:
            src = min((f for f in self._raw if f >= r), default=1.0)
            while r / src < 0.5 and min(self._raw[src].shape) >= 4:  # exact halvings first: INTER_AREA's fast path
                half = self._raw.get(src / 2)
                if half is None:
                    half = self._raw[src / 2] = cv2.resize(self._raw[src], None, fx=0.5, fy=0.5,
                                                           interpolation=cv2.INTER_AREA)
                src /= 2
            k = r / src
            img = self._raw[src] if k == 1.0 else cv2.resize(self._raw[src], None, fx=k, fy=k,
                                                             interpolation=cv2.INTER_AREA)
            if min(img.shape) < 2:
                img = np.zeros((2, 2), np.float32)
            self._raw[r] = img
        return img

    def get(self, r: float) -> np.ndarray:
        img = self._cache.get(r)
        if img is None:
            img = self._resampled(min(r, 1.0))
            if self.lcn_sigma > 0:
                img = local_contrast(img, self.lcn_sigma)
            img = np.ascontiguousarray(img, dtype=np.float32)
            self._cache[r] = img
        return img


# Training's resolutions. Models learn each couple on the coarsest dyadic octave (cv2.pyrDown) at which the face
# is still at least F pixels wide -- on helen's ~200-pixel faces, about 2F for the finest couple -- and track at
# exactly F (``level_factor``). Learning at F too was measured worse: cap12 mean NME 0.047 -> 0.049 (max 0.085 ->
# 0.17) at 400x300, 0.048 -> 0.060 at 640x480; so was learning at ~1.5 F with couples (48, 96, 192).


def octave_for(face_px: float, couple_face_px: float, n_octaves: int = 8) -> int:
    """Coarsest octave at which a face ``face_px`` wide stays at least ``couple_face_px`` wide."""
    if not np.isfinite(face_px) or face_px <= couple_face_px:
        return 0
    return int(min(max(math.floor(math.log2(face_px / couple_face_px)), 0), n_octaves - 1))


class Octaves(Levels):
    """Training's images: ``get(r)`` for r = 2**-o is octave o (cv2.pyrDown o times, no half-pixel offset),
    contrast-normalised as in ``Levels``. ``octave_factor`` gives r."""

    def _resampled(self, r: float) -> np.ndarray:
        img = self._raw.get(r)
        if img is None:
            img = self._raw[r] = cv2.pyrDown(self._resampled(2.0 * r))  # octave o from octave o - 1
        return img


def octave_factor(face_px: float, couple_face_px: float) -> float:
    """The resampling factor 2**-o of training's octave for a couple."""
    return 0.5 ** octave_for(face_px, couple_face_px)
