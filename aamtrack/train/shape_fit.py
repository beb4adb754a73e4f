"""Shape learning (sigma learning, poster step 1): the pose, shape units sigma and deformation coefficients
that best project the model's 68 landmarks onto annotated 2D points, by bounded, regularised least squares

    min  sum_i |P(q) L (M + S sigma + A alpha)_i - u_i|^2 / w^2  +  lam_s |sigma / sd|^2  +  lam_c |alpha|^2

with w the face width in pixels (so the weights do not depend on image size) and P the weak-perspective pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.shape_model import N_POSE, ShapeModel, initial_pose, rotation_matrix

LAMBDA_SHAPE = 1e-3
LAMBDA_COEF = 1e-4


@dataclass(frozen=True)
class ShapeFit:
    """q (n_q,) float64; shape_params (n_shape,) float64; rms_px: RMS landmark residual in pixels."""

    q: np.ndarray
    shape_params: np.ndarray
    rms_px: float


def _unpack(x, sm: ShapeModel, free_pose, fit_sigma, sigma_fixed):
    q = np.zeros(sm.n_q)
    n_p = len(free_pose)
    q[free_pose] = x[:n_p]
    q[3] = np.exp(q[3])
    q[N_POSE:] = x[n_p:n_p + sm.n_coef]
    sigma = x[n_p + sm.n_coef:] if fit_sigma else sigma_fixed
    return q, sigma


def _cross(x: float, y: float, z: float) -> np.ndarray:
    """K(v): K(v) @ w = v x w."""
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def landmark_problem(sm: ShapeModel, points: np.ndarray, free_pose: list, fit_sigma: bool, sigma_fixed: np.ndarray):
    """(residuals(x), jacobian(x)) of the fit of x = [free pose (log-scale for the scale), coefficients, sigma if
    ``fit_sigma``] to (68, 2) points (module docstring)."""
    width = float(np.ptp(points[:, 0]) + 1e-9)
    LM = sm.landmark_map @ sm.mean
    LS = np.einsum("lv,kvd->kld", sm.landmark_map, sm.shape_units)
    LA = np.einsum("lv,kvd->kld", sm.landmark_map, sm.basis)
    n_p = len(free_pose)

    n_c = sm.n_coef

    def _rot(q):
        """(R, {axis: dR / d angle}) of R = Rz Ry Rx: dR/drx = R K(x), dR/dry = K(Rz y) R, dR/drz = K(z) R,
        with K(v) the cross-product matrix of v."""
        R = rotation_matrix(*q[:3])
        cz, sz = np.cos(q[2]), np.sin(q[2])
        return R, {0: R @ _cross(1.0, 0.0, 0.0), 1: _cross(-sz, cz, 0.0) @ R, 2: _cross(0.0, 0.0, 1.0) @ R}

    def _shape(q, sigma):
        return LM + np.tensordot(sigma, LS, axes=1) + np.tensordot(q[N_POSE:], LA, axes=1)

    def residuals(x):
        q, sigma = _unpack(x, sm, free_pose, fit_sigma, sigma_fixed)
        R, _ = _rot(q)
        X = _shape(q, sigma)
        u = q[3] * X @ R[0] + q[4]
        v = -q[3] * X @ R[1] + q[5]
        res = [(u - points[:, 0]) / width, (v - points[:, 1]) / width, np.sqrt(LAMBDA_COEF) * q[N_POSE:]]
        if fit_sigma:
            res.append(np.sqrt(LAMBDA_SHAPE) * sigma / sm.shape_sd)
        return np.concatenate(res)

    def jacobian(x):
        """d residuals / dx, analytic (the numerical one cost a residual evaluation per unknown)."""
        q, sigma = _unpack(x, sm, free_pose, fit_sigma, sigma_fixed)
        R, dR = _rot(q)
        X = _shape(q, sigma)
        s = q[3] / width
        n_lm = len(points)
        J = np.zeros((2 * n_lm + n_c + (sm.n_shape if fit_sigma else 0), len(x)))
        for a, j in enumerate(free_pose):
            if j < 3:
                J[:n_lm, a], J[n_lm:2 * n_lm, a] = s * X @ dR[j][0], -s * X @ dR[j][1]
            elif j == 3:
                J[:n_lm, a], J[n_lm:2 * n_lm, a] = s * X @ R[0], -s * X @ R[1]
            else:
                J[(j - 4) * n_lm:(j - 3) * n_lm, a] = 1.0 / width
        cols = [(LA, n_p)] + ([(LS, n_p + n_c)] if fit_sigma else [])
        for B, c0 in cols:
            J[:n_lm, c0:c0 + len(B)] = s * (B @ R[0]).T
            J[n_lm:2 * n_lm, c0:c0 + len(B)] = -s * (B @ R[1]).T
        J[2 * n_lm:2 * n_lm + n_c, n_p:n_p + n_c] = np.sqrt(LAMBDA_COEF) * np.eye(n_c)
        if fit_sigma:
            J[2 * n_lm + n_c:, n_p + n_c:] = np.diag(np.sqrt(LAMBDA_SHAPE) / sm.shape_sd)
        return J

    return residuals, jacobian


def fit_landmarks(sm: ShapeModel, points: np.ndarray, *, shape_params: np.ndarray | None = None,
                  fit_sigma: bool = True, q0: np.ndarray | None = None) -> ShapeFit:
    """Fit pose, coefficients and (if ``fit_sigma`` and the model has shape units) sigma to (68, 2) points.

    ``shape_params`` is held when ``fit_sigma`` is False (tracking a known person).
    """
    from scipy.optimize import least_squares  # imported here: the tracker needs only initial_pose

    points = np.asarray(points, float)
    fit_sigma = fit_sigma and sm.n_shape > 0
    sigma_fixed = np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float)
    free_pose = [0, 1, 2, 3, 4, 5] if sm.kind == "3d" else [2, 3, 4, 5]
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
        lo = np.r_[lo, -3 * sm.shape_sd]
        hi = np.r_[hi, 3 * sm.shape_sd]
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
    q, sigma = _unpack(best.x, sm, free_pose, fit_sigma, sigma_fixed)
    pred = sm.landmarks(q, sigma)
    rms = float(np.sqrt(((pred - points) ** 2).sum(1).mean()))
    return ShapeFit(q=q, shape_params=np.array(sigma, float), rms_px=rms)
