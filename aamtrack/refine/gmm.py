"""Non-rigid point set registration by the L2 distance between Gaussian mixtures (Jian & Vemuri, PAMI 2011).

Each point set is a mixture of equal isotropic Gaussians. The moving set is ``X = L @ Y``: a linear function of
the positions ``Y`` of control points (here the key points of an RBF deformation, :mod:`aamtrack.refine.rbf`), and

    E(Y) = S(X, X) / m^2 - 2 S(X, Z) / (m n)    with   S(A, B) = sum_ij exp(-|a_i - b_j|^2 / h^2)

(normalised by ``S(Z, Z) / n^2``: :func:`l2_cost`) is what the registration lowers, coarse to fine in ``h``. It
does so not with a general-purpose optimiser but with a few EM-like steps (see :func:`register`): each moves every
point by the difference of the Gaussian-weighted means of scene and moving set around it (the gradient of E per
point divided by the local weight) and fits the controls to that by least squares, plus
``anchor * mean |Y - Y_prior|^2``, which keeps the controls near a prior where the surface alone cannot place them
(sliding along a flat patch). With ``pull="normal"`` (the default) only the component of each point's step along
its surface normal is kept, and the controls are fitted to those steps: where the skin slid along the surface is
left to the prior. ``pull="plane"`` is point-to-plane proper (with a little point-to-point, ``tangential``): the
controls, free in 3D, are fitted to the steps' normal parts only, so that where a region's normals differ (its
curvature) they fix its motion along the surface too; ``"mixed"`` keeps ``tangential`` of the step's part along
the surface; ``"isotropic"`` keeps all of it (point-to-point).
Approximations, all for speed: the Gauss transforms skip pairs beyond 3 h (terms
``< exp(-9)``); the moving set's own mean is evaluated once per scale; at most ``max_points`` moving points (a random
subset) steer the steps at each scale, and coarse scales thin both sets. Memory is O(n + m) throughout.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg
from scipy.spatial import cKDTree

from .gauss_grid import GaussGrid, _as_points, gauss_moments, gauss_transform

log = logging.getLogger(__name__)

PULLS = ("normal", "mixed", "plane", "isotropic")

__all__ = ["GaussGrid", "GmmConfig", "GmmResult", "gauss_moments", "gauss_transform", "l2_cost", "register",
           "smooth_basis", "surface_normals", "thin", "warmup"]


@dataclass(frozen=True)
class GmmConfig:
    """Options of :func:`register`.

    scales : kernel widths h, coarse to fine, in units of ``spacing``. anchor : weight of the pull of the free
    controls back to their start (``mean |Y - Y0|^2`` against the mean squared step of the moving points).
    max_iter : iterations per scale; step_tol : stop a scale when the moving points move by less than
    ``step_tol * h`` (root mean square) in an iteration. max_points : the steps are computed on at most this many
    moving points per scale, a random subset (None: all); the result moves every point. tol : Gauss transform truncation: pairs with ``exp(-r^2/h^2) < tol`` are
    skipped (the default, ``exp(-9)``, is a cutoff at 3 h: approximate; None: exact O(n m) sums).
    density : at a coarse scale both sets are thinned at random to about ``density`` points per h (so a point
    meets a bounded number of others); seed : of that thinning. pull : one name, or one per scale:
    ``"normal"`` moves each point only along its surface normal (where the skin slides along the surface is left
    to the anchor's prior), ``"plane"`` point-to-plane with the controls free in 3D plus ``tangential`` of
    point-to-point (the three axes coupled: 3 d unknowns per call, meant for scales with a small basis),
    ``"mixed"`` the normal step plus ``tangential`` times its part along the surface, ``"isotropic"`` by the whole
    difference of the means (point-to-point). tangential : see pull. anchor_tangential : with the normal pull,
    the anchor holds the controls only along the surface, not along their normals.
    """

    scales: tuple = (2.0, 1.0)
    anchor: float = 0.05
    max_iter: int = 5
    step_tol: float = 0.02
    max_points: int | None = 3000
    tol: float | None = float(np.exp(-9.0))
    density: float = 1.5
    seed: int = 0
    pull: str | tuple = "normal"
    tangential: float = 0.1
    anchor_tangential: bool = False

    def pull_at(self, level: int) -> str:
        """The pull of scale ``level`` (``pull`` is one name, or one per scale)."""
        pull = self.pull if isinstance(self.pull, str) else self.pull[level]
        if pull not in PULLS:
            raise ValueError(f"unknown pull {pull!r}; expected one of {PULLS}")
        return pull


@dataclass(frozen=True)
class GmmResult:
    """controls : (k, 3) float64 fitted control positions; moved : (m, 3) float64 ``L @ controls``;
    cost : mean squared length of the last step field ``m_Z - m_X`` (see :func:`register`), in squared units of the
    points: about 0 at a fit (:func:`l2_cost` gives Jian & Vemuri's normalised cost); n_evals : iterations."""

    controls: np.ndarray
    moved: np.ndarray
    cost: float
    n_evals: int


def register(
    operator: np.ndarray,
    controls0: np.ndarray,
    scene: np.ndarray,
    *,
    spacing: float,
    free: np.ndarray | None = None,
    config: GmmConfig = GmmConfig(),
    bases: Sequence | None = None,
    anchor_to: np.ndarray | None = None,
    cache: dict | None = None,
) -> GmmResult:
    """Move the control points so that ``operator @ controls`` matches the scene (Jian & Vemuri's L2 cost).

    operator : (m, k) float64 -- moving points as a linear function of the k control positions.
    controls0 : (k, 3) float64 initial control positions (also the anchor unless ``anchor_to`` is given).
    scene : (n, 3) float64 points to register to (a crop of the surface the moving points cover).
    spacing : typical distance between neighbouring points (the unit of ``config.scales``).
    free : (k,) bool -- which controls move (default all); the others stay fixed.
    bases : optional, one per scale: None or a (n_free, d) float64 matrix B; at that scale the free controls move
    only by ``B @ theta`` (a smooth field of d coarse nodes: see :func:`smooth_basis`), so that the registration
    sees whole regions with their curvature features rather than patches that could slide.
    anchor_to : optional (k, 3) float64 positions the free controls are pulled to (the prior where the surface
    cannot place them, e.g. sliding along it); default controls0.
    cache : optional dict, filled on the first call and reused by later calls with the same operator, free, bases
    and config (e.g. every frame of a sequence): the moving points that steer each scale and the factored normal
    equations, which depend on nothing else.

    Each iteration is an EM-like (mean-shift) step of the L2 cost: every moving point x_i is sent by
    ``m_Z(x_i) - m_X(x_i)``, the difference of the Gaussian-weighted means of the scene and of the moving set (itself
    left out) around it -- the gradient of the L2 cost divided by the local weight, so that shape bias cancels --
    and the controls take the least-squares step (with the anchor) that best produces it. The normal equations
    depend only on the operator, so they are factored once per scale.
    """
    operator = np.ascontiguousarray(operator, dtype=np.float64)
    y = _as_points(controls0, "controls0").copy()
    scene = _as_points(scene, "scene")
    free = np.ones(len(y), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    if operator.shape[1] != len(y) or free.shape != (len(y),):
        raise ValueError(f"operator {operator.shape}, controls {y.shape} and free {free.shape} do not match")
    if bases is not None and len(bases) != len(config.scales):
        raise ValueError(f"{len(bases)} bases for {len(config.scales)} scales")
    m, n = operator.shape[0], len(scene)
    n_free = int(free.sum())
    if n_free == 0 or m == 0 or n == 0:
        return GmmResult(y, operator @ y, float("nan"), 0)
    rng = np.random.default_rng(config.seed)
    y0_free = (y if anchor_to is None else _as_points(anchor_to, "anchor_to"))[free].copy()
    if y0_free.shape != (n_free, 3):
        raise ValueError("anchor_to must be (k, 3) like controls0")
    n_evals = 0
    for level, rel in enumerate(config.scales):
        h = float(rel) * spacing
        # thin at coarse scales, keeping enough points to pin the free controls (8 per degree of freedom)
        basis = None if bases is None else bases[level]
        dof = n_free if basis is None else basis.shape[1]
        keep = min(1.0, max((config.density / float(rel)) ** 2, 8.0 * dof / m))
        z = scene[np.sort(rng.choice(n, max(1, int(round(keep * n))), replace=False))] if keep < 1 else scene
        if cache is not None and level in cache:
            rows, system = cache[level]
        else:
            if config.max_points is not None:
                keep = min(keep, max(config.max_points, 8 * dof) / m)
            rows = rng.choice(m, max(1, int(round(keep * m))), replace=False) if keep < 1 else np.arange(m)
            rows = rows[_spatial_order(operator[rows] @ y, 3.0 * h)]  # neighbours in turn: kinder to the cache
            system = _normal_equations(operator[rows], free, basis, config)
            if cache is not None:
                cache[level] = (rows, system)
        n_iter, residual = _iterate(y, free, z, h, y0_free, basis, config, system, config.pull_at(level))
        n_evals += n_iter
        log.debug("gmm: h=%.4g, %d iterations, residual %.4g", h, n_iter, residual)
    return GmmResult(y, operator @ y, residual, n_evals)


def _normal_equations(operator, free, basis, config) -> tuple:
    """(l_fixed, l_free, l_basis, factor) of one scale: the steering rows' operator on the fixed and on the free
    controls, on the basis coefficients, and the Cholesky factor of the least-squares step's normal equations
    (with the anchor)."""
    m, n_free = len(operator), int(free.sum())
    l_fixed = np.ascontiguousarray(operator[:, ~free])
    l_free = np.ascontiguousarray(operator[:, free])
    l_basis = l_free if basis is None else l_free @ basis
    eye = np.eye(n_free) if basis is None else basis.T @ basis
    normal = l_basis.T @ l_basis / m + (config.anchor / n_free) * eye
    factor = scipy.linalg.cho_factor(normal + 1e-12 * np.trace(normal) * np.eye(len(normal)))
    return l_fixed, l_free, l_basis, factor


def _plane_equations(l_basis, normals, basis, w_anchor, mu) -> tuple:
    """Cholesky factor of the coupled normal equations of the point-to-plane step (see :func:`_iterate`) and the
    per-point weights W_i = mu I + (1 - mu) n_i n_i^T : (m, 3, 3)."""
    m, d = l_basis.shape
    w = mu * np.eye(3) + (1.0 - mu) * normals[:, :, None] * normals[:, None, :]
    eye = np.eye(d) if basis is None else basis.T @ basis
    big = np.empty((3 * d, 3 * d))
    for a in range(3):
        for b in range(a, 3):
            block = (l_basis * (w[:, a, b] / m)[:, None]).T @ l_basis
            if a == b:
                block = block + w_anchor * eye
            big[a * d:(a + 1) * d, b * d:(b + 1) * d] = block
            big[b * d:(b + 1) * d, a * d:(a + 1) * d] = block.T
    factor = scipy.linalg.cho_factor(big + 1e-12 * np.trace(big) * np.eye(3 * d))
    return factor, w


def _iterate(y, free, scene, h, y0_free, basis, config, system, pull) -> tuple[int, float]:
    """One scale of :func:`register` (system: of :func:`_normal_equations`); updates ``y[free]`` in place, returns
    (iterations, last mean squared step).

    pull "plane": the controls' step theta minimises ``sum_i (u_i - s_i)^T W_i (u_i - s_i) / m + anchor`` with u_i
    the step of moving point i, s_i its mean-shift step and ``W_i = mu I + (1 - mu) n_i n_i^T`` (mu =
    ``config.tangential``): point-to-plane plus a little point-to-point. Unlike "normal" (which fits the controls
    to steps projected on the normals, i.e. asks for no motion along the surface), the motion along the surface is
    left to the other points: where the normals of a region differ (its curvature) they fix its motion in 3D.
    The three axes are coupled, so the normal equations (3 d unknowns) are built per call: meant for the scales
    with a small basis."""
    l_fixed, l_free, l_basis, factor = system
    m, n_free = len(l_free), int(free.sum())
    x_fixed = l_fixed @ y[~free]
    w_anchor = config.anchor / n_free
    yf = y[free]
    x = np.ascontiguousarray(x_fixed + l_free @ yf)
    # m_X(x_i) - x_i, the mean of the moving set around x_i (x_i left out: it has weight exactly 1), is a property
    # of the local shape; it is evaluated once per scale and held fixed while the set deforms a little (approximate)
    bias, normals = _shape(x, h, config, pull)
    # with the normal pull the anchor holds the controls only along the surface (their normal place is the scan's):
    # its target is the prior slid along each control's normal (that of the nearest moving point) to the control
    key_normals = normals[cKDTree(x).query(yf)[1]] if normals is not None and config.anchor_tangential else None
    w_point = None
    if pull == "plane":
        factor, w_point = _plane_equations(l_basis, normals, basis, w_anchor, config.tangential)
        normals = None
    scene_grid = GaussGrid(scene, h, tol=config.tol)
    w_z, mean_z = np.empty(m), np.empty((m, 3))
    n_iter, residual = 0, float("nan")
    for n_iter in range(1, config.max_iter + 1):
        scene_grid.moments(x, w_z, mean_z)
        # points with little scene around them (holes, occlusions) pull less
        conf = w_z / (w_z + 0.1 * max(float(np.median(w_z)), 1e-12))
        step = (mean_z - x - bias) * conf[:, None]
        if normals is not None:  # point-to-plane: only the component along the normal (held for the scale)
            along_normal = normals * (step * normals).sum(1)[:, None]
            step = along_normal if pull == "normal" else along_normal + config.tangential * (step - along_normal)
        if w_point is not None:
            step = np.einsum("nij,nj->ni", w_point, step)
        residual = float((step * step).sum(1).mean())
        off = yf - y0_free
        if key_normals is not None:
            off = off - key_normals * (off * key_normals).sum(1)[:, None]
        rhs = l_basis.T @ step / m - w_anchor * (off if basis is None else basis.T @ off)
        if w_point is None:
            theta = scipy.linalg.cho_solve(factor, rhs)
        else:  # the three axes' unknowns stacked axis by axis
            d = rhs.shape[0]
            theta = scipy.linalg.cho_solve(factor, rhs.T.reshape(-1)).reshape(3, d).T
        delta = theta if basis is None else basis @ theta
        yf = yf + delta
        moved = l_free @ delta
        x = np.ascontiguousarray(x + moved)
        rms = float(np.sqrt((moved * moved).sum(1).mean()))
        log.debug("gmm: h=%.4g iteration %d: residual %.4g, rms step %.4g", h, n_iter, residual, rms)
        if rms < config.step_tol * h:
            break
    y[free] = yf
    return n_iter, residual


def _shape(x: np.ndarray, h: float, config: GmmConfig, pull: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(bias (m, 3), normals (m, 3) or None) of the moving set x at scale h: ``m_X(x_i) - x_i``, the mean of the
    moving set around each point with the point itself left out (it has weight exactly 1), which the scene's mean
    shows too where the two sets coincide (a property of the local shape, subtracted from the step), and the
    surface normals for the normal pull."""
    m = len(x)
    w_x, mean_x = np.empty(m), np.empty((m, 3))
    GaussGrid(x, h, tol=config.tol).moments(x, w_x, mean_x)
    w_self = np.maximum(w_x - 1.0, 0.0)
    bias = np.where(w_self[:, None] > 1e-9, w_x[:, None] * (mean_x - x) / np.maximum(w_self, 1e-9)[:, None], 0.0)
    return bias, (surface_normals(x, h) if pull != "isotropic" else None)


def l2_cost(x: np.ndarray, scene: np.ndarray, scale: float, *, tol: float | None = None) -> float:
    """Normalised L2 distance ``(S(X,X)/m^2 - 2 S(X,Z)/(m n)) / (S(Z,Z)/n^2)`` (-1 when X = Z, Jian & Vemuri)."""
    x, scene = _as_points(x, "x"), _as_points(scene, "scene")
    m, n = len(x), len(scene)
    s_zz = GaussGrid(scene, scale, tol=tol).transform(scene)[0] / (n * n)
    s_xx = GaussGrid(x, scale, tol=tol).transform(x)[0] / (m * m)
    s_xz = GaussGrid(scene, scale, tol=tol).transform(x)[0] / (m * n)
    return float((s_xx - 2.0 * s_xz) / s_zz)


def smooth_basis(rest: np.ndarray, free: np.ndarray, n_nodes: int, rng: np.random.Generator) -> np.ndarray | None:
    """(n_free, d) matrix B: a smooth displacement field of the free controls, zero at the fixed ones.

    rest : (k, 3) control positions in the rest shape; free : (k,) bool. n_nodes : free controls, spread by
    farthest point sampling from a random start (rng), that carry the field: B is the thin-plate RBF interpolation
    (:mod:`.rbf`) of the values (0 at the fixed controls, theta at the nodes), d = n_nodes (applied per axis).
    None when n_nodes covers every free control.
    """
    from .rbf import rbf_system

    rest = np.asarray(rest, np.float64)
    free = np.asarray(free, bool)
    idx_free = np.flatnonzero(free)
    if n_nodes >= len(idx_free):
        return None
    nodes = _farthest_points(rest[idx_free], n_nodes, rng)
    centres = np.concatenate([rest[~free], rest[idx_free[nodes]]])
    op = rbf_system(centres).operator(rest[idx_free])
    return np.ascontiguousarray(op[:, int((~free).sum()):])


def surface_normals(points: np.ndarray, radius: float, *, k: int = 10) -> np.ndarray:
    """(n, 3) float64 unit normals of a sampled surface: the least-variance direction of each point's ``k`` nearest
    neighbours (PCA), those farther than ``2 * radius`` left out (sign arbitrary: the steps use ``n n^T``)."""
    points = np.asarray(points, np.float64)
    k = min(k, len(points))
    dist, nb = cKDTree(points).query(points, k=k)
    dist, nb = dist.reshape(len(points), k), nb.reshape(len(points), k)
    w = (dist < 2.0 * radius).astype(np.float64)
    w[:, 0] = 1.0
    nbp = points[nb]
    mu = (nbp * w[:, :, None]).sum(1) / w.sum(1)[:, None]
    local = (nbp - mu[:, None]) * np.sqrt(w)[:, :, None]
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    return np.ascontiguousarray(vecs[:, :, 0])


def _spatial_order(points: np.ndarray, cell: float) -> np.ndarray:
    """Permutation that visits the points cell by cell (cubes of side ``cell``)."""
    k = np.floor((points - points.min(0)) / cell).astype(np.int64)
    return np.lexsort((k[:, 2], k[:, 1], k[:, 0]))


def _farthest_points(points: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    chosen = [int(rng.integers(len(points)))]
    dist = np.linalg.norm(points - points[chosen[0]], axis=1)
    for _ in range(1, k):
        chosen.append(int(np.argmax(dist)))
        dist = np.minimum(dist, np.linalg.norm(points - points[chosen[-1]], axis=1))
    return np.array(chosen)


def thin(points: np.ndarray, cell: float, rng: np.random.Generator) -> np.ndarray:
    """Indices (sorted) of at most one point per cube of side ``cell``, chosen at random: an even subsample."""
    points = np.asarray(points, dtype=np.float64)
    order = rng.permutation(len(points))
    keys = np.floor(points[order] / cell).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return np.sort(order[first])


def warmup() -> None:
    """Compile the Gauss transform kernels on tiny inputs (numba caches them on disk)."""
    pts = np.random.default_rng(0).standard_normal((8, 3))
    gauss_transform(pts, pts, 1.0, tol=None)
    gauss_transform(pts, pts, 1.0, tol=1e-6)
    gauss_moments(pts, pts, 1.0, tol=None)
    gauss_moments(pts, pts, 1.0, tol=1e-6)
    op = np.abs(np.random.default_rng(1).standard_normal((8, 5)))
    register(op / op.sum(1, keepdims=True), pts[:5], pts, spacing=1.0)
