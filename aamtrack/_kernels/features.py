"""Compiled feature images: what the texture map samples instead of (or beside) grey levels.

Image gradient orientations (IGO, Tzimiropoulos et al. 2012) in their "edge structure" form (Antonakos et al.,
IEEE TIP 2015): the Sobel gradient g of the grey image, divided by |g| + soft * mean|g| + eps, so strong edges
give unit vectors, weak gradients shrink towards 0 (a flat or uniform image gives all zeros rather than random
orientations), and any affine change of the grey levels leaves the features unchanged. Two channels, gx and gy,
in image axes (x right, y down); the residual kernel turns them into the face's own axes.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT


@numba.njit(**NJIT)
def _gradient_row(r0, r1, r2, dy_n, gx_out, gy_out, mag):
    """One row of the gradient from the rows above (r0), at (r1) and below (r2): Sobel / 8, one-sided at the left
    and right ends; ``dy_n`` = 1/4 of the inverse row span (1/8 inside, 1/4 on the first and last row). The inner
    loop has no branch and no reduction, so it vectorises (float32, as the outputs)."""
    W = r1.shape[0]
    two = np.float32(2.0)
    eighth = np.float32(0.125)
    for x in range(1, W - 1):
        gx = ((r0[x + 1] - r0[x - 1]) + two * (r1[x + 1] - r1[x - 1]) + (r2[x + 1] - r2[x - 1])) * eighth
        gy = ((r2[x - 1] - r0[x - 1]) + two * (r2[x] - r0[x]) + (r2[x + 1] - r0[x + 1])) * dy_n
        gx_out[x] = gx
        gy_out[x] = gy
        mag[x] = math.sqrt(gx * gx + gy * gy)
    for x in (0, W - 1):
        xm = max(x - 1, 0)
        xp = min(x + 1, W - 1)
        dx_n = np.float32(0.25 / max(xp - xm, 1))
        gx = ((r0[xp] - r0[xm]) + two * (r1[xp] - r1[xm]) + (r2[xp] - r2[xm])) * dx_n
        gy = ((r2[xm] - r0[xm]) + two * (r2[x] - r0[x]) + (r2[xp] - r0[xp])) * dy_n
        gx_out[x] = gx
        gy_out[x] = gy
        mag[x] = math.sqrt(gx * gx + gy * gy)


@numba.njit(**NJIT)
def _gradient_features(gray, soft, eps, out):
    """out (2, H, W) float32 <- edge-structure gradient of gray (H, W) float32 (H, W >= 2).

    g = 3x3 Sobel / 8 (one-sided at the border); out = g / (|g| + soft * mean|g| + eps). Three passes, each a
    loop that vectorises: the gradient and its magnitude row by row (``_gradient_row``), the mean magnitude over
    eight running sums (one sum is a chain of dependent adds), and the division. 5.8x faster than one branchy
    float64 loop on a 257 x 220 level (316 -> 55 us, AMD EPYC), to float32 rounding (<= 1.2e-7).
    """
    H, W = gray.shape
    mag = np.empty((H, W), np.float32)
    for y in range(H):
        ym = max(y - 1, 0)
        yp = min(y + 1, H - 1)
        _gradient_row(gray[ym], gray[y], gray[yp], np.float32(0.25 / max(yp - ym, 1)), out[0, y], out[1, y],
                      mag[y])
    acc = np.zeros(8)
    n8 = W - W % 8
    for y in range(H):
        m = mag[y]
        for x in range(0, n8, 8):
            for j in range(8):
                acc[j] += m[x + j]
        for x in range(n8, W):
            acc[0] += m[x]
    damp = np.float32(soft * acc.sum() / (H * W) + eps)
    one = np.float32(1.0)
    for y in range(H):
        m = mag[y]
        gx = out[0, y]
        gy = out[1, y]
        for x in range(W):
            inv = one / (m[x] + damp)
            gx[x] *= inv
            gy[x] *= inv


def gradient_features(gray: np.ndarray, *, soft: float = 1.0, eps: float = 1.0) -> np.ndarray:
    """(2, H, W) float32 edge-structure gradient features of a grey image (H, W) (see module docstring).

    soft: weight of the image's mean gradient magnitude in the damping (0 = pure orientations);
    eps: grey levels added to the damping (flat regions tend to 0 instead of noise orientations).
    """
    gray = np.ascontiguousarray(gray, dtype=np.float32)
    if gray.ndim != 2 or min(gray.shape) < 2:
        raise ValueError(f"gradient_features needs a (H, W) image with H, W >= 2, got shape {gray.shape}")
    out = np.empty((2,) + gray.shape, np.float32)
    _gradient_features(gray, float(soft), float(eps), out)
    return out
