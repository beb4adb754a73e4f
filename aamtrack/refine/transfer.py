"""Facial motion transfer from a source sequence F^t (identity A) to a target neutral face T^0 (identity B), after
Akagi et al., section 3:

1. a similarity (scale, rotation, translation; Umeyama 1991) from the source's 68 landmarks to the target's puts
   the source in the target's frame and units;
2. D_fit, an RBF deformation with ``D_fit(F^0) ~ T^0``, starts from the 68 landmarks; the key point sampler
   (:mod:`.sampler`) adds key points chosen on the source motion and places them on the target by GMM
   registration of ``D_fit(F^0)`` to T^0: this gives the correspondences (no other vertex correspondence is used);
3. D_trns^t moves the target: an RBF deformation centred on the key points' places on the target whose values are
   the source key points' displacements ``F^t - F^0`` (in the target frame), so ``T^t = T^0 + D_trns^t(T^0)``.

A zero source motion gives ``T^t = T^0`` exactly.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .rbf import rbf_system
from .sampler import SamplerConfig, refine_key_points

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TransferConfig:
    """sampler : key point sampler options for D_fit; kernel, smoothing : of D_trns;
    max_selection_frames : at most this many source frames (evenly spaced) are used to select key points."""

    sampler: SamplerConfig = field(default_factory=SamplerConfig)
    kernel: str = "thin_plate"
    smoothing: float = 0.0
    max_selection_frames: int = 50


@dataclass(frozen=True)
class TransferResult:
    """frames : (n_frames, n_target, 3) float32 animated target (frame 0 is T^0).
    key_index : (n_keys,) int64 source vertices used as key points (the first 68 are the landmarks).
    key_on_target : (n_keys, 3) float64 their places on the target. scale, rotation (3, 3), translation (3,):
    the similarity ``x -> scale * x @ rotation.T + translation`` from source to target frame.
    fit_errors : mean distance from D_fit(F^0) to T^0 after each accepted sampler round."""

    frames: np.ndarray
    key_index: np.ndarray
    key_on_target: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    fit_errors: tuple = ()


def similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares ``dst ~ s * src @ R.T + t`` (Umeyama 1991): returns (s, R (3, 3), t (3,))."""
    src = np.asarray(src, np.float64)
    dst = np.asarray(dst, np.float64)
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    u, sig, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[-1] = -1.0
    rot = u @ np.diag(d) @ vt
    var = (a * a).sum() / len(src)
    s = float((sig * d).sum() / var) if var > 0 else 1.0
    return s, rot, mu_d - s * mu_s @ rot.T


def transfer(
    source_frames: np.ndarray,
    source_landmarks: np.ndarray,
    target: np.ndarray,
    target_landmarks: np.ndarray,
    *,
    config: TransferConfig = TransferConfig(),
    progress: Callable[[int], None] | None = None,
) -> TransferResult:
    """Animate ``target`` with the motion of ``source_frames``.

    source_frames : (n_frames, n_source, 3) source faces, same vertex order in every frame; frame 0 is F^0.
    source_landmarks, target_landmarks : (68,) int vertex indices of the iBUG-68 landmarks (the only given
    correspondence). target : (n_target, 3) neutral target T^0 (any vertex count, order and units).
    progress : called with the number of registrations done.
    """
    src = np.asarray(source_frames, dtype=np.float64)
    tgt = np.ascontiguousarray(target, dtype=np.float64)
    s_lm = np.asarray(source_landmarks, dtype=np.int64)
    t_lm = np.asarray(target_landmarks, dtype=np.int64)
    if src.ndim != 3 or src.shape[2] != 3 or len(src) == 0:
        raise ValueError(f"source_frames must be (n_frames >= 1, n, 3), got {src.shape}")
    if len(s_lm) != len(t_lm):
        raise ValueError(f"{len(s_lm)} source landmarks but {len(t_lm)} target landmarks")
    scale, rot, shift = similarity(src[0, s_lm], tgt[t_lm])
    src = scale * src @ rot.T + shift
    neutral = src[0]
    motion = src - neutral
    step = max(1, -(-len(src) // max(1, config.max_selection_frames)))
    # D_fit: a two-frame "sequence" F^0 -> T^0, key points chosen on the source motion
    keys = refine_key_points(
        neutral,
        [neutral, tgt],
        np.stack([neutral[s_lm], tgt[t_lm]]),
        s_lm,
        config=config.sampler,
        motion=motion[::step],
        progress=progress,
    )
    on_target = keys.positions[1]
    log.info("transfer: %d key points, fit error %s", len(keys.index), keys.errors)
    # D_trns^t: source key point displacements, interpolated over the target around their places on it
    system = rbf_system(on_target, kernel=config.kernel, smoothing=config.smoothing)
    n_frames, k = len(src), len(keys.index)
    disp = motion[:, keys.index].transpose(1, 0, 2).reshape(k, 3 * n_frames)
    moved = system.evaluate(tgt, system.solve(disp)).reshape(len(tgt), n_frames, 3).transpose(1, 0, 2)
    frames = (tgt[None] + moved).astype(np.float32)
    return TransferResult(frames, keys.index, on_target, scale, rot, shift, keys.errors)
