"""Shape learning (sigma learning, poster step 1): the pose, shape units sigma and deformation coefficients
that best project the model's 68 landmarks onto annotated 2D points, by bounded, regularised least squares (the
problem: ``aamtrack.mesh.landmark_fit``), from several starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.landmark_fit import SIGMA_BOUND_SD, free_pose as _free_pose, landmark_problem, unpack
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
    from scipy.optimize import least_squares  # imported here: the tracker needs only initial_pose

    points = np.asarray(points, float)
    fit_sigma = fit_sigma and sm.n_shape > 0
    sigma_fixed = np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float)
    free_pose = _free_pose(sm)
    n_p = len(free_pose)
    residuals, jacobian = landmark_problem(sm, points, free_pose, fit_sigma, sigma_fixed)

    starts = [q0] if q0 is not None else []
    base = initial_pose(sm, points, sigma_fixed)
    starts.append(base)
    if sm.kind == "3d" and q0 is None:  # a turned head can fall into the mirror minimum: try both sides
        for ry in (-0.35, 0.35):
            alt = base.copy()
            alt[1] = ry
            starts.append(alt)
    lo_q, hi_q = sm.bounds()
    lo = np.r_[np.full(n_p, -np.inf), lo_q[N_POSE:]]
    hi = np.r_[np.full(n_p, np.inf), hi_q[N_POSE:]]
    lo[free_pose.index(3)], hi[free_pose.index(3)] = -np.inf, np.inf
    if fit_sigma:
        lo = np.r_[lo, -SIGMA_BOUND_SD * sm.shape_sd]
        hi = np.r_[hi, SIGMA_BOUND_SD * sm.shape_sd]
    best = None
    for q_start in starts:
        x0 = np.r_[q_start[free_pose], q_start[N_POSE:]]
        x0[free_pose.index(3)] = np.log(max(q_start[3], 1e-9))
        if fit_sigma:
            x0 = np.r_[x0, sigma_fixed]
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        sol = least_squares(residuals, x0, jac=jacobian, bounds=(lo, hi), x_scale="jac", max_nfev=200)
        if best is None or sol.cost < best.cost:
            best = sol
    q, sigma = unpack(best.x, sm, free_pose, fit_sigma, sigma_fixed)
    pred = sm.landmarks(q, sigma)
    rms = float(np.sqrt(((pred - points) ** 2).sum(1).mean()))
    return ShapeFit(q=q, shape_params=np.array(sigma, float), rms_px=rms)
