"""The 2D model: generalised Procrustes alignment of 68-point shapes, PCA of the aligned shapes, and a
Delaunay triangulation of the mean. Pose is a similarity (roll, scale, translation)."""

from __future__ import annotations

import numpy as np

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


# The outline of the 68 points (jaw, then brows right to left) and how far the outer ring lies beyond it.
OUTLINE = tuple(range(17)) + tuple(range(26, 16, -1))
RING = 0.12


def ring_operator(n_points: int = 68, *, outline=OUTLINE, ring: float = RING) -> np.ndarray:
    """(n_points + len(outline), n_points) linear map from the 68 points to the points plus an outer ring:
    ring vertex i = outline point i pushed ``ring`` of its distance away from the centroid of all points.
    The ring puts the face's contour (jaw against neck or background) inside the texture map, so the
    search sees the edge from both sides; being linear in the points, it moves with shape and pose."""
    centroid = np.full(n_points, 1.0 / n_points)
    rows = [np.eye(n_points)]
    for i in outline:
        r = -ring * centroid
        r[i] += 1.0 + ring
        rows.append(r[None])
    return np.vstack(rows)


def pca_shape_model(points: np.ndarray, *, variance: float = 0.97, max_modes: int = 12,
                    ring: float = 0.0) -> ShapeModel:
    """2D ShapeModel from (n, 68, 2) annotated points (image axes, y down); vertices are the 68 points and
    an outer ring (``ring_operator``; ``ring=0`` for none)."""
    from scipy.spatial import Delaunay  # here, not at import: 'aamtrack run' starts faster without scipy.spatial

    up = np.stack([points[..., 0], -points[..., 1]], axis=-1)
    mean, aligned = procrustes_mean(up)
    X = (aligned - mean).reshape(len(aligned), -1)
    _, sv, Vt = np.linalg.svd(X, full_matrices=False)
    var = sv ** 2 / len(X)
    n_modes = int(min(max_modes, np.searchsorted(np.cumsum(var) / var.sum(), variance) + 1))
    sd = np.sqrt(var[:n_modes])
    R = ring_operator(ring=ring) if ring > 0 else np.eye(68)
    n_v = len(R)
    basis = np.zeros((n_modes, n_v, 3))
    modes = (Vt[:n_modes] * sd[:, None]).reshape(n_modes, 68, 2)  # unit coefficient = 1 sd
    basis[:, :, :2] = np.einsum("vl,kld->kvd", R, modes)
    mean3 = np.column_stack([R @ mean, np.zeros(n_v)])
    tri = Delaunay(mean3[:, :2]).simplices.astype(np.int32)
    return ShapeModel(
        kind="2d", mean=mean3, shape_units=np.zeros((0, n_v, 3)), basis=basis, triangles=tri,
        landmark_map=np.eye(68, n_v), shape_names=(), coef_names=tuple(f"pca_{i}" for i in range(n_modes)),
        coef_lo=np.full(n_modes, -3.0), coef_hi=np.full(n_modes, 3.0), shape_sd=np.zeros(0),
    )
