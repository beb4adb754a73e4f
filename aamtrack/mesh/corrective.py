"""Corrective shape units for the 3D model: what Candide-3's shape units and barycentric landmark map cannot fit
of human-labelled 68-point shapes, learned from the training fits and added to the model.

The 68 landmarks become vertices of the model (appended after the mesh's own, in no triangle), so the model
reports them exactly instead of through barycentric extrapolation (the jaw line lies outside Candide's outline).
Each corrective unit is a principal component of the training fits' landmark residuals (model frame, scale and
roll undone; unit coefficient = one standard deviation), moving the landmark vertices by the component and the
mesh vertices by a Gaussian-weighted blend of the nearby landmarks' motion, so the texture map follows the
landmarks. Candide's own shape units and animation units carry over to the landmark vertices through the
landmark map, so the landmarks deform with the mesh exactly as before.
"""

from __future__ import annotations

import numpy as np

from .shape_model import ShapeModel

SPREAD = 0.08  # Gaussian width of the blend, in face widths
FLOOR = 1.5    # a vertex farther than about this many widths from every landmark barely moves


def blend_weights(vertices: np.ndarray, landmarks: np.ndarray, width: float) -> np.ndarray:
    """(n_vertices, 68) weights: w_vl = g(|v - l|) / (sum_l g(|v - l|) + g(FLOOR h)), g Gaussian of width
    h = SPREAD * width over the frontal (x, y) positions."""
    h = SPREAD * width
    d2 = ((vertices[:, None, :2] - landmarks[None, :, :2]) ** 2).sum(-1)
    g = np.exp(-d2 / (2 * h * h))
    return g / (g.sum(1, keepdims=True) + np.exp(-FLOOR ** 2 / 2))


def with_corrective_units(sm: ShapeModel, residuals: np.ndarray, n_units: int) -> ShapeModel:
    """The 3D model with landmark vertices and ``n_units`` corrective shape units learned from the training fits'
    landmark residuals (n, 68, 2) in model units and axes (``train.pipeline._model_residuals``)."""
    L = sm.landmark_map
    n_v = sm.n_vertices
    lm = L @ sm.mean
    R = residuals.reshape(len(residuals), -1)
    _, S, Vt = np.linalg.svd(R - R.mean(0), full_matrices=False)
    k = min(n_units, len(S))
    modes = (Vt[:k] * (S[:k, None] / np.sqrt(len(R)))).reshape(k, 68, 2)
    W = blend_weights(sm.mean, lm, sm.frontal_width())
    units = np.zeros((k, n_v + 68, 3))
    units[:, n_v:, :2] = modes
    units[:, :n_v, :2] = np.einsum("vl,kld->kvd", W, modes)

    def extend(arr):  # (k, n_v, 3) -> (k, n_v + 68, 3): the landmark vertices follow through the map
        return np.concatenate([arr, np.einsum("lv,kvd->kld", L, arr)], axis=1)

    landmark_map = np.zeros((68, n_v + 68))
    landmark_map[:, n_v:] = np.eye(68)
    return ShapeModel(
        kind=sm.kind, mean=np.vstack([sm.mean, lm]),
        shape_units=np.concatenate([extend(sm.shape_units), units]), basis=extend(sm.basis),
        triangles=sm.triangles, landmark_map=landmark_map,
        shape_names=tuple(sm.shape_names) + tuple(f"corrective_{i}" for i in range(k)),
        coef_names=sm.coef_names, coef_lo=sm.coef_lo, coef_hi=sm.coef_hi,
        shape_sd=np.r_[sm.shape_sd, np.ones(k)])
