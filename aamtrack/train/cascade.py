"""Learned update cascade (supervised descent on the AAM residual).

Per couple, a short sequence of linear updates delta = R_s e + b_s, each learned by ridge regression of the true
correction (the delta that takes the current parameters to the ground-truth fit, in the face-frame composition of
``aamtrack._kernels.warp._compose``) on the projected residual e over many perturbed starts of the training fits;
stage s + 1 is learned on the starts as stage s left them, and each couple starts where the coarser one left off
(Cootes et al. 2001 learned U by regression; Xiong & De la Torre 2013, supervised descent; Tzimiropoulos 2015,
project-out cascaded regression). The search keeps the poster's shape, warp -> residual -> delta = R e.

Perturbed starts mix two kinds: detection-like (the offsets between the training fits and the rough pose the
Haar box gives, measured on the training images themselves, so the cascade learns the capture range detection
needs) and tracking-like (small offsets from the truth, as between consecutive frames).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..kernels import compose, residual_batch
from .workers import for_each

log = logging.getLogger(__name__)


def inverse_compose(q: np.ndarray, q_target: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(M, n_free) deltas that ``_compose`` (step 1, no bounds) turns q (M, n) into q_target (M, n) on the free
    indices: angles and coefficients subtract, the scale is a log ratio, and the translation is expressed in
    model units along the start's rolled axes (the inverse of the 2x2 map in ``_compose``, which is its own
    inverse up to the scale)."""
    q = np.atleast_2d(q)
    q_target = np.atleast_2d(q_target)
    out = np.empty((len(q), len(free)))
    c, s, sc = np.cos(q[:, 2]), np.sin(q[:, 2]), q[:, 3]
    du_img = q_target[:, 4] - q[:, 4]
    dv_img = q_target[:, 5] - q[:, 5]
    for a, j in enumerate(free):
        if j == 3:
            out[:, a] = np.log(q_target[:, 3] / q[:, 3])
        elif j == 4:
            out[:, a] = (c * du_img - s * dv_img) / sc
        elif j == 5:
            out[:, a] = (-s * du_img - c * dv_img) / sc
        else:
            out[:, a] = q_target[:, j] - q[:, j]
    return out


