"""Gauss transform kernels for the L2 distance between Gaussian mixtures (Jian & Vemuri, PAMI 2011).

The Gauss transform of two point sets is ``S = sum_ij exp(-|x_i - y_j|^2 / h^2)``; the kernels also write its
gradient with respect to every ``x_i``. Memory is linear in the number of points: no pairwise matrix is formed.

Two kernels: ``_gauss_transform_direct`` (exact, O(n*m) time) and ``_gauss_transform_grid`` (pairs farther than a
cutoff radius are skipped, found through a uniform grid over ``y`` whose occupied cells are kept as a sorted list of
keys, so memory stays O(n + m) however large the bounding box). Public wrappers live in ``aamtrack.refine.gmm``.
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
def _gauss_transform_grid(x, y_sorted, keys, cell, origin, dims, inv_h2, r2_max, grad):
    """Gauss transform over pairs closer than ``sqrt(r2_max)`` (the cutoff must not exceed ``cell``).

    y_sorted : (m, 3) float64, y ordered as ``keys`` (see ``_grid_build``). grad : (n, 3) float64, overwritten with
    d S / d x_i. Returns S.
    """
    n = x.shape[0]
    total = 0.0
    c = -2.0 * inv_h2
    for i in range(n):
        xi0 = x[i, 0]
        xi1 = x[i, 1]
        xi2 = x[i, 2]
        cx = int(np.floor((xi0 - origin[0]) / cell))
        cy = int(np.floor((xi1 - origin[1]) / cell))
        cz = int(np.floor((xi2 - origin[2]) / cell))
        gx = 0.0
        gy = 0.0
        gz = 0.0
        z_lo = max(cz - 1, 0)
        z_hi = min(cz + 1, dims[2] - 1)
        if z_lo <= z_hi:
            for ix in range(max(cx - 1, 0), min(cx + 2, dims[0])):
                for iy in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                    base = (ix * dims[1] + iy) * dims[2]
                    # cells (ix, iy, z_lo..z_hi) have consecutive keys: one contiguous run of y_sorted
                    start = _lower_bound(keys, base + z_lo)
                    stop = _lower_bound(keys, base + z_hi + 1)
                    for j in range(start, stop):
                        d0 = xi0 - y_sorted[j, 0]
                        d1 = xi1 - y_sorted[j, 1]
                        d2 = xi2 - y_sorted[j, 2]
                        r2 = d0 * d0 + d1 * d1 + d2 * d2
                        if r2 < r2_max:
                            w = np.exp(-r2 * inv_h2)
                            total += w
                            gx += w * d0
                            gy += w * d1
                            gz += w * d2
        grad[i, 0] = c * gx
        grad[i, 1] = c * gy
        grad[i, 2] = c * gz
    return total
