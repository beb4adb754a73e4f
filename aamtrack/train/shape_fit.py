"""Shape learning (sigma learning, poster step 1): the pose, shape units sigma and deformation coefficients
that best project the model's 68 landmarks onto annotated 2D points, by bounded, regularised least squares (the
problem: ``aamtrack.mesh.landmark_fit``), from several starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.landmark_fit import LandmarkFitter, free_pose as _free_pose, unpack
from ..mesh.shape_model import N_POSE, ShapeModel, initial_pose


@dataclass(frozen=True)
class ShapeFit:
    """q (n_q,) float64; shape_params (n_shape,) float64; rms_px: RMS landmark residual in pixels."""

    q: np.ndarray
    shape_params: np.ndarray
    rms_px: float


def fit_landmarks(sm: ShapeModel, points: np.ndarray, *, shape_params: np.ndarray | None = None,
                  fit_sigma: bool = True, q0: np.ndarray | None = None) -> ShapeFit:
    """Fit pose, coefficients and (if ``fit_sigma`` and the model has shape units) sigma to (68, 2) points.

    ``shape_params`` is held when ``fit_sigma`` is False (tracking a known person).
    """
    points = np.asarray(points, float)
    fit_sigma = fit_sigma and sm.n_shape > 0
    sigma_fixed = np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float)
    free_pose = _free_pose(sm)
    fitter = LandmarkFitter(sm)

    starts = [q0] if q0 is not None else []
    base = initial_pose(sm, points, sigma_fixed)
    starts.append(base)
    if sm.kind == "3d" and q0 is None:  # a turned head can fall into the mirror minimum: try both sides
        for ry in (-0.35, 0.35):
            alt = base.copy()
            alt[1] = ry
            starts.append(alt)
    lo, hi = fitter.bounds(fit_sigma)
    best = None
    for q_start in starts:
        x0 = np.r_[q_start[free_pose], q_start[N_POSE:]]
        x0[free_pose.index(3)] = np.log(max(q_start[3], 1e-9))
        if fit_sigma:
            x0 = np.r_[x0, sigma_fixed]
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        x, cost = fitter.solve(points, x0, fit_sigma, sigma_fixed)
        if best is None or cost < best[1]:
            best = (x, cost)
    q, sigma = unpack(best[0], sm, free_pose, fit_sigma, sigma_fixed)
    pred = sm.landmarks(q, sigma)
    rms = float(np.sqrt(((pred - points) ** 2).sum(1).mean()))
    return ShapeFit(q=q, shape_params=np.array(sigma, float), rms_px=rms)
