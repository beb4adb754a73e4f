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

The forward filter is reset (its output is the raw frame) on a detection (``status == "detected"``: the track
starts again, possibly on another face) and on the first successful frame after a frame without a result (lost,
unreadable); the backward one (``look_ahead``, below) on the frame before a detection and the last successful
frame before a frame without a result, so neither pulls a frame towards another stretch's face. Dropped frames of
a realtime replay only widen ``dt``. Frames without a result pass through as they are. Smoothing runs on the tracker's output only: the tracker itself searches from its own unsmoothed fits.

Defaults, chosen on cap12 (the one video with a per-frame reference) with the shipped 3D model
(``benchmarks/smoothing.py``; README, "Smoothing"): ``min_cutoff = 0.02`` Hz, ``beta = 20`` Hz per (face width / s),
``d_cutoff = 4`` Hz. There they halve the jitter on the still stretches (0.46x with ``follow_jumps``, 2026-11-29) at 0.05 frame of
added lag on the moving ones. At rest the cutoff is set mostly by the speed the landmarks' own noise shows (beta times about 0.03
face widths/s), not by ``min_cutoff``; a faster speed estimate (``d_cutoff`` 4 rather than 2 Hz) is what lowered it. The lag depends on the speed: on a steady
motion of v face widths per second the cutoff settles at ``min_cutoff + beta v`` and the output trails by
``(1 - alpha) / alpha`` frames (at 25 fps: 0.2 frame at 1 face width/s, 0.4 at 0.5, 0.8 at 0.25, 2.0 at 0.1, 3.9 at 0.05; in pixels
the lag shrinks with the speed). Still stretches of a real video hold slow true motion as well as noise, so
less jitter costs lag on slow motion: raise ``beta`` for less lag, lower it for less jitter.

