"""Update matrix learning (poster step 3): for one couple, the gradient G of the projected residual with respect
to each searched parameter, estimated on the training images by perturbing each parameter of the ground-truth
fit by known amounts (several magnitudes, both signs; slope by least squares through the origin), and
U = -(G^T G)^-1 G^T, computed with a solve (plus a ridge of 1e-6 of the mean diagonal, for conditioning)."""

from __future__ import annotations

import numpy as np

from ..mesh.shape_model import N_POSE, ShapeModel

# Perturbation magnitudes (one sign; both are used). Translation in units of the face width, angles in
# radians, scale as log-scale, coefficients as a share of half their range.
TRANSLATION_STEPS = (0.02, 0.05, 0.10)
ANGLE_STEPS = (np.radians(3.0), np.radians(7.0), np.radians(15.0))
LOG_SCALE_STEPS = (0.03, 0.06, 0.10)
COEF_STEPS = (0.1, 0.25, 0.5)
SHAPE_STEPS = (0.25, 0.5, 1.0)  # shape units, in prior spreads


def perturbation_steps(sm: ShapeModel) -> np.ndarray:
    """(n_free, 6) float64 signed perturbations of each free parameter of the search vector [q, sigma]
    (``ShapeModel.person_view``)."""
    width = sm.frontal_width()
    rows = []
    free = sm.person_view()[1]
    for j in free:
        if j >= sm.n_q:
            sd = sm.shape_sd[j - sm.n_q]
            rows.append([m for t in SHAPE_STEPS for m in (t * sd, -t * sd)])
            continue
        if j <= 2:
            mags = ANGLE_STEPS
        elif j == 3:
            mags = LOG_SCALE_STEPS
        elif j <= 5:
            mags = tuple(width * t for t in TRANSLATION_STEPS)
        else:
            k = j - 6
            half = 0.5 * (sm.coef_hi[k] - sm.coef_lo[k])
            mags = tuple(half * t for t in COEF_STEPS)
        rows.append([m for mag in mags for m in (mag, -mag)])
    return np.array(rows, dtype=np.float64)


def update_matrix(G: np.ndarray, prior: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """From G (N, n_free) and the prior weights (n_free,) (0 for the pose), by one solve:
    U = -(G^T G + diag(prior))^-1 G^T (n_free, N) float32 and prior_step = (G^T G + diag(prior))^-1 diag(prior)
    (n_free, n_free) float64, so that delta = U e - prior_step p is the Gauss-Newton step of
    |e|^2 + sum prior p^2 (the paper's U = -(G^T G)^-1 G^T when the prior is 0)."""
    n = G.shape[1]
    prior = np.zeros(n) if prior is None else np.asarray(prior, float)
    GtG = G.T @ G
    ridge = 1e-6 * np.trace(GtG) / n
    sol = np.linalg.solve(GtG + np.diag(prior) + ridge * np.eye(n), np.hstack([G.T, np.diag(prior)]))
    return (-sol[:, : G.shape[0]]).astype(np.float32), np.ascontiguousarray(sol[:, G.shape[0]:])


def prior_weights(sm: ShapeModel, free: np.ndarray, n_pixels: int, strength: float) -> np.ndarray:
    """(n_free,) prior weights: ``strength * n_pixels / sd^2`` on each coefficient, 0 on the pose, so a
    coefficient one prior spread from 0 costs ``strength`` in mean squared residual (``ShapeModel.spreads``)."""
    free = np.asarray(free)
    return np.where(free < N_POSE, 0.0, strength * n_pixels / sm.spreads()[free] ** 2)
