"""Compiled area resampling: OpenCV's ``cv2.resize(..., interpolation=cv2.INTER_AREA)`` of a float32 image by a
factor in (0.5, 1), bit for bit, in about 40% of its time on the tracker's crops.

OpenCV (``resizeArea_``, ``computeResizeAreaTab`` in imgproc/src/resize.cpp) gives each destination pixel the
area-weighted mean of the source pixels its cell covers: per source row a horizontal pass
``buf[dx] = sum_k S[si_k] * alpha_k`` (float32, the cell's entries in source order, from 0), then per destination
row ``D = beta_0 * buf_0 (+ beta_1 * buf_1 ...)`` over the source rows the cell covers, in order. It computes the
horizontal pass once per (destination row, source row) pair, so most source rows twice; here once per source row
(the same values), with the at most three entries of a cell of width <= 2 padded to three (a 0 weight adds an
exact 0). The same float32 operations in the same order give the same bits (tested against cv2 in
tests/kernels/test_resample.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT


@numba.njit(**NJIT)
def _area_tab(ssize, dsize, scale, start, si, alpha):
    """OpenCV's ``computeResizeAreaTab`` for one axis: destination cell d takes the entries
    ``start[d]:start[d + 1]`` of (source index si, weight alpha float32). scale = source / destination size."""
    k = 0
    for d in range(dsize):
        start[d] = k
        f1 = d * scale
        f2 = f1 + scale
        cell = min(scale, ssize - f1)
        s1 = math.ceil(f1)
        s2 = min(math.floor(f2), ssize - 1)
        s1 = min(s1, s2)
        if s1 - f1 > 1e-3:
            si[k] = s1 - 1
            alpha[k] = np.float32((s1 - f1) / cell)
            k += 1
        for s in range(s1, s2):
            si[k] = s
            alpha[k] = np.float32(1.0 / cell)
            k += 1
        if f2 - s2 > 1e-3:
            si[k] = s2
            alpha[k] = np.float32(min(min(f2 - s2, 1.0), cell) / cell)
            k += 1
    start[dsize] = k


@numba.njit(**NJIT)
def _resize_area(src, scale, out):
    """out (h, w) float32 <- src (H, W) float32 resampled by area (see module docstring); scale = 1 / factor in
    [1, 2] (a cell covers at most three source pixels per axis), out's size as cv2.resize rounds it."""
    H, W = src.shape
    dh, dw = out.shape
    xs = np.empty(dw + 1, np.int64)
    xi = np.empty(2 * W + 2, np.int64)
    xa = np.empty(2 * W + 2, np.float32)
    ys = np.empty(dh + 1, np.int64)
    yi = np.empty(2 * H + 2, np.int64)
    ya = np.empty(2 * H + 2, np.float32)
    _area_tab(W, dw, scale, xs, xi, xa)
    _area_tab(H, dh, scale, ys, yi, ya)
    i0 = np.empty(dw, np.int64)
    i1 = np.empty(dw, np.int64)
    i2 = np.empty(dw, np.int64)
    a0 = np.zeros(dw, np.float32)
    a1 = np.zeros(dw, np.float32)
    a2 = np.zeros(dw, np.float32)
    for d in range(dw):
        s, n = xs[d], xs[d + 1] - xs[d]
        i0[d], a0[d] = xi[s], xa[s]
        i1[d] = i2[d] = xi[s]
        if n > 1:
            i1[d], a1[d] = xi[s + 1], xa[s + 1]
        if n > 2:
            i2[d], a2[d] = xi[s + 2], xa[s + 2]
    hor = np.empty((H, dw), np.float32)
    done = np.zeros(H, np.bool_)
    for j in range(ys[dh]):
        sy = yi[j]
        if not done[sy]:
            row = src[sy]
            h = hor[sy]
            for d in range(dw):
                h[d] = (row[i0[d]] * a0[d] + row[i1[d]] * a1[d]) + row[i2[d]] * a2[d]
            done[sy] = True
    for dy in range(dh):
        j0 = ys[dy]
        beta = ya[j0]
        h = hor[yi[j0]]
        for d in range(dw):
            out[dy, d] = beta * h[d]
        for j in range(j0 + 1, ys[dy + 1]):
            beta = ya[j]
            h = hor[yi[j]]
            for d in range(dw):
                out[dy, d] += beta * h[d]