def compose_all(q: np.ndarray, free: np.ndarray, delta: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(M, n) each row of q composed with its delta (M, n_free) by the kernel's own ``_compose``."""
    out = np.empty_like(q)
    for i in range(len(q)):
        compose(q[i], free, delta[i], 1.0, lo, hi, out[i])
    return out


@dataclass(frozen=True)
class StartSpread:
    """Tracking-like perturbations (standard deviations): translation in face widths, log-scale, angles in
    radians, coefficients in prior spreads (``spread`` per coefficient, given by the caller)."""

    translation: float = 0.04
    log_scale: float = 0.04
    angle: float = np.radians(4.0)
    coef: float = 0.3


def perturbed_starts(q_true: np.ndarray, free: np.ndarray, detection_deltas: np.ndarray, coef_spread: np.ndarray,
                     width: float, lo: np.ndarray, hi: np.ndarray, *, n_per: int, rng: np.random.Generator,
                     detection_share: float = 0.6, spread: StartSpread = StartSpread()) -> tuple[np.ndarray, np.ndarray]:
    """Starts for the cascade: ``n_per`` per training fit (rows of q_true (n, n_q)). Returns (starts (n * n_per,
    n_q), index of the fit each start belongs to).

    detection_deltas (k, n_free): offsets (as ``inverse_compose(q_true, q_detected)``) measured from Haar boxes;
    a detection-like start applies one of them, drawn at random, times a factor in [0.75, 1.25] for variety.
    coef_spread (n_q,): the prior spread of each coefficient (ignored for the pose).
    """
    n = len(q_true)
    idx = np.repeat(np.arange(n), n_per)
    M = len(idx)
    deltas = np.zeros((M, len(free)))
    det = rng.random(M) < detection_share if len(detection_deltas) else np.zeros(M, bool)
    if det.any():
        pick = rng.integers(0, len(detection_deltas), det.sum())
        deltas[det] = detection_deltas[pick] * rng.uniform(0.75, 1.25, (det.sum(), 1))
    trk = ~det
    for a, j in enumerate(free):
        if j <= 2:
            sd = spread.angle
        elif j == 3:
            sd = spread.log_scale
        elif j <= 5:
            sd = spread.translation * width
        else:
            sd = spread.coef * coef_spread[j]
        deltas[trk, a] = rng.normal(0.0, sd, trk.sum())
    return compose_all(q_true[idx], free, deltas, lo, hi), idx


_CROSS_ROWS = 4096  # rows per float32 product of X^T Y (float64 throughout took five times as long: a float64
# copy of X, /tmp 2026-12-01)


def ridge_fit(X: np.ndarray, Y: np.ndarray, *, alphas=(0.03, 0.3, 3.0, 30.0, 300.0), holdout: float = 0.15,
              groups: np.ndarray | None = None, rng: np.random.Generator | None = None) -> tuple[np.ndarray,
                                                                                                   np.ndarray, float]:
    """Ridge regression Y ~ X R^T + b, the ridge alpha * trace(Xc^T Xc) / D chosen among ``alphas`` on a held-out
    share of the groups (training images: starts of one image never straddle the split), then refitted on all.
    X (M, D), Y (M, k). One Gram matrix per split and a Cholesky solve per alpha tried: the alphas from the
    smallest up, stopping where the held-out error rises: the grid's best wherever the error falls then rises
    along it (in the helen_train trainings of 2026-12-01 every fit chose the alpha the whole grid chose; a solve
    of the finest couple's 3,860-wide system takes 0.7 s on one core). Returns (R (k, D) float32, b (k,) float64,
    chosen alpha)."""
    from scipy.linalg import cho_factor, cho_solve

    rng = rng or np.random.default_rng(0)
    groups = np.arange(len(X)) if groups is None else groups
    ug = np.unique(groups)
    held = np.isin(groups, rng.choice(ug, max(1, int(holdout * len(ug))), replace=False))
    Xf = np.asarray(X, np.float32)
    Y = np.asarray(Y, np.float64)

    def moments(mask):
        Xm, Ym = Xf[mask], Y[mask]
        XtY = np.zeros((X.shape[1], Y.shape[1]))
        for s in range(0, len(Xm), _CROSS_ROWS):  # float32 products of a few thousand rows, summed in float64
            XtY += Xm[s:s + _CROSS_ROWS].T @ Ym[s:s + _CROSS_ROWS].astype(np.float32)
        return (Xm.T @ Xm).astype(np.float64), Xm.sum(0, dtype=np.float64), XtY, Ym.sum(0), int(mask.sum())

    def solve(mom, alpha):
        A, sx, B, sy, n = mom
        xm, ym = sx / n, sy / n
        Ac = A - n * np.outer(xm, xm)
        Bc = B - n * np.outer(xm, ym)
        lam = alpha * np.trace(Ac) / len(Ac)
        R = cho_solve(cho_factor(Ac + lam * np.eye(len(Ac)), check_finite=False), Bc, check_finite=False)
        return R.T, ym - xm @ R

    if len(X) < X.shape[1]:  # fewer rows than columns: the dual is the smaller system
        def fit_train(alpha):
            return _ridge_dual(Xf, Y, ~held, alpha)

        def fit_all(alpha):
            return _ridge_dual(Xf, Y, np.ones(len(X), bool), alpha)
    else:
        m_tr, m_he = moments(~held), moments(held)

        def fit_train(alpha):
            return solve(m_tr, alpha)

        def fit_all(alpha):
            return solve(tuple(a + b for a, b in zip(m_tr, m_he, strict=True)), alpha)
    sd = Y.std(0) + 1e-12  # error per output scaled by its spread, so every parameter counts
    best, least = None, np.inf
    for alpha in sorted(alphas):
        R, b = fit_train(alpha)
        err = float((((Xf[held] @ R.T + b - Y[held]) / sd) ** 2).mean())
        if err >= least:  # past the minimum
            break
        best, least = alpha, err
    R, b = fit_all(best)
    return R.astype(np.float32), b, best


def _ridge_dual(X: np.ndarray, Y: np.ndarray, mask: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """(R, b) of ``ridge_fit``'s regression on the rows ``mask``, in the dual (for M < D): R = Xc^T (Xc Xc^T +
    lambda I)^-1 Yc, lambda = alpha * trace(Xc Xc^T) / D as in the primal."""
    from scipy.linalg import cho_factor, cho_solve

    Xm = X[mask].astype(np.float64)
    xm, ym = Xm.mean(0), Y[mask].mean(0)
    Xc = Xm - xm
    K = Xc @ Xc.T
    lam = alpha * np.trace(K) / X.shape[1]
    A = cho_solve(cho_factor(K + lam * np.eye(len(K)), check_finite=False), Y[mask] - ym, check_finite=False)
    R = (Xc.T @ A).T
    return R, ym - xm @ R.T


def rows_by_owner(owner: np.ndarray, n: int) -> list[np.ndarray]:
    """Each of n images' rows (ascending) of owner (M,) int, the image each row belongs to: work per image, each
    image's rows its own (threads may fill them, ``train.workers``)."""
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.arange(n + 1))
    return [order[bounds[i]:bounds[i + 1]] for i in range(n)]


def residual_matrix(images, factors, shifts, starts: np.ndarray, owner: np.ndarray, shape3d: np.ndarray,
                    basis: np.ndarray, mean: np.ndarray, app: np.ndarray, pix_vid: np.ndarray,
                    pix_bary: np.ndarray, mode: int, workers: int = 1) -> np.ndarray:
    """(M, D) float32 projected residuals of every start (rows of ``starts``) on its own image: ``images[i]`` a
    feature image (C, h, w) resampled by ``factors[i]``, frame pixel x at ``factors[i] * x + shifts[i]``
    (``aamtrack.imaging.level_shift``); the images' rows on up to ``workers`` threads (``train.workers``)."""
    E = np.empty((len(starts), len(mean)), np.float32)
    rows_of = rows_by_owner(owner, len(images))

    def fill(i):  # image i's rows of E, its own
        rows = rows_of[i]
        if len(rows):
            E[rows] = residual_batch(images[i], factors[i], shifts[i], shape3d, basis, starts[rows], mean, app,
                                     pix_vid, pix_bary, mode, np.empty((len(rows), len(mean)), np.float32))

    for_each(fill, range(len(images)), workers)
    return E
