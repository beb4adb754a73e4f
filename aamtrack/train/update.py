"""Update matrix learning (poster step 3): for one couple, the gradient G of the projected residual with respect
to each searched parameter, estimated on the training images by perturbing each parameter of the ground-truth
fit by known amounts (several magnitudes, both signs; slope by least squares through the origin), and
U = -(G^T G)^-1 G^T, computed with a solve (plus a ridge of 1e-6 of the mean diagonal, for conditioning)."""

from __future__ import annotations

import numpy as np

from ..mesh.shape_model import ShapeModel

# Perturbation magnitudes (one sign; both are used). Translation in units of the face width, angles in
# radians, scale as log-scale, coefficients as a share of half their range.
TRANSLATION_STEPS = (0.02, 0.05, 0.10)
ANGLE_STEPS = (np.radians(3.0), np.radians(7.0), np.radians(15.0))
LOG_SCALE_STEPS = (0.03, 0.06, 0.10)
COEF_STEPS = (0.1, 0.25, 0.5)


def perturbation_steps(sm: ShapeModel) -> np.ndarray:
    """(n_free, 6) float64 signed perturbations of each free parameter."""
    width = sm.frontal_width()
    rows = []
    for j in sm.free:
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


def update_matrix(G: np.ndarray) -> np.ndarray:
    """U = -(G^T G)^-1 G^T (n_free, N) float32 from G (N, n_free), by a solve."""
    GtG = G.T @ G
    ridge = 1e-6 * np.trace(GtG) / len(GtG)
    return (-np.linalg.solve(GtG + ridge * np.eye(len(GtG)), G.T)).astype(np.float32)
