"""Learning the landmark cascade (``aamtrack.landmark_cascade``): supervised descent from where the AAM search
leaves the points to the labels.

Starts: for each training image, one of the search's own fits of it (the caller's: from its Haar box), and
``n_starts`` made ones: the label plus an error drawn from the AAM's fits of other images
(expressed in the face frame, scaled by a factor in ``error_scale``), turned, scaled and shifted a little. The
made starts have the shape of the errors the search really makes, in the numbers a regression needs. Each stage
is a ridge regression of the remaining displacement (face frame) on the descriptors (``cascade.ridge_fit``, its
strength chosen on held-out images), applied to the starts before the next stage is learned. The last
``shape_stages`` stages also regress on the points' own shape (``landmark_cascade.shape_features``, weighted by
``shape_weight`` against the descriptors in the ridge): measured on the 3D model's captured helen_train/helen_test
fits (/tmp harness, 2026-11-26, halves 0.35..0.1), helen_test mean NME 0.0371 -> 0.0359 / 0.0357 / 0.0362 /
0.0366 with the last stage reading it at weight 1 / 3 / 10 / 30 (jaw 0.0652 -> 0.0622 at 3, every region lower);
the last two stages at 1: 0.0370, all four: 0.0365 -- read early, the shape takes over what the descriptors
should correct, and the later stages have nothing left to learn on the training starts.
"""

from __future__ import annotations

import logging
from functools import partial

import numpy as np

from ..landmark_cascade import DescriptorSpec, LandmarkCascade, project_descriptors, similarity_to, training_rows
from ..metrics import IBUG_LEFT_EYE_OUTER, IBUG_RIGHT_EYE_OUTER, nme
from .cascade import ridge_fit, rows_by_owner
from .shape2d import procrustes_mean
from .workers import for_each

log = logging.getLogger(__name__)

DEFAULT_SPEC = DescriptorSpec()
MAX_LIBRARY_NME = 0.15  # AAM fits worse than this are failures, not errors to learn to correct


def levelled(shape: np.ndarray) -> np.ndarray:
    """(68, 2) shape centred, turned level and scaled so the outer eye corners are 1 apart."""
    ref = shape - shape.mean(0)
    d = ref[IBUG_LEFT_EYE_OUTER] - ref[IBUG_RIGHT_EYE_OUTER]
    a = np.arctan2(d[1], d[0])
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])  # row vectors: turns d onto +x
    return ref @ rot / np.hypot(*d)


def reference_shape(points: np.ndarray) -> np.ndarray:
    """(68, 2) Procrustes mean of points (n, 68, 2) (``shape2d.procrustes_mean``), ``levelled``."""
    return levelled(procrustes_mean(np.asarray(points, float))[0])


def made_starts(truth: np.ndarray, ref: np.ndarray, library: np.ndarray, n_per: int, rng: np.random.Generator,
                error_scale: tuple = (0.5, 1.5), angle: float = np.radians(4.0), log_scale: float = 0.04,
                shift: float = 0.04) -> np.ndarray:
    """(n, n_per, 68, 2) starts around the labels truth (n, 68, 2): each plus a library error (k, 68, 2) (face
    frame) times a factor in ``error_scale``, turned (sd ``angle`` radians) and scaled (sd ``log_scale``) about
    its centre and shifted (sd ``shift``, eye distances)."""
    out = np.empty((len(truth), n_per, 68, 2))
    for i, P in enumerate(truth):
        M, c = similarity_to(ref, P)
        Minv = np.linalg.inv(M)
        Pn = (P - c) @ Minv
        for j in range(n_per):
            e = library[rng.integers(len(library))] * rng.uniform(*error_scale)
            a = rng.normal(0.0, angle)
            rot = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]) * np.exp(rng.normal(0.0, log_scale))
            m = Pn.mean(0)
            Xn = (Pn + e - m) @ rot + m + rng.normal(0.0, shift, 2)
            out[i, j] = Xn @ M + c
    return out


def _read_starts(spec: DescriptorSpec, ref: np.ndarray, images: list, scales: list, X: np.ndarray,
                 truth: np.ndarray, half: float, F: np.ndarray, Y: np.ndarray, frames: np.ndarray,
                 S: np.ndarray | None, item: tuple) -> None:
    """For item (image, rows): the rows ``rows`` (the starts of image ``image``) of F (descriptors on a patch of half
    side ``half``), Y (the displacement to the label), frames (the face frame) and with S, the shape, in one compiled
    call (``landmark_cascade.training_rows``). Each image's rows are its own: images may be read on several
    threads."""
    image, rows = item
    f, y, fr, s = training_rows(spec, images[image], scales[image], X[rows], truth[image], ref, half,
                                with_shape=S is not None)
    F[rows], Y[rows], frames[rows] = f, y, fr
    if S is not None:
        S[rows] = s


