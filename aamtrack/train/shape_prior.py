"""Learning the shape prior (``aamtrack.mesh.shape_prior``): PCA of the labelled 68-point shapes, each taken into
the frame of their mean by the least-squares similarity."""

from __future__ import annotations

import numpy as np

from ..mesh.landmarks import similarity_fit
from ..mesh.shape_prior import ShapePrior
from .landmarks import levelled, reference_shape


def learn_shape_prior(points: np.ndarray, *, variance: float = 0.97, n_iter: int = 3) -> ShapePrior:
    """The shape prior of labelled points (n, 68, 2) (any pixels; the training images and their mirrors): the modes
    that explain ``variance`` of the aligned shapes' variance, each shape aligned to the mean as
    ``ShapePrior.score`` aligns one (the mean re-estimated ``n_iter`` times from
    ``train.landmarks.reference_shape``)."""
    pts = np.asarray(points, np.float64)
    if pts.ndim != 3 or pts.shape[1:] != (68, 2) or len(pts) < 2:
        raise ValueError(f"points of shape {pts.shape}: expected (n >= 2, 68, 2)")

    def aligned_to(mean):
        out = np.empty_like(pts)
        for i, p in enumerate(pts):
            s, R, t = similarity_fit(mean, p)
            out[i] = (p - t) @ R.T / s
        return out

    mean = reference_shape(pts)
    for _ in range(n_iter):
        mean = levelled(aligned_to(mean).mean(0))
    X = (aligned_to(mean) - mean).reshape(len(pts), -1)
    _, sv, Vt = np.linalg.svd(X, full_matrices=False)
    var = sv ** 2 / len(X)
    k = int(min(len(var) - 1, np.searchsorted(np.cumsum(var) / var.sum(), variance) + 1))
    rest = float(var[k:].sum()) / (X.shape[1] - k)
    return ShapePrior(mean=mean, modes=np.ascontiguousarray(Vt[:k]), variances=var[:k].copy(),
                      residual_variance=max(rest, 1e-12))


__all__ = ["learn_shape_prior"]
