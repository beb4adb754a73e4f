"""The 3D tracking model built on Candide-3: which animation and shape units it uses, and their bounds."""

from __future__ import annotations

import numpy as np

from .candide import Candide
from .shape_model import ShapeModel

# Animation units tracked (AUV numbers of the .wfm file), with the range each may take.
TRACKED_AUS = (
    ("AUV11", "jaw_drop", -0.2, 1.2),
    ("AUV2", "lip_stretcher", -1.0, 1.0),
    ("AUV14", "lip_corner_depressor", -1.0, 1.0),
    ("AUV0", "upper_lip_raiser", -1.0, 1.0),
    ("AUV3", "brow_lowerer", -1.0, 1.0),
    ("AUV5", "outer_brow_raiser", -1.0, 1.0),
    ("AUV6", "eyes_closed", -0.5, 1.2),
)

# Shape units that a frontal face shows (depth-only units such as "Cheeks z" cannot be seen in 2D points).
FRONTAL_SHAPE_UNITS = (
    "Head height",
    "Eyebrows vertical position",
    "Eyes vertical position",
    "Eyes, width",
    "Eyes, height",
    "Eye separation distance",
    "Nose vertical position",
    "Mouth vertical position",
    "Mouth width",
    "Chin width",
)


def _snake(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name.lower()).strip("_").replace("__", "_")


def candide_shape_model(candide: Candide, landmark_map: np.ndarray, *, shape_sd: float = 1.0) -> ShapeModel:
    """The 3D ShapeModel: mean M, the frontal shape units S, the tracked animation units A."""
    au_idx = [candide.anim_index(code) for code, *_ in TRACKED_AUS]
    su_idx = [candide.shape_names.index(name) for name in FRONTAL_SHAPE_UNITS]
    return ShapeModel(
        kind="3d",
        mean=candide.vertices.copy(),
        shape_units=candide.shape_units[su_idx].copy(),
        basis=candide.anim_units[au_idx].copy(),
        triangles=candide.triangles.astype(np.int32),
        landmark_map=landmark_map,
        shape_names=tuple(_snake(n) for n in FRONTAL_SHAPE_UNITS),
        coef_names=tuple(name for _, name, _, _ in TRACKED_AUS),
        coef_lo=np.array([lo for *_, lo, _ in TRACKED_AUS], float),
        coef_hi=np.array([hi for *_, hi in TRACKED_AUS], float),
        shape_sd=np.full(len(su_idx), shape_sd),
    )