def learn_landmark_cascade(images: list, scales: list, truth: np.ndarray, fits: np.ndarray, fit_owner: np.ndarray,
                           groups: np.ndarray, *, spec: DescriptorSpec = DEFAULT_SPEC,
                           halves: tuple = (0.35, 0.22, 0.14, 0.1), n_starts: int = 16,
                           error_scale: tuple = (0.5, 1.5), n_components: int = 48,
                           alphas: tuple = (0.3, 1.0, 3.0, 10.0, 30.0), shape_stages: int = 1,
                           shape_weight: float = 3.0, repeats: int = 0, rng: np.random.Generator,
                           like: LandmarkCascade | None = None, progress=None,
                           workers: int = 1) -> tuple[LandmarkCascade, list]:
    """Learn the cascade from training images (grey, each resampled by ``scales[i]``), their labels truth
    (n, 68, 2) (frame pixels), the AAM's final fits (M, 68, 2) of image ``fit_owner[m]``, and each image's group
    (an image and its mirror: one side of a hold-out). Each stage projects a point's descriptor on its
    ``n_components`` principal components (over all points and starts) before the regression; the last
    ``shape_stages`` also read the points' shape (module docstring); with ``like`` (a cascade of the same
    halves), its reference shape, descriptor means and components instead (so that a cascade's last-stage
    descriptors, which the landmark validator weighs, mean the same in both). ``repeats``: how many more times the
    cascade's last stage runs when applied (``LandmarkCascade.repeats``; the stages are learned as without).
    ``workers``: threads reading the starts' descriptors (``train.workers``; the same cascade with any number).
    Returns (cascade, per-stage record)."""
    progress = progress or (lambda it, **_: it)
    if like is not None and tuple(float(h) for h in halves) != like.halves:
        raise ValueError(f"halves {tuple(halves)} differ from the cascade whose descriptors they share {like.halves}")
    ref = reference_shape(truth) if like is None else like.ref
    lib, real = [], []
    err = nme(fits, truth[fit_owner])
    for i in range(len(truth)):
        M, _ = similarity_to(ref, truth[i])
        own = np.flatnonzero((fit_owner == i) & (err < MAX_LIBRARY_NME))
        if len(own):
            Minv = np.linalg.inv(M)
            lib.extend((fits[own] - truth[i]) @ Minv)
            real.append((i, fits[rng.choice(own)]))
    lib = np.array(lib)
    made = made_starts(truth, ref, lib, n_starts, rng, error_scale)
    owner = np.r_[[i for i, _ in real], np.repeat(np.arange(len(truth)), n_starts)].astype(np.int64)
    X = np.concatenate([np.array([f for _, f in real]).reshape(-1, 68, 2), made.reshape(-1, 68, 2)])
    log.info("landmark cascade: %d starts (%d the search's own), %d library errors, median NME %.4f", len(X),
             len(real), len(lib), float(np.median(nme(X, truth[owner]))))
    by_image = [(i, rows) for i, rows in enumerate(rows_by_owner(owner, len(truth))) if len(rows)]
    per = spec.size
    d = min(n_components, per)
    Rs, Ss, bs, means, bases, record = [], [], [], [], [], []
    for k in progress(range(len(halves)), desc="landmark cascade", unit="stage"):
        F = np.empty((len(X), 68 * spec.size), np.float32)
        Y = np.empty((len(X), 136))
        frames = np.empty((len(X), 2, 2))
        with_shape = k >= len(halves) - shape_stages
        S = np.empty((len(X), 136), np.float32) if with_shape else None
        for_each(partial(_read_starts, spec, ref, images, scales, X, truth, halves[k], F, Y, frames, S), by_image,
                 workers)
        sample = F.reshape(-1, per)[rng.permutation(len(F) * 68)[:50000]].astype(np.float64)
        if like is None:
            mu = sample.mean(0)
            _, sv, Vt = np.linalg.svd(sample - mu, full_matrices=False)
            mu, B = mu.astype(np.float32), np.ascontiguousarray(Vt[:d].T, dtype=np.float32)
        else:
            mu, B = like.basis_mean[k], like.basis[k]
        centred = sample - mu
        energy = float(np.linalg.norm(centred @ B) ** 2 / max(np.linalg.norm(centred) ** 2, 1e-30))
        Z = project_descriptors(F, mu, B)
        del F
        nz = Z.shape[1]
        if with_shape:  # the shape's columns weighted against the descriptors' in the ridge
            Z = np.concatenate([Z, np.float32(shape_weight) * S], axis=1)
        R, b, alpha = ridge_fit(Z, Y, alphas=alphas, groups=groups[owner], rng=np.random.default_rng(k))
        # float16 as the model file stores them (half the bytes; ~1e-3 relative)
        Sk = (R[:, nz:] * shape_weight if with_shape else np.zeros((136, 136))).astype(np.float16).astype(np.float32)
        R = np.ascontiguousarray(R[:, :nz]).astype(np.float16).astype(np.float32)
        step = Z[:, :nz] @ R.T + b
        if with_shape:
            step += S @ Sk.T
        step = step.reshape(-1, 68, 2)
        del Z
        X = X + np.einsum("mlj,mjk->mlk", step, frames)
        Rs.append(R)
        Ss.append(Sk)
        bs.append(b)
        means.append(mu)
        bases.append(B)
        e = nme(X, truth[owner])
        record.append({"stage": k, "half": halves[k], "alpha": alpha, "shape": bool(with_shape),
                       "train_nme_median": float(np.median(e)), "train_nme_mean": float(e.mean()),
                       "pca_energy": energy})
        log.info("landmark stage %d: ridge %g, training starts' NME median %.4f mean %.4f", k, alpha,
                 float(np.median(e)), float(e.mean()))
    return LandmarkCascade(ref, spec, tuple(float(h) for h in halves), np.stack(means), np.stack(bases),
                           np.stack(Rs), np.stack(bs), np.stack(Ss), repeats), record
