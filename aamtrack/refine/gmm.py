"""Non-rigid point set registration by the L2 distance between Gaussian mixtures (Jian & Vemuri, PAMI 2011).

Each point set is a mixture of equal isotropic Gaussians. The moving set is ``X = L @ Y``: a linear function of
the positions ``Y`` of control points (here the key points of an RBF deformation, :mod:`aamtrack.refine.rbf`), and

    E(Y) = S(X, X) / m^2 - 2 S(X, Z) / (m n)    with   S(A, B) = sum_ij exp(-|a_i - b_j|^2 / h^2)

(normalised by ``S(Z, Z) / n^2``) is minimised over the free control points with L-BFGS, coarse to fine in ``h``,
plus ``anchor * mean |Y - Y0|^2 / h^2`` which keeps key points near their prediction where the surface alone cannot
place them (sliding along a flat patch). Gauss transforms use a grid and skip pairs with ``exp(...) < tol`` (default
1e-10): approximate to that tolerance per pair, O(n + m) memory.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from .._kernels.gauss import _gauss_transform_direct, _gauss_transform_grid, _grid_build

log = logging.getLogger(__name__)

_MAX_CELLS_PER_AXIS = 1 << 20  # keys stay well inside int64


def _as_points(a: np.ndarray, name: str) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must be (n, 3), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} has non-finite values")
    return a


class GaussGrid:
    """The points ``y`` sorted into a grid for repeated Gauss transforms at one scale.

    y : (m, 3) points; scale : kernel width h; tol : pairs with ``exp(-r^2/h^2) < tol`` are skipped (None: exact).
    """

    def __init__(self, y: np.ndarray, scale: float, *, tol: float | None = 1e-10):
        self.y = _as_points(y, "y")
        if not scale > 0:
            raise ValueError(f"scale must be > 0, got {scale}")
        self.inv_h2 = 1.0 / (scale * scale)
        self.exact = tol is None or len(self.y) == 0
        if self.exact:
            return
        cutoff = scale * np.sqrt(np.log(1.0 / tol))
        lo = self.y.min(0)
        dims = np.floor((self.y.max(0) - lo) / cutoff).astype(np.int64) + 1
        if dims.max() > _MAX_CELLS_PER_AXIS:
            self.exact = True
            return
        self.cell, self.r2_max, self.origin, self.dims = float(cutoff), float(cutoff * cutoff), lo, dims
        self.order = np.empty(len(self.y), dtype=np.int64)
        self.keys = np.empty(len(self.y), dtype=np.int64)
        _grid_build(self.y, self.cell, self.origin, self.dims, self.order, self.keys)
        self.y_sorted = np.ascontiguousarray(self.y[self.order])

    def transform(self, x: np.ndarray, grad: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """``(S, dS/dx)`` for x : (n, 3) float64 contiguous; grad : optional (n, 3) float64 output buffer."""
        if grad is None:
            grad = np.empty_like(x)
        if self.exact:
            return _gauss_transform_direct(x, self.y, self.inv_h2, grad), grad
        total = _gauss_transform_grid(
            x, self.y_sorted, self.keys, self.cell, self.origin, self.dims, self.inv_h2, self.r2_max, grad
        )
        return total, grad


def gauss_transform(
    x: np.ndarray, y: np.ndarray, scale: float, *, tol: float | None = 1e-10
) -> tuple[float, np.ndarray]:
    """Gauss transform ``S = sum_ij exp(-|x_i - y_j|^2 / scale^2)`` and its gradient ``(n, 3)`` w.r.t. x.

    x : (n, 3), y : (m, 3) points. tol : skip pairs whose term is below tol (None: exact O(n m) sum).
    """
    x = _as_points(x, "x")
    return GaussGrid(y, scale, tol=tol).transform(x)


@dataclass(frozen=True)
class GmmConfig:
    """Options of :func:`register`.

    scales : kernel widths h, coarse to fine, in units of ``spacing``. anchor : weight of ``mean |Y - Y0|^2 / h^2``.
    max_iter : L-BFGS iterations per scale. tol : Gauss transform truncation (None: exact).
    density : at a coarse scale both sets are thinned at random to about ``density`` points per h (so a point
    meets a bounded number of others); seed : of that thinning.
    """

    scales: tuple = (2.0, 1.0)
    anchor: float = 0.2
    max_iter: int = 30
    tol: float | None = 1e-6
    density: float = 1.5
    seed: int = 0


@dataclass(frozen=True)
class GmmResult:
    """controls : (k, 3) float64 fitted control positions; moved : (m, 3) float64 ``L @ controls``;
    cost : final normalised L2 cost (about -1 at a perfect fit); n_evals : cost evaluations."""

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
) -> GmmResult:
    """Move the control points so that ``operator @ controls`` matches the scene (Jian & Vemuri's L2 cost).

    operator : (m, k) float64 -- moving points as a linear function of the k control positions.
    controls0 : (k, 3) float64 initial control positions (also the anchor).
    scene : (n, 3) float64 points to register to (a crop of the surface the moving points cover).
    spacing : typical distance between neighbouring points (the unit of ``config.scales``).
    free : (k,) bool -- which controls move (default all); the others stay fixed.
    """
    operator = np.ascontiguousarray(operator, dtype=np.float64)
    y = _as_points(controls0, "controls0").copy()
    scene = _as_points(scene, "scene")
    free = np.ones(len(y), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    if operator.shape[1] != len(y) or free.shape != (len(y),):
        raise ValueError(f"operator {operator.shape}, controls {y.shape} and free {free.shape} do not match")
    m, n = operator.shape[0], len(scene)
    l_free = np.ascontiguousarray(operator[:, free])
    n_free = int(free.sum())
    if n_free == 0 or m == 0 or n == 0:
        x = operator @ y
        return GmmResult(y, x, float("nan"), 0)
    rng = np.random.default_rng(config.seed)
    y0_free = y[free].copy()
    n_evals = 0
    cost = float("nan")
    for rel in config.scales:
        h = float(rel) * spacing
        # thin at coarse scales, keeping enough points to pin the free controls (8 per control)
        keep = min(1.0, max((config.density / float(rel)) ** 2, 8.0 * n_free / m))
        rows = np.sort(rng.choice(m, max(1, int(round(keep * m))), replace=False)) if keep < 1 else slice(None)
        z = scene[np.sort(rng.choice(n, max(1, int(round(keep * n))), replace=False))] if keep < 1 else scene
        cost, evals = _minimise(operator[rows], y, free, z, h, y0_free, config)
        n_evals += evals
        log.debug("gmm: h=%.4g cost=%.6f", h, cost)
    return GmmResult(y, operator @ y, cost, n_evals)


def _minimise(operator, y, free, scene, h, y0_free, config):
    """One scale of :func:`register`; updates ``y[free]`` in place, returns (cost, n_evals)."""
    m, n, n_free = len(operator), len(scene), int(free.sum())
    l_free = np.ascontiguousarray(operator[:, free])
    x_fixed = operator[:, ~free] @ y[~free]
    scene_grid = GaussGrid(scene, h, tol=config.tol)
    s_zz = scene_grid.transform(scene)[0] / (n * n)
    grad_self = np.empty((m, 3))
    grad_cross = np.empty((m, 3))
    w_anchor = config.anchor / (n_free * h * h)
    n_evals = 0

    def fun(theta: np.ndarray) -> tuple[float, np.ndarray]:
        nonlocal n_evals
        n_evals += 1
        yf = theta.reshape(n_free, 3)
        x = np.ascontiguousarray(x_fixed + l_free @ yf)
        s_xx, _ = GaussGrid(x, h, tol=config.tol).transform(x, grad_self)
        s_xz, _ = scene_grid.transform(x, grad_cross)
        e = (s_xx / (m * m) - 2.0 * s_xz / (m * n)) / s_zz
        dx = (2.0 * grad_self / (m * m) - 2.0 * grad_cross / (m * n)) / s_zz
        d = yf - y0_free
        e += w_anchor * float((d * d).sum())
        g = l_free.T @ dx + 2.0 * w_anchor * d
        return e, g.ravel()

    res = scipy.optimize.minimize(
        fun, y[free].ravel(), jac=True, method="L-BFGS-B", options={"maxiter": config.max_iter, "gtol": 1e-12}
    )
    y[free] = res.x.reshape(n_free, 3)
    return float(res.fun), n_evals


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
