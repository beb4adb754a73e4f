"""Gauss transform kernels for the L2 distance between Gaussian mixtures (Jian & Vemuri, PAMI 2011).

The Gauss transform of two point sets is ``S = sum_ij exp(-|x_i - y_j|^2 / h^2)``; the kernels also write its
gradient with respect to every ``x_i``. Memory is linear in the number of points: no pairwise matrix is formed.

Exact kernels (``*_direct``, O(n*m) time) and grid kernels (pairs farther than a cutoff radius are skipped, found
through a uniform grid over ``y`` whose occupied cells are kept as a sorted list of keys, so memory stays O(n + m)
however large the bounding box; where the grid has few cells, a table of each cell's first point replaces the
binary search). Besides the transform and its gradient, the kernels give per-point moments (weight and weighted
mean of the y near each x) for EM-like registration steps; the grid's transform and gradient are derived from its
moments in the wrapper (one grid traversal kernel). Public wrappers live in ``aamtrack.refine.gauss_grid``.
"""

from __future__ import annotations

import numba
import numpy as np

from ._flags import NJIT


@numba.njit(**NJIT)
def _gauss_transform_direct(x, y, inv_h2, grad):
    """Exact Gauss transform.

    x : (n, 3) float64, y : (m, 3) float64, inv_h2 : 1 / h^2.
    grad : (n, 3) float64, overwritten with d S / d x_i.  Returns S.
    """
    n = x.shape[0]
    m = y.shape[0]
    total = 0.0
    for i in range(n):
        gx = 0.0
        gy = 0.0
        gz = 0.0
        xi0 = x[i, 0]
        xi1 = x[i, 1]
        xi2 = x[i, 2]
        for j in range(m):
            d0 = xi0 - y[j, 0]
            d1 = xi1 - y[j, 1]
            d2 = xi2 - y[j, 2]
            w = np.exp(-(d0 * d0 + d1 * d1 + d2 * d2) * inv_h2)
            total += w
            gx += w * d0
            gy += w * d1
            gz += w * d2
        c = -2.0 * inv_h2
        grad[i, 0] = c * gx
        grad[i, 1] = c * gy
        grad[i, 2] = c * gz
    return total


@numba.njit(**NJIT)
def _grid_build(y, cell, origin, dims, order, keys):
    """Sort ``y`` into grid cells of side ``cell`` starting at ``origin``.

    dims : (3,) int64 cells per axis. Fills order : (m,) int64 (indices of y by cell) and keys : (m,) int64
    (sorted cell keys, ``(ix * dims[1] + iy) * dims[2] + iz``).
    """
    m = y.shape[0]
    raw = np.empty(m, dtype=np.int64)
    for j in range(m):
        ix = min(max(int(np.floor((y[j, 0] - origin[0]) / cell)), 0), dims[0] - 1)
        iy = min(max(int(np.floor((y[j, 1] - origin[1]) / cell)), 0), dims[1] - 1)
        iz = min(max(int(np.floor((y[j, 2] - origin[2]) / cell)), 0), dims[2] - 1)
        raw[j] = (ix * dims[1] + iy) * dims[2] + iz
    idx = np.argsort(raw, kind="mergesort")
    for j in range(m):
        order[j] = idx[j]
        keys[j] = raw[idx[j]]


@numba.njit(**NJIT)
def _lower_bound(keys, value):
    """First position in the sorted keys whose key is >= value (binary search)."""
    lo = 0
    hi = keys.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if keys[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(**NJIT)
def _grid_table(keys, table):
    """table : (n_cells + 1,) int64, overwritten with the first position of each cell key in the sorted keys (the
    last entry is len(keys)), so a cell's points are ``table[key]:table[key + 1]`` without a search."""
    j = 0
    for v in range(table.shape[0]):
        while j < keys.shape[0] and keys[j] < v:
            j += 1
        table[v] = j


@numba.njit(**NJIT)
def _first_at(keys, table, value):
    """First position of a key >= value: from the table when there is one (non-empty), else a binary search."""
    if table.shape[0] > 0:
        return table[value]
    return _lower_bound(keys, value)


@numba.njit(**NJIT)
def _gauss_moments_direct(x, y, inv_h2, weight, mean):
    """Exact zeroth and first moments of the Gaussian weights ``w_ij = exp(-|x_i - y_j|^2 / h^2)``.

    x : (n, 3) float64, y : (m, 3) float64. weight : (n,) float64, overwritten with ``sum_j w_ij``; mean : (n, 3)
    float64, overwritten with ``sum_j w_ij y_j / sum_j w_ij`` (x_i where the weight is 0). Returns S = sum weight.
    """
    n = x.shape[0]
    m = y.shape[0]
    total = 0.0
    for i in range(n):
        s = 0.0
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        for j in range(m):
            d0 = y[j, 0] - x[i, 0]
            d1 = y[j, 1] - x[i, 1]
            d2 = y[j, 2] - x[i, 2]
            w = np.exp(-(d0 * d0 + d1 * d1 + d2 * d2) * inv_h2)
            s += w
            g0 += w * d0
            g1 += w * d1
            g2 += w * d2
        weight[i] = s
        if s > 0.0:
            s_inv = 1.0 / s
        else:
            s_inv = 0.0
        mean[i, 0] = x[i, 0] + g0 * s_inv
        mean[i, 1] = x[i, 1] + g1 * s_inv
        mean[i, 2] = x[i, 2] + g2 * s_inv
        total += s
    return total


@numba.njit(**NJIT)
def _gauss_moments_grid(x, y_sorted, keys, table, cell, origin, dims, inv_h2, r2_max, weight, mean):
    """:func:`_gauss_moments_direct` over pairs closer than ``sqrt(r2_max)`` (at most ``cell``), found through the
    grid of ``_grid_build``. The weighted mean is taken relative to x_i (better rounding). Returns S."""
    n = x.shape[0]
    total = 0.0
    for i in range(n):
        xi0 = x[i, 0]
        xi1 = x[i, 1]
        xi2 = x[i, 2]
        cx = int(np.floor((xi0 - origin[0]) / cell))
        cy = int(np.floor((xi1 - origin[1]) / cell))
        cz = int(np.floor((xi2 - origin[2]) / cell))
        s = 0.0
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        z_lo = max(cz - 1, 0)
        z_hi = min(cz + 1, dims[2] - 1)
        if z_lo <= z_hi:
            for ix in range(max(cx - 1, 0), min(cx + 2, dims[0])):
                for iy in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                    base = (ix * dims[1] + iy) * dims[2]
                    start = _first_at(keys, table, base + z_lo)
                    stop = _first_at(keys, table, base + z_hi + 1)
                    for j in range(start, stop):
                        d0 = y_sorted[j, 0] - xi0
                        d1 = y_sorted[j, 1] - xi1
                        d2 = y_sorted[j, 2] - xi2
                        r2 = d0 * d0 + d1 * d1 + d2 * d2
                        if r2 < r2_max:
                            w = np.exp(-r2 * inv_h2)
                            s += w
                            g0 += w * d0
                            g1 += w * d1
                            g2 += w * d2
        weight[i] = s
        if s > 0.0:
            s_inv = 1.0 / s
        else:
            s_inv = 0.0
        mean[i, 0] = xi0 + g0 * s_inv
        mean[i, 1] = xi1 + g1 * s_inv
        mean[i, 2] = xi2 + g2 * s_inv
        total += s
    return total
