"""The map between the 68 iBUG landmarks and a triangle mesh.

Every landmark becomes a fixed linear combination of the mesh vertices (barycentric weights on one triangle,
extrapolated where the landmark lies outside the mesh, as the jaw-line points do on Candide, whose outline is
narrower than the visible jaw), so the 3D model can be fitted to 68-point annotations and reports 68 points.

Where each landmark lies is found, not typed in: the mean 68-point shape of a training set is aligned to the
mesh's frontal view by a similarity fitted on the semantic anchors below (eye corners, mouth corners, nose tip,
chin: Candide vertices that are MPEG-4 feature points, see the Candide-3 report), then each landmark takes the
triangle under it. ``refine_landmark_map`` can then move each landmark by its mean fit residual.
"""

from __future__ import annotations

import numpy as np

from ..metrics import PIXEL_ORIGIN

# iBUG-68 index (0-based) -> Candide-3 vertex. Candide's +x is the subject's left, the image right.
CANDIDE_ANCHORS = {
    36: 53,  # outer corner of the image-left eye (MPEG-4 3.12)
    39: 56,  # inner corner of the image-left eye (3.8)
    42: 23,  # inner corner of the image-right eye (3.11)
    45: 20,  # outer corner of the image-right eye (3.7)
    30: 5,   # nose tip (9.3)
    48: 64,  # image-left mouth corner (8.4)
    54: 31,  # image-right mouth corner (8.3)
    8: 10,   # chin bottom (2.1)
}

# iBUG-68 left/right mirror: point i of a mirrored face is point IBUG_MIRROR[i] of the face, mirrored.
IBUG_MIRROR = np.array(list(range(16, -1, -1)) + list(range(26, 16, -1)) + [27, 28, 29, 30, 35, 34, 33, 32, 31]
                       + [45, 44, 43, 42, 47, 46, 39, 38, 37, 36, 41, 40]
                       + [54, 53, 52, 51, 50, 49, 48, 59, 58, 57, 56, 55] + [64, 63, 62, 61, 60, 67, 66, 65])


def mirror_points(points: np.ndarray, width: int, *, origin: float = PIXEL_ORIGIN) -> np.ndarray:
    """(..., 68, 2) landmarks of the horizontally mirrored image (``width`` pixels wide; ``origin`` the coordinate
    of the top-left pixel's centre: x -> width - 1 + 2 origin - x, so x -> width + 1 - x for the package's 1-based
    points, ``metrics.PIXEL_ORIGIN``, and width - 1 - x for OpenCV's, as training uses inside), and left and right
    points swap names."""
    out = np.asarray(points, float)[..., IBUG_MIRROR, :].copy()
    out[..., 0] = width - 1 + 2.0 * origin - out[..., 0]
    return out


def affine_points(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """(..., 2) points (the package's pixel convention, ``metrics.PIXEL_ORIGIN``) moved with an image that a 2x3
    affine ``matrix`` maps as ``cv2.warpAffine`` does (OpenCV's convention: pixel centres at integers)."""
    A = np.asarray(matrix, np.float64)
    return (np.asarray(points, np.float64) - PIXEL_ORIGIN) @ A[:, :2].T + A[:, 2] + PIXEL_ORIGIN


# Triangles of the eyeballs and pupils (Candide 3.1.4 added them last): they lie behind the eyelid surface
# and are used for landmarks only where nothing else is under a point.
N_CANDIDE_SKIN_TRIANGLES = 168


def similarity_fit(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity dst ~ s * src @ R + t for (n, 2) point sets (R a rotation, never a reflection);
    returns (s, R (2, 2), t (2,)). Closed form, a complex-number regression: s R = [[p, q], [-q, p]] with
    p = sum(a . b) / |a|^2 and q = sum(a x b) / |a|^2 for the centred sets a, b (the same as the SVD solution with
    its reflection guard, to 1e-13, and a few times faster: the landmark cascade's training calls it per start)."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    n2 = max(float((a * a).sum()), 1e-12)
    p = float((a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]).sum()) / n2
    q = float((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()) / n2
    s = float(np.hypot(p, q))
    R = np.array([[p, q], [-q, p]]) / s if s > 0 else np.eye(2)
    return s, R, md - s * ms @ R


def _barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of 2D points p (m, 2) in triangle (a, b, c); (m, 3)."""
    v0, v1, v2 = b - a, c - a, p - a
    den = v0[0] * v1[1] - v1[0] * v0[1]
    if abs(den) < 1e-15:
        return np.full((len(p), 3), np.nan)
    w1 = (v2[:, 0] * v1[1] - v1[0] * v2[:, 1]) / den
    w2 = (v0[0] * v2[:, 1] - v2[:, 0] * v0[1]) / den
    return np.stack([1.0 - w1 - w2, w1, w2], axis=1)


def barycentric_map(points: np.ndarray, verts2d: np.ndarray, triangles: np.ndarray,
                    *, n_preferred: int | None = None) -> np.ndarray:
    """Weights W (n_points, n_vertices) with W @ verts2d == points for points inside the mesh.

    A point inside several triangles takes the first among the first ``n_preferred`` triangles; a point
    outside every triangle takes the triangle whose barycentric coordinates are least negative
    (extrapolation from the nearest triangle).
    """
    n_pref = len(triangles) if n_preferred is None else n_preferred
    W = np.zeros((len(points), len(verts2d)))
    bary = np.stack([_barycentric(points, *verts2d[t]) for t in triangles], axis=1)  # (m, n_tri, 3)
    worst = np.nan_to_num(bary.min(axis=2), nan=-np.inf)
    for i in range(len(points)):
        inside = np.flatnonzero(worst[i] >= -1e-9)
        pref = inside[inside < n_pref]
        k = pref[0] if len(pref) else (inside[0] if len(inside) else int(np.argmax(worst[i])))
        W[i, triangles[k]] = bary[i, k]
    return W


def candide_landmark_map(vertices: np.ndarray, triangles: np.ndarray, mean68: np.ndarray) -> np.ndarray:
    """(68, n_vertices) weights placing the iBUG-68 landmarks on Candide.

    vertices : (n_vertices, 3) Candide neutral shape; mean68 : (68, 2) mean landmark shape in image axes
    (y down, any scale).
    """
    frontal = vertices[:, :2]
    src = np.column_stack([mean68[:, 0], -mean68[:, 1]])  # to y up
    idx = list(CANDIDE_ANCHORS)
    s, R, t = similarity_fit(src[idx], frontal[list(CANDIDE_ANCHORS.values())])
    placed = s * src @ R + t
    return barycentric_map(placed, frontal, triangles, n_preferred=N_CANDIDE_SKIN_TRIANGLES)


def refine_landmark_map(landmark_map: np.ndarray, vertices: np.ndarray, triangles: np.ndarray,
                        residuals_model: np.ndarray, *, n_preferred: int | None = None) -> np.ndarray:
    """Move each landmark by its mean fit residual and place it again.

    residuals_model : (n_images, 68, 2) annotated minus fitted landmark, in model units and model axes
    (x right, y up), i.e. image residuals with scale and roll undone.
    """
    placed = landmark_map @ vertices[:, :2] + np.nanmean(residuals_model, axis=0)
    return barycentric_map(placed, vertices[:, :2], triangles, n_preferred=n_preferred)
