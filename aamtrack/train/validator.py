"""The fit validator: a logistic regression on a few statistics of a finished fit (``aamtrack.search.STAT_NAMES``)
that says how likely the fit sits on a face, learned at training time from

- positives: the training fits the cascade brought close to the labels (NME below ``good_nme``);
- negatives: fits the cascade left far off (NME above ``bad_nme``), fits displaced from the truth by a third to
  two thirds of the face width, rescaled or turned, and fits on non-face images (black, grey, uniform colour,
  noise, blurred noise, smooth ramps).

Its output is the confidence reported per frame, and the tracker's loss test.
"""

from __future__ import annotations

import numpy as np

from ..model import Validator


def logistic_fit(X: np.ndarray, y: np.ndarray, names: tuple, *, l2: float = 1e-3, n_iter: int = 50) -> Validator:
    """Logistic regression by Newton's method (IRLS) on standardised features X (n, k), labels y (n,) in {0, 1},
    classes weighted to count equally; a small L2 penalty on the weights (not the bias)."""
    mean = X.mean(0)
    scale = X.std(0) + 1e-9
    Z = np.column_stack([(X - mean) / scale, np.ones(len(X))])
    w = np.zeros(Z.shape[1])
    cw = np.where(y > 0.5, 0.5 / max(y.mean(), 1e-9), 0.5 / max(1 - y.mean(), 1e-9))
    reg = np.r_[np.full(Z.shape[1] - 1, l2 * len(X)), 0.0]
    for _ in range(n_iter):
        p = 1.0 / (1.0 + np.exp(-np.clip(Z @ w, -50, 50)))
        g = Z.T @ (cw * (p - y)) + reg * w
        H = (Z * (cw * p * (1 - p))[:, None]).T @ Z + np.diag(reg + 1e-9)
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return Validator(tuple(names), w[:-1], mean, scale, float(w[-1]))


def non_face_images(shape: tuple, rng: np.random.Generator) -> list[np.ndarray]:
    """Grey (H, W) float32 images with no face: black, mid grey, a random uniform level, uniform noise, blurred
    noise, and a smooth ramp."""
    import cv2

    H, W = shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = rng.uniform(0, 2 * np.pi)
    return [np.zeros(shape, np.float32), np.full(shape, 128, np.float32),
            np.full(shape, rng.uniform(0, 255), np.float32),
            rng.uniform(0, 255, shape).astype(np.float32),
            cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), rng.uniform(2, 8)),
            (128 + 100 * np.sin(ang) * (xx / W - 0.5) + 100 * np.cos(ang) * (yy / H - 0.5)).astype(np.float32)]
