"""Temporal smoothing of a stream of FrameResults with a One Euro filter.

Casiez, Roussel and Vogel, *1€ Filter: A Simple Speed-based Low-pass Filter for Noisy Input in Interactive
Systems*, CHI 2012. A first-order low-pass filter whose cutoff frequency rises with the signal's speed: at rest
a low cutoff removes jitter, in motion a high cutoff keeps the lag small. Per frame, with ``dt`` the time since
the previous frame (from the timestamps)::

    alpha(fc)  = 1 / (1 + 1 / (2 pi fc dt))
    dx         = (x - x_prev) / dt                        raw velocity (from the previous raw value, as in
                                                          the authors' reference code)
    dx_hat     = dx_hat_prev + alpha(d_cutoff) (dx - dx_hat_prev)
    fc         = min_cutoff + beta * speed(dx_hat)
    x_hat      = x_hat_prev + alpha(fc) (x - x_hat_prev)

This module applies it to a whole face at once: one speed per frame, the mean over the 68 landmarks of
``|dx_hat|`` divided by the face width (the width of the landmarks' bounding box), so ``speed`` is in face widths
per second and the parameters do not depend on the image size. With ``follow_jumps`` (default) the speed is at
least the raw speed of the landmarks' centroid (``|mean(dx)|``, not low-passed): the filtered speed reaches a
sudden move of the whole face only a frame or two late (``d_cutoff``), so the first frames of a camera shake or a
quick turn were held back, while the centroid's raw speed sees the move at once and hardly sees the points' own
noise (which averages out over 68 points). Measured (``benchmarks/smoothing.py``; the robustness suite's video
rows, cap12 3D, smoothed NME minus raw, 2026-11-29): shake +0.0076 -> +0.0025, clean +0.0015 -> +0.0011 (jitter
0.075 -> 0.078 px against 0.169 raw), dim_small -0.0013 -> -0.0014; raising ``beta`` to 25 instead, for the same
clean jitter (0.080), left shake at +0.0057. The same ``alpha(fc)`` then filters the landmarks,
the mesh vertices, the pose (rotation, translation, scale), the 3D landmarks and the animation units, so
everything written for a frame stays consistent (an overlay's mesh and axes sit on its landmarks). Shape units
(held per person) pass through.

The filter is reset (its output is the raw frame) on a detection (``status == "detected"``: the track starts
again, possibly on another face) and on the first successful frame after a frame without a result (lost,
unreadable); dropped frames of a realtime replay only widen ``dt``. Frames without a result pass through as they
are. Smoothing runs on the tracker's output only: the tracker itself searches from its own unsmoothed fits.

Defaults, chosen on cap12 (the one video with a per-frame reference) with the shipped 3D model
(``benchmarks/smoothing.py``; README, "Smoothing"): ``min_cutoff = 0.02`` Hz, ``beta = 20`` Hz per (face width / s),
``d_cutoff = 4`` Hz. There they halve the jitter on the still stretches (0.46x with ``follow_jumps``, 2026-11-29) at 0.05 frame of
added lag on the moving ones. At rest the cutoff is set mostly by the speed the landmarks' own noise shows (beta times about 0.03
face widths/s), not by ``min_cutoff``; a faster speed estimate (``d_cutoff`` 4 rather than 2 Hz) is what lowered it. The lag depends on the speed: on a steady
motion of v face widths per second the cutoff settles at ``min_cutoff + beta v`` and the output trails by
``(1 - alpha) / alpha`` frames (at 25 fps: 0.2 frame at 1 face width/s, 0.4 at 0.5, 0.8 at 0.25, 2.0 at 0.1, 3.9 at 0.05; in pixels
the lag shrinks with the speed). Still stretches of a real video hold slow true motion as well as noise, so
less jitter costs lag on slow motion: raise ``beta`` for less lag, lower it for less jitter.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Iterable, Iterator

import numpy as np

from ..result import FrameResult

__all__ = ["SmoothConfig", "OneEuroFilter", "smooth_results"]

# FrameResult fields filtered with the face's alpha (landmarks and vertices first: they give the speed)
_FIELDS = ("landmarks", "vertices", "landmarks3d", "rotation", "translation", "anim_params")


@dataclass(frozen=True)
class SmoothConfig:
    """Parameters of the One Euro filter (Casiez et al. 2012).

    min_cutoff : float, Hz -- cutoff at rest: lower is smoother when still, with more lag on slow motion.
    beta : float, Hz per (face width / s) -- how fast the cutoff rises with speed: higher is less lag in motion.
    d_cutoff : float, Hz -- cutoff of the low-pass on the velocity that drives the cutoff.
    follow_jumps : bool -- the speed is at least the landmarks' centroid's raw speed (``smooth_results``), so a
        sudden move of the whole face (camera shake, a quick turn) opens the filter at once.
    """

    min_cutoff: float = 0.02
    beta: float = 20.0
    d_cutoff: float = 4.0
    follow_jumps: bool = True

    def __post_init__(self):
        if not (self.min_cutoff > 0 and self.d_cutoff > 0 and self.beta >= 0):
            raise ValueError(f"need min_cutoff > 0, d_cutoff > 0, beta >= 0, got {self}")


def _alpha(cutoff: float, dt: float) -> float:
    return 1.0 / (1.0 + 1.0 / (2.0 * math.pi * cutoff * dt))


class OneEuroFilter:
    """One Euro filter on an array signal whose elements share one speed (the caller's ``speed`` function).

    ``filter(x, t)`` returns the smoothed ``x`` (same shape, float64) and the alpha used; ``reset()`` forgets the
    past, so the next value passes through unchanged. State lives on the object: one filter per signal.
    """

    def __init__(self, config: SmoothConfig = SmoothConfig(), speed=None, jump=None):
        self.config = config
        self.speed = speed or (lambda dx, x: float(np.abs(dx).mean()))
        self.jump = jump  # (raw dx, x) -> a speed the cutoff follows at once, unfiltered; None: none
        self.reset()

    def reset(self) -> None:
        self.x_prev = None
        self.x_hat = None
        self.dx_hat = None
        self.t = None

    def filter(self, x, t: float) -> tuple[np.ndarray, float]:
        x = np.asarray(x, dtype=np.float64)
        dt = None if self.t is None else t - self.t
        if self.x_hat is None or not dt or dt <= 0 or self.x_hat.shape != x.shape:
            self.x_prev, self.x_hat, self.dx_hat, self.t = x.copy(), x.copy(), np.zeros_like(x), t
            return x.copy(), 1.0
        cfg = self.config
        dx = (x - self.x_prev) / dt
        self.x_prev = x.copy()
        self.dx_hat = self.dx_hat + _alpha(cfg.d_cutoff, dt) * (dx - self.dx_hat)
        speed = self.speed(self.dx_hat, x)
        if self.jump is not None:
            speed = max(speed, self.jump(dx, x))
        a = _alpha(cfg.min_cutoff + cfg.beta * speed, dt)
        self.x_hat = self.x_hat + a * (x - self.x_hat)
        self.t = t
        return self.x_hat.copy(), a


def _face_width(landmarks: np.ndarray) -> float:
    """The landmarks' x extent in pixels (at least 1): the unit of the filter's speeds."""
    return max(float(np.ptp(landmarks[:, 0])), 1.0)


def _face_speed(dx_landmarks: np.ndarray, landmarks: np.ndarray) -> float:
    """Mean landmark speed in face widths per second."""
    return float(np.linalg.norm(dx_landmarks, axis=1).mean()) / _face_width(landmarks)


def _centroid_speed(dx_landmarks: np.ndarray, landmarks: np.ndarray) -> float:
    """Speed of the landmarks' centroid in face widths per second (``SmoothConfig.follow_jumps``)."""
    return float(np.linalg.norm(dx_landmarks.mean(axis=0))) / _face_width(landmarks)


def smooth_results(results: Iterable[FrameResult], config: SmoothConfig = SmoothConfig()) -> Iterator[FrameResult]:
    """Yield ``results`` with landmarks, vertices, pose, 3D landmarks and animation units One-Euro-filtered.

    Parameters
    ----------
    results : iterable of FrameResult
        A tracker's output, in frame order (e.g. ``Tracker.track(frames)``).
    config : SmoothConfig

    Yields
    ------
    FrameResult
        One per input, same frame, status, confidence and timings. Unsuccessful ones are passed through.
    """
    landmark_filter = OneEuroFilter(config, speed=_face_speed, jump=_centroid_speed if config.follow_jumps else None)
    state = {}          # field -> smoothed value of the previous successful frame
    gap = True          # no usable predecessor: the next successful frame resets the filter
    for res in results:
        if not res.success:
            if res.status != "dropped":
                gap = True
            yield res
            continue
        lm = np.asarray(res.landmarks, dtype=np.float64)
        if gap or res.status == "detected" or not np.isfinite(lm).all():
            landmark_filter.reset()
        smoothed_lm, a = landmark_filter.filter(lm, res.timestamp)
        changes = {"landmarks": smoothed_lm}
        for name in _FIELDS[1:]:
            value = getattr(res, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=np.float64)
            prev = state.get(name)
            if a < 1.0 and prev is not None and prev.shape == value.shape:
                value = prev + a * (value - prev)
            changes[name] = value
        scale = res.scale
        if a < 1.0 and "scale" in state and math.isfinite(state["scale"]):
            scale = state["scale"] + a * (scale - state["scale"])
        changes["scale"] = float(scale)
        state = {**changes}
        gap = False
        yield dataclasses.replace(res, **changes)
