"""The 2D model: generalised Procrustes alignment of 68-point shapes, PCA of the aligned shapes, and a
Delaunay triangulation of the mean. Pose is a similarity (roll, scale, translation)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from ..mesh.landmarks import similarity_fit
from ..mesh.shape_model import ShapeModel


def procrustes_mean(shapes: np.ndarray, *, n_iter: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Generalised Procrustes analysis of (n, 68, 2) shapes (any axes). Returns (mean (68, 2) centred with
    unit frontal width, aligned (n, 68, 2))."""
    ref = shapes[0] - shapes[0].mean(0)
    for _ in range(n_iter):
        aligned = np.empty_like(shapes)
        for i, s in enumerate(shapes):
            sc, R, t = similarity_fit(s, ref)
            aligned[i] = sc * s @ R + t
        new = aligned.mean(0)
        new -= new.mean(0)
        new /= np.ptp(new[:, 0])
        if np.abs(new - ref).max() < 1e-7:
            ref = new
            break
        ref = new
    return ref, aligned


def pca_shape_model(points: np.ndarray, *, variance: float = 0.97, max_modes: int = 12) -> ShapeModel:
    """2D ShapeModel from (n, 68, 2) annotated points (image axes, y down)."""
    up = np.stack([points[..., 0], -points[..., 1]], axis=-1)
    mean, aligned = procrustes_mean(up)
    X = (aligned - mean).reshape(len(aligned), -1)
    _, sv, Vt = np.linalg.svd(X, full_matrices=False)
    var = sv ** 2 / len(X)
    n_modes = int(min(max_modes, np.searchsorted(np.cumsum(var) / var.sum(), variance) + 1))
    sd = np.sqrt(var[:n_modes])
    basis = np.zeros((n_modes, 68, 3))
    basis[:, :, :2] = (Vt[:n_modes] * sd[:, None]).reshape(n_modes, 68, 2)  # unit coefficient = 1 sd
    mean3 = np.column_stack([mean, np.zeros(68)])
    tri = Delaunay(mean).simplices.astype(np.int32)
    return ShapeModel(
        kind="2d", mean=mean3, shape_units=np.zeros((0, 68, 3)), basis=basis, triangles=tri,
        landmark_map=np.eye(68), shape_names=(), coef_names=tuple(f"pca_{i}" for i in range(n_modes)),
        coef_lo=np.full(n_modes, -3.0), coef_hi=np.full(n_modes, 3.0), shape_sd=np.zeros(0),
    )
