"""Gauss transforms of point sets through a uniform grid (public wrappers of :mod:`aamtrack._kernels.gauss`).

``S = sum_ij exp(-|x_i - y_j|^2 / h^2)``, its gradient with respect to every x_i, and the per-point moments (weight
``sum_j w_ij`` and weighted mean of the y_j) that the EM-like registration steps use. Pairs with
``exp(-r^2/h^2) < tol`` are skipped (a cutoff radius ``h sqrt(ln 1/tol)``): approximate to that tolerance per
pair; ``tol=None`` gives the exact O(n m) sums. Memory is O(n + m) (no pairwise matrix): the grid keeps its occupied
cells as a sorted list of keys (with a table of each cell's first point where the grid has few cells), and each
x visits the 27 cells around it.
"""

from __future__ import annotations

import numpy as np

from .._kernels.gauss import _gauss_moments_direct, _gauss_moments_grid
from .._kernels.gauss import _gauss_transform_direct, _grid_build, _grid_table

_MAX_CELLS_PER_AXIS = 1 << 20  # keys stay well inside int64
_TABLE_CELLS_PER_POINT = 16  # a cell table (O(cells) memory) only where it stays O(points)


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
        self.r2_max = float(cutoff * cutoff)
        self.cell = float(cutoff)
        lo = self.y.min(0)
        dims = np.floor((self.y.max(0) - lo) / self.cell).astype(np.int64) + 1
        if dims.max() > _MAX_CELLS_PER_AXIS:
            self.exact = True
            return
        self.origin, self.dims = lo, dims
        self.order = np.empty(len(self.y), dtype=np.int64)
        self.keys = np.empty(len(self.y), dtype=np.int64)
        _grid_build(self.y, self.cell, self.origin, self.dims, self.order, self.keys)
        n_cells = int(np.prod(dims))
        self.table = np.empty(n_cells + 1 if n_cells <= _TABLE_CELLS_PER_POINT * len(self.y) + 4096 else 0, np.int64)
        _grid_table(self.keys, self.table)
        self.y_sorted = np.ascontiguousarray(self.y[self.order])

    def transform(self, x: np.ndarray, grad: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """``(S, dS/dx)`` for x : (n, 3) float64 contiguous; grad : optional (n, 3) float64 output buffer."""
        if grad is None:
            grad = np.empty_like(x)
        if self.exact:
            return _gauss_transform_direct(x, self.y, self.inv_h2, grad), grad
        # from the moments: dS/dx_i = -2/h^2 sum_j w_ij (x_i - y_j) = -2/h^2 weight_i (x_i - mean_i)
        weight = np.empty(len(x))
        mean = np.empty_like(x)
        total = self.moments(x, weight, mean)
        np.multiply((-2.0 * self.inv_h2) * weight[:, None], x - mean, out=grad)
        return total, grad

    def moments(self, x: np.ndarray, weight: np.ndarray, mean: np.ndarray) -> float:
        """Fill weight : (n,) with ``sum_j w_ij`` and mean : (n, 3) with the w-weighted mean of y around each x_i
        (x_i where nothing is near); x : (n, 3) float64 contiguous. Returns S."""
        if self.exact:
            return _gauss_moments_direct(x, self.y, self.inv_h2, weight, mean)
        return _gauss_moments_grid(
            x, self.y_sorted, self.keys, self.table, self.cell, self.origin, self.dims, self.inv_h2, self.r2_max, weight, mean
        )


def gauss_transform(
    x: np.ndarray, y: np.ndarray, scale: float, *, tol: float | None = 1e-10
) -> tuple[float, np.ndarray]:
    """Gauss transform ``S = sum_ij exp(-|x_i - y_j|^2 / scale^2)`` and its gradient ``(n, 3)`` w.r.t. x.

    x : (n, 3), y : (m, 3) points. tol : skip pairs whose term is below tol (None: exact O(n m) sum).
    """
    x = _as_points(x, "x")
    return GaussGrid(y, scale, tol=tol).transform(x)


def gauss_moments(
    x: np.ndarray, y: np.ndarray, scale: float, *, tol: float | None = 1e-10
) -> tuple[np.ndarray, np.ndarray]:
    """Per-point weights ``sum_j w_ij`` (n,) and weighted means of y (n, 3), ``w_ij = exp(-|x_i - y_j|^2/scale^2)``."""
    x = _as_points(x, "x")
    weight, mean = np.empty(len(x)), np.empty((len(x), 3))
    GaussGrid(y, scale, tol=tol).moments(x, weight, mean)
    return weight, mean
