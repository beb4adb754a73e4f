"""A scan as a surface, for the key point sampler (:mod:`.sampler`): points with normals and point-to-plane
distances (:class:`_Surface`), moving points onto it along its normal -- onto a robust local quadric
(:func:`_fit_heights`) or onto the tangent planes of the nearest scan points (:func:`_project`) -- and the head's
rigid motion by robust point-to-plane ICP (:func:`_rigid_motion`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


class _Surface:
    """A scan as points with normals (PCA of 8 neighbours) for point-to-plane distances."""

    def __init__(self, points: np.ndarray):
        self.points = np.asarray(points, dtype=np.float64)
        self.tree = cKDTree(self.points)
        k = min(8, len(self.points))
        _, nb = self.tree.query(self.points, k=k)
        nb = nb.reshape(len(self.points), k)
        local = self.points[nb] - self.points[nb].mean(1, keepdims=True)
        _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
        self.normals = vecs[:, :, 0]
        self.spacing = max(float(np.median(np.linalg.norm(self.points[nb[:, min(1, k - 1)]] - self.points, axis=1))),
                           1e-12)  # median distance to the nearest other scan point

    def distance(self, query: np.ndarray, cap: float = np.inf) -> np.ndarray:
        """Point-to-plane distance to the nearest scan point, truncated at ``cap`` (also where no scan point is
        within ``cap``: parts of the template the scan does not cover count the same whatever their place)."""
        dist, j = self.tree.query(query, distance_upper_bound=cap)
        out = np.full(len(query), cap)
        ok = np.isfinite(dist)
        out[ok] = np.abs(((query[ok] - self.points[j[ok]]) * self.normals[j[ok]]).sum(1))
        return np.minimum(out, cap)


def _fit_heights(points: np.ndarray, surface: "_Surface", *, k: int = 16, n_robust: int = 3,
                 border: float = 0.5, tilt: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move points along the scan's normal onto a local quadric fit of the scan (moving least squares), and say how
    well the scan fixes that move.

    For each point x: its ``k`` nearest scan points, in a frame of the normal n of the nearest one (:class:`_Surface`),
    give heights ``h = (p - x) . n`` over the tangent coordinates (u, v); ``h ~ c0 + c1 u + c2 v + c3 u^2 + c4 uv +
    c5 v^2`` is fitted with Gaussian weights ``exp(-(|(u, v)| / s)^2)`` (s the median distance of the k) and
    ``n_robust`` rounds of Geman-McClure reweighting (scale 1.5 median absolute residuals; another layer of the scan
    near x, an ear's fold, gives way); x moves by ``c0 n``. A quadric averages the scan's noise over the ``k`` points
    and keeps the surface's bend, where one tangent plane per scan point (:func:`_project`) adds both.

    Returns (moved (n, 3), normals (n, 3), sigma (n,)): normals are n, or with ``tilt`` the quadric's own normal at
    x (from c1, c2; it fits the k points where the PCA normal of :class:`_Surface` fits 8); sigma is the standard error of c0
    (sandwich estimate from the weighted residuals; approximate: under the robust weights it falls short of the
    actual error, about 0.3x on Gaussian noise, so it serves as a relative measure -- the sampler's
    ``fit_max_sigma`` is set on that), +inf where x lies at the scan's border (the k neighbours' centroid lies off
    to one side along the surface by more than ``border`` times their mean distance, as in :func:`_project`: c0
    would be an extrapolation; on randomly sampled scans about 2% of the points inside are taken for border too)."""
    x = np.asarray(points, np.float64)
    if len(x) == 0:
        return x.copy(), np.zeros_like(x), np.zeros(0)
    k = min(k, len(surface.points))
    dist, j = surface.tree.query(x, k=k)
    dist, j = dist.reshape(len(x), k), j.reshape(len(x), k)
    n = surface.normals[j[:, 0]]
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(n, e1)
    rel = surface.points[j] - x[:, None]
    u, v, h = ((rel * e[:, None]).sum(2) for e in (e1, e2, n))
    r_uv = np.hypot(u, v)
    w0 = np.exp(-((r_uv / np.maximum(np.median(dist, axis=1), 1e-12)[:, None]) ** 2))
    design = np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], 2)
    w = w0
    scale = max(float(np.median(dist[:, 0])), 1e-12)
    for _ in range(n_robust + 1):
        ata = np.einsum("nki,nk,nkj->nij", design, w, design) + 1e-12 * scale ** 2 * np.eye(6)
        coef = np.linalg.solve(ata, np.einsum("nki,nk,nk->ni", design, w, h)[..., None])[..., 0]
        res = h - np.einsum("nki,ni->nk", design, coef)
        sig = np.maximum(1.5 * np.median(np.abs(res), axis=1, keepdims=True), 1e-6 * scale)
        w = w0 / (1.0 + (res / sig) ** 2) ** 2
    row0 = np.linalg.solve(ata, np.eye(6)[:, :1].repeat(len(x), 1).T[..., None])[..., 0]  # (A^T W A)^-1 e0
    gain = np.einsum("nki,ni->nk", design, row0) * w  # d c0 / d h_k
    sigma = np.sqrt((gain ** 2 * res ** 2).sum(1) * k / max(k - 6, 1))
    sigma[np.hypot(u.mean(1), v.mean(1)) > border * r_uv.mean(1)] = np.inf
    if tilt:  # the quadric's own normal at x: (-c1, -c2, 1) in the frame (e1, e2, n)
        fitted = n - coef[:, 1:2] * e1 - coef[:, 2:3] * e2
        return x + n * coef[:, :1], fitted / np.linalg.norm(fitted, axis=1)[:, None], sigma
    return x + n * coef[:, :1], n, sigma