Looking ahead (``look_ahead`` frames, default 8; since 2026-11-29): a recorded video's later frames are there to
be read, so the filter also runs backwards in time, from a few frames ahead, and the two are averaged. Forwards
the filter trails the motion by the lag above; backwards it leads by as much; their mean keeps the smoothing and
loses the lag (forward-backward filtering; on a steady ramp the mean's lag is under 0.01 frame). Measured on
cap12 (``benchmarks/smoothing.py``, the dlib reference; raw 3D 0.0196, 2D 0.0191): NME 3D 0.0207 -> 0.0197, 2D
0.0203 -> 0.0193, jitter on the still stretches 0.078 -> 0.073 px; the robustness suite's smoothed column
(3D): clean 0.0207 -> 0.0197, noise 0.0231 -> 0.0223, dim_small 0.0285 -> 0.0278, shake 0.0258 -> 0.0246, every
other row the same or lower. Results then come out up to 3 x ``look_ahead`` frames late (``_two_sided``); a
live replay (``aamtrack run --realtime``) has no frames ahead and filters forwards only (``look_ahead`` 0).
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
    look_ahead : int, frames -- also filter backwards, from this many frames ahead, and average with the forward
        filter (the module docstring: takes out the lag); 0 filters forwards only (causal, as a live feed needs).
    """

    min_cutoff: float = 0.02
    beta: float = 20.0
    d_cutoff: float = 4.0
    follow_jumps: bool = True
    look_ahead: int = 8

    def __post_init__(self):
        if not (self.min_cutoff > 0 and self.d_cutoff > 0 and self.beta >= 0 and self.look_ahead >= 0):
            raise ValueError(f"need min_cutoff > 0, d_cutoff > 0, beta >= 0, look_ahead >= 0, got {self}")


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
    x = landmarks[:, 0]
    return max(float(x.max() - x.min()), 1.0)


def _face_speed(dx_landmarks: np.ndarray, landmarks: np.ndarray) -> float:
    """Mean landmark speed in face widths per second."""
    speeds = np.sqrt(np.einsum("ij,ij->i", dx_landmarks, dx_landmarks))
    return float(speeds.sum()) / len(speeds) / _face_width(landmarks)


def _centroid_speed(dx_landmarks: np.ndarray, landmarks: np.ndarray) -> float:
    """Speed of the landmarks' centroid in face widths per second (``SmoothConfig.follow_jumps``)."""
    vx, vy = dx_landmarks.sum(axis=0)
    return math.hypot(vx, vy) / len(dx_landmarks) / _face_width(landmarks)


def smooth_results(results: Iterable[FrameResult], config: SmoothConfig = SmoothConfig()) -> Iterator[FrameResult]:
    """Yield ``results`` with landmarks, vertices, pose, 3D landmarks and animation units One-Euro-filtered:
    with ``config.look_ahead`` > 0 forwards and backwards, the two averaged (``_two_sided``); else forwards only
    (``_forwards``).

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
    if config.look_ahead > 0:
        return _two_sided(results, config)
    return _forwards(results, config)


def _forwards(results: Iterable[FrameResult], config: SmoothConfig) -> Iterator[FrameResult]:
    """``smooth_results`` filtering forwards only, one frame after another (causal)."""
    for res, stacked, y in _forward_pass(results, config):
        yield res if y is None else dataclasses.replace(res, **_unstacked(y, stacked[1]))


def _forward_pass(results: Iterable[FrameResult], config: SmoothConfig) -> Iterator[tuple]:
    """(result, its ``_stacked`` fields or None, the filtered stacked fields or None) per result, in order: None for
    unsuccessful results, which pass through. The filter restarts on a detection and after a lost or unreadable
    frame (dropped frames of a realtime replay only widen the step)."""
    f = _StackedFilter(config)
    gap = True  # no usable predecessor: the next successful frame restarts the filter
    for res in results:
        if not res.success:
            if res.status != "dropped":
                gap = True
            yield res, None, None
            continue
        stacked = _stacked(res)
        y = f.step(stacked, res.timestamp, gap or res.status == "detected")
        gap = False
        yield res, stacked, y


class _StackedFilter:
    """The face's One Euro filter on a result's stacked fields (``_stacked``): the landmarks (first) give the speed
    and so alpha, which filters every field alike, as one vector."""

    def __init__(self, config: SmoothConfig):
        self.landmarks = OneEuroFilter(config, speed=_face_speed, jump=_centroid_speed if config.follow_jumps else None)
        self.y, self.layout = None, None

    def step(self, stacked: tuple, t: float, restart: bool) -> np.ndarray:
        x, layout = stacked
        lm = x[:layout[0][2]].reshape(-1, 2)
        if restart or not np.isfinite(lm).all():
            self.landmarks.reset()
        a = self.landmarks.filter(lm, t)[1]  # 1 where the filter (re)starts: the value passes through
        if a < 1.0 and self.y is not None and layout == self.layout and math.isfinite(self.y[-1]):
            self.y = self.y + a * (x - self.y)
        else:
            self.y = x
        self.layout = layout
        return self.y


def _stacked(res: FrameResult) -> tuple[np.ndarray, tuple]:
    """The filtered fields of a successful result (``_FIELDS`` that it has, landmarks first, then its scale) as one
    float64 vector, and their layout ((name, shape, size), ...)."""
    parts, layout = [], []
    for name in _FIELDS:
        value = getattr(res, name)
        if value is None:
            continue
        value = np.asarray(value, dtype=np.float64)
        parts.append(value.ravel())
        layout.append((name, value.shape, value.size))
    parts.append(np.array([res.scale], dtype=np.float64))
    layout.append(("scale", (), 1))
    return np.concatenate(parts), tuple(layout)


def _unstacked(y: np.ndarray, layout: tuple) -> dict:
    """``_stacked``'s vector back as FrameResult fields."""
    out, k = {}, 0
    for name, shape, size in layout:
        out[name] = float(y[k]) if name == "scale" else y[k:k + size].reshape(shape)
        k += size
    return out


def _two_sided(results: Iterable[FrameResult], config: SmoothConfig) -> Iterator[FrameResult]:
    """The forward filter (``_forward_pass``) and the same filter run backwards in time (``_backward_pass``),
    averaged.

    A causal filter trails the motion; run backwards it leads by as much, so their mean follows the motion without
    the lag while keeping the smoothing (forward-backward filtering, here with the One Euro filter's adaptive cutoff
    on either side). The backward filter needs the frames after a frame: the stream is taken in blocks of
    2 x ``look_ahead`` frames, each block's backward pass started (from the raw value) ``look_ahead`` frames after
    the block's end, or at the end of its stretch of successful frames (the frame before a detection, a lost or
    unreadable frame, the end of the stream). So results come out at most 3 x ``look_ahead`` frames after they go
    in, and the backward filter has had at least ``look_ahead`` frames to settle.
    """
    n = config.look_ahead
    block = 2 * n
    buf: list = []  # (result, stacked, forward-filtered) not yet given out
    for entry in _forward_pass(results, config):
        buf.append(entry)
        if len(buf) >= block + n:
            yield from _averaged(buf, block, config)
            del buf[:block]
    yield from _averaged(buf, len(buf), config)


def _averaged(entries: list, n_out: int, config: SmoothConfig) -> Iterator[FrameResult]:
    """The first ``n_out`` of ``entries`` (``_forward_pass``'s, in frame order), each the mean of its forward value
    and the backward filter's (``_backward_pass`` over all of ``entries``)."""
    if not entries or n_out <= 0:
        return
    back = _backward_pass(entries, n_out, config)
    for (res, stacked, y_fwd), y_bwd in zip(entries[:n_out], back):
        yield res if y_fwd is None else dataclasses.replace(res, **_unstacked(0.5 * (y_fwd + y_bwd), stacked[1]))


def _backward_pass(entries: list, n_out: int, config: SmoothConfig) -> list:
    """The filter of ``_forward_pass`` run over ``entries`` from the last to the first, as if time ran backwards:
    for each of the first ``n_out``, None (unsuccessful) or its filtered stacked fields. It restarts where
    ``_forward_pass`` would if the frames came in reverse: at the last entry, after a lost or unreadable frame, and
    on the frame before a detection (where a forward stretch starts)."""
    f = _StackedFilter(config)
    out: list = [None] * n_out
    t_end = entries[-1][0].timestamp
    gap = True
    for i in range(len(entries) - 1, -1, -1):
        res, stacked, _ = entries[i]
        if stacked is None:
            if res.status != "dropped":
                gap = True
            continue
        restart = gap or i + 1 == len(entries) or entries[i + 1][0].status == "detected"
        y = f.step(stacked, t_end - res.timestamp, restart)
        if i < n_out:
            out[i] = y
        gap = False
    return out
