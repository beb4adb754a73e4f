"""Plain result records of fitting and tracking (frozen dataclasses; a failure is a status, never None)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from typing import Literal

Status = Literal["detected", "tracked", "lost", "dropped", "unreadable"]
STATUSES: tuple = Status.__args__


@dataclass(frozen=True)
class FitResult:
    """One active search on one image.

    p : (n_params,) float64 -- final search vector (pose, coefficients, shape units; ``Model.param_names``)
    landmarks : (68, 2) float64 -- iBUG-68 points in image pixels
    vertices : (n_vertices, 2) float64 -- all model vertices in image pixels
    residual : float -- final RMS of the normalised texture residual
    iterations : tuple of int -- iterations (cascade stages) run per couple, coarse to fine
    stats : tuple of float -- the fit statistics the validator reads (``aamtrack.model.STAT_NAMES``)
    confidence : float -- 0..1, the model's validator on ``stats``: how likely the fit is on a face
    landmark_prior : (68, 2) float64 or None -- the part of the landmark cascade's move of the points that its
        stages' shape term made (``LandmarkCascade.run``): what the points' shape says of itself rather than the
        image; None before the cascade
    dim : bool -- the confidence is the validator for dim faces' (``Model.validator_for``): the face's contrast
        over the image's noise is low
    soft : bool -- the points are the soft landmark cascade's (``Model.cascade_for``): the face looks blurred
    """

    p: np.ndarray
    landmarks: np.ndarray
    vertices: np.ndarray
    residual: float
    iterations: tuple = ()
    stats: tuple = ()
    confidence: float = 0.0
    landmark_prior: np.ndarray | None = None
    dim: bool = False
    soft: bool = False


@dataclass(frozen=True)
class FrameResult:
    """What the tracker says of one frame.

    status : one of STATUSES. ``success`` is True for "detected" and "tracked".
    landmarks : (68, 2) float64 image pixels, NaN where not successful
    landmarks3d : (68, 3) float64 millimetres in the model's own frame (pose removed; the mean face's outer eye
        corners 89 mm apart, ``ShapeModel.mm_per_unit``), 3D model only, else None
    rotation : (3,) float64 radians (Rx, Ry, Rz); 2D model: (0, 0, roll)
    translation : (2,) float64 pixels; scale : float (pixels per model unit)
    anim_params, shape_params : 1-D float64, named by the shape model's ``coef_names`` / ``shape_names``
    vertices : (n_vertices, 2) float64 mesh vertices in pixels (for overlays), NaN where not successful
    confidence : 0..1, the model's fit validator (``Model.validator``)
    reason : why the frame has no result ("no face detected", "low confidence ..."); empty when successful, but for
        a frame tracked back from a later detection ("tracked back from frame N", ``TrackerConfig.backfill``)
    """

    frame: int
    timestamp: float
    status: Status
    confidence: float = 0.0
    landmarks: np.ndarray = field(default_factory=lambda: np.full((68, 2), np.nan))
    landmarks3d: np.ndarray | None = None
    rotation: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    translation: np.ndarray = field(default_factory=lambda: np.full(2, np.nan))
    scale: float = float("nan")
    anim_params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    shape_params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vertices: np.ndarray | None = None
    timings: dict = field(default_factory=dict)
    reason: str = ""

    @property
    def success(self) -> bool:
        return self.status in ("detected", "tracked")