def _project(points: np.ndarray, surface: "_Surface", cap: float, *, k: int = 8, n_iter: int = 3,
             border: float = 0.5) -> np.ndarray:
    """Move points along the scan's normal onto it: to the Gaussian-weighted mean of the tangent planes of their
    ``k`` nearest scan points (weights ``exp(-d^2 / s^2)``, s the distance to the nearest of them). Points stay
    where no scan point is within ``cap`` and at the scan's border (their neighbours' centroid lies off to one
    side along the surface by more than ``border`` times their mean distance: the tangent planes of a border
    are poor). Along the surface nothing moves. (Each tangent plane leaves about ``curvature * d^2 / 2`` of the
    surface's bend: approximate, a small part of a millimetre on a face scan.)"""
    x = np.array(points, np.float64)
    for _ in range(n_iter):
        dist, j = surface.tree.query(x, k=k, distance_upper_bound=cap)
        ok = np.isfinite(dist[:, 0])
        if not ok.any():
            break
        d, jj = dist[ok], j[ok]
        valid = np.isfinite(d)
        jj = np.where(valid, jj, jj[:, :1])
        n = surface.normals[jj]
        n = n * np.sign((n * n[:, :1]).sum(2))[:, :, None]  # one orientation per point
        w = np.where(valid, np.exp(-((d / np.maximum(d[:, :1], 1e-12 * cap)) ** 2)), 0.0)
        normal = (n * w[:, :, None]).sum(1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
        rel = surface.points[jj] - x[ok][:, None]
        centroid = (rel * valid[:, :, None]).sum(1) / valid.sum(1)[:, None]
        along = centroid - normal * (centroid * normal).sum(1)[:, None]
        spread = (np.linalg.norm(rel, axis=2) * valid).sum(1) / valid.sum(1)
        inside = np.linalg.norm(along, axis=1) <= border * spread
        offset = -(rel * n).sum(2)
        move = normal * ((w * offset).sum(1) / w.sum(1))[:, None]
        x[np.flatnonzero(ok)[inside]] -= move[inside]
    return x


def _rigid_fit(src: np.ndarray, dst: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares rotation R (3, 3) and shift t (3,) with ``dst ~ src @ R.T + t`` (Kabsch)."""
    w = weight / max(float(weight.sum()), 1e-300)
    mu_s, mu_d = w @ src, w @ dst
    u, _, vt = np.linalg.svd(((dst - mu_d) * w[:, None]).T @ (src - mu_s))
    d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    rot = u @ d @ vt
    return rot, mu_d - mu_s @ rot.T


def _rotation(omega: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector omega (3,) (Rodrigues)."""
    angle = float(np.linalg.norm(omega))
    if angle < 1e-12:
        return np.eye(3)
    k = omega / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * kx @ kx


def _rigid_motion(points, surface, landmarks, landmarks0, spacing, n_iter: int = 30):
    """The head's rigid motion F^0 -> scan: a function (n, 3) -> (n, 3).

    Starts from the landmarks' best rigid fit (biased by expressions: the landmarks move with the jaw and lips),
    then robust point-to-plane ICP of the (thinned) F^0 to the scan (:class:`_Surface`): points without scan within
    ``4 * spacing`` are left out, and residuals are weighted by Geman-McClure with a scale of 1.5 median absolute
    residuals, so that the parts of the face that move on their own (jaw, cheeks, lips) give way to the rigid
    rest (forehead, nose, temples)."""
    rot, shift = _rigid_fit(landmarks0, landmarks, np.ones(len(landmarks0)))
    points = np.asarray(points, np.float64)
    centre = points.mean(0)
    for _ in range(n_iter):
        x = points @ rot.T + shift
        dist, j = surface.tree.query(x, distance_upper_bound=4.0 * spacing)
        ok = np.isfinite(dist)
        if ok.sum() < 6:
            break
        xo, no = x[ok], surface.normals[j[ok]]
        r = ((xo - surface.points[j[ok]]) * no).sum(1)
        scale = max(1.5 * float(np.median(np.abs(r))), 1e-3 * spacing)
        w = 1.0 / (1.0 + (r / scale) ** 2) ** 2
        c = centre @ rot.T + shift
        jac = np.hstack([np.cross(xo - c, no), no])
        a = jac.T @ (jac * w[:, None]) + 1e-9 * np.eye(6)
        delta = np.linalg.solve(a, -jac.T @ (w * r))
        step = _rotation(delta[:3])
        rot = step @ rot
        shift = (shift - c) @ step.T + c + delta[3:]
        if np.linalg.norm(delta[:3]) * 10.0 * spacing + np.linalg.norm(delta[3:]) < 1e-4 * spacing:
            break
    return lambda p: p @ rot.T + shift
