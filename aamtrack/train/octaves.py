"""Training's resolutions. Models learn each couple on the coarsest dyadic octave (cv2.pyrDown) at which the face
is still at least F pixels wide -- on helen's ~200-pixel faces, about 2F for the finest couple -- and track at
exactly F (``aamtrack.imaging.level_factor``). Learning at F too was measured worse (cap12 mean NME 0.047 ->
0.049, max 0.085 -> 0.17, with the intensity model)."""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..imaging import Levels


def octave_for(face_px: float, couple_face_px: float, n_octaves: int = 8) -> int:
    """Coarsest octave at which a face ``face_px`` wide stays at least ``couple_face_px`` wide."""
    if not np.isfinite(face_px) or face_px <= couple_face_px:
        return 0
    return int(min(max(math.floor(math.log2(face_px / couple_face_px)), 0), n_octaves - 1))


def octave_factor(face_px: float, couple_face_px: float) -> float:
    """The resampling factor 2**-o of training's octave for a couple."""
    return 0.5 ** octave_for(face_px, couple_face_px)


class Octaves(Levels):
    """Training's images: ``get(r)`` for r = 2**-o is octave o (cv2.pyrDown o times, no half-pixel offset),
    with the features of ``Levels``."""

    def _resampled(self, r: float) -> np.ndarray:
        img = self._raw.get(r)
        if img is None:
            img = self._raw[r] = cv2.pyrDown(self._resampled(2.0 * r))  # octave o from octave o - 1
        return img
