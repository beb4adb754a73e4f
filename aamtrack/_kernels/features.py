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
def _gradient_features(gray, soft, eps, out):
    """out (2, H, W) float32 <- edge-structure gradient of gray (H, W) float32 (H, W >= 2).

    g = 3x3 Sobel / 8 (one-sided at the border); out = g / (|g| + soft * mean|g| + eps).
    """
    H, W = gray.shape
    total = 0.0
    for y in range(H):
        ym = max(y - 1, 0)
        yp = min(y + 1, H - 1)
        dy_n = 1.0 / max(yp - ym, 1)
        for x in range(W):
            xm = max(x - 1, 0)
            xp = min(x + 1, W - 1)
            dx_n = 1.0 / max(xp - xm, 1)
            gx = (gray[ym, xp] - gray[ym, xm] + 2.0 * (gray[y, xp] - gray[y, xm]) + gray[yp, xp] - gray[yp, xm]) \
                * 0.25 * dx_n
            gy = (gray[yp, xm] - gray[ym, xm] + 2.0 * (gray[yp, x] - gray[ym, x]) + gray[yp, xp] - gray[ym, xp]) \
                * 0.25 * dy_n
            out[0, y, x] = gx
            out[1, y, x] = gy
            total += math.sqrt(gx * gx + gy * gy)
    damp = soft * total / (H * W) + eps
    for y in range(H):
        for x in range(W):
            gx = out[0, y, x]
            gy = out[1, y, x]
            inv = 1.0 / (math.sqrt(gx * gx + gy * gy) + damp)
            out[0, y, x] = gx * inv
            out[1, y, x] = gy * inv


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
