"""Compiled score of 68 points against a shape prior (``aamtrack.mesh.shape_prior``): the least-squares similarity of
the prior's mean onto the points (as ``mesh.landmarks.similarity_fit``), the points taken back into the mean's
frame, and their departure x from the mean weighed by the modes' variances and the residual's. The numpy version
took about 37 us a call, most of it per-call overhead on 68 points; every tracked frame asks for it.
"""

from __future__ import annotations

import math

import numba

from ._flags import NJIT


@numba.njit(**NJIT)
def _shape_score(pts, mean, modes, variances, residual_variance, x):
    """sqrt((sum_k b_k^2 / variances_k + |x - b modes|^2 / residual_variance) / (2 L)) with b = modes @ x, x (2 L,)
    scratch <- the points pts (L, 2) moved by the inverse of the similarity taking mean (L, 2) onto them, minus
    mean; modes (K, 2 L) orthonormal rows. inf for non-finite points or a degenerate similarity."""
    n = pts.shape[0]
    msx = 0.0
    msy = 0.0
    mdx = 0.0
    mdy = 0.0
    for i in range(n):
        if not (math.isfinite(pts[i, 0]) and math.isfinite(pts[i, 1])):
            return math.inf
        msx += mean[i, 0]
        msy += mean[i, 1]
        mdx += pts[i, 0]
        mdy += pts[i, 1]
    msx /= n
    msy /= n
    mdx /= n
    mdy /= n
    n2 = 0.0
    p = 0.0
    q = 0.0
    for i in range(n):
        ax = mean[i, 0] - msx
        ay = mean[i, 1] - msy
        bx = pts[i, 0] - mdx
        by = pts[i, 1] - mdy
        n2 += ax * ax + ay * ay
        p += ax * bx + ay * by
        q += ax * by - ay * bx
    if n2 < 1e-12:
        n2 = 1e-12
    p /= n2
    q /= n2
    s2 = p * p + q * q  # (s R = [[p, q], [-q, p]]; its inverse on row vectors: v @ [[p, -q], [q, p]] / s^2)
    if not s2 > 1e-18:
        return math.inf
    xx = 0.0
    for i in range(n):
        bx = pts[i, 0] - mdx
        by = pts[i, 1] - mdy
        u = (bx * p + by * q) / s2 - (mean[i, 0] - msx)
        v = (-bx * q + by * p) / s2 - (mean[i, 1] - msy)
        x[2 * i] = u
        x[2 * i + 1] = v
        xx += u * u + v * v
    d2 = 0.0
    bb = 0.0
    for k in range(modes.shape[0]):
        b = 0.0
        for j in range(2 * n):
            b += modes[k, j] * x[j]
        bb += b * b
        d2 += b * b / variances[k]
    rr = xx - bb
    if rr < 0.0:
        rr = 0.0
    d2 += rr / residual_variance
    return math.sqrt(d2 / (2 * n))

