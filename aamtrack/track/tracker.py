"""Video tracker: detection, then frame-to-frame active search, confidence, loss and re-detection.

``Tracker.track(frames)`` is a generator: it takes frames (objects with ``index``, ``timestamp``, ``image``
(BGR/grey or None) and optionally ``dropped``) and yields one FrameResult per frame, in order. Its loop state
(the current parameters, the person's sigma) lives in the generator's locals, so one Tracker can serve several
videos. With several faces in view the largest is tracked.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Iterable, Iterator

import numpy as np

from ..mesh.shape_model import N_POSE
from ..model import Model
from .detector import HaarDetector, guess_points
from .pyramid import Levels, to_gray32
from .result import FitResult, FrameResult
from .search import Searcher
from ..train.shape_fit import initial_pose

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrackerConfig:
    """min_confidence: below it a frame is lost and the detector runs on the next frame.
    min_inside: share of the 68 landmarks that must lie inside the frame.
    max_turn, max_rescale: a frame whose fit turned more than ``max_turn`` radians about any axis or rescaled
    by more than ``max_rescale`` (log) since the previous frame is taken as lost: no head does that in 1/25 s,
    a search that slid onto the background does (the residual alone can miss it on textured backgrounds).
    roi_margin: the search works on a crop of the face's box grown by this share of its size on each side.
    predict: constant-velocity prediction of the pose (damped by ``predict_damping``).
    sigma_frames: 3D models estimate the person's shape units in this many good frames (the median of
    independent per-frame estimates by the model's person couple, each from the mean person), then hold them
    (0: keep the training set's mean person). cap12, 3D: mean NME 0.065 without, 0.048 with 15 frames,
    0.0477 (max 0.091) with 50.
    One person per video is assumed: sigma is kept through losses and re-detections.
    skip_coarse: frames tracked from the previous frame skip this many of the coarsest couples (they give
    the capture range a detection needs; frame-to-frame motion is smaller). On cap12 (2D) skipping one kept
    the accuracy (mean NME 0.0426 -> 0.0424) and cut the median tracking time 0.85 -> 0.75 ms.
    starts: after a detection the search runs from each (scale factor, vertical shift as a share of the face
    width, roll in radians) applied to the rough pose from the box, and keeps the fit of lowest cost (Haar
    boxes vary in scale and in how far down the face they sit, and say nothing of roll)."""

    min_confidence: float = 0.5
    min_inside: float = 0.7
    max_turn: float = 0.35
    max_rescale: float = 0.25
    roi_margin: float = 0.3
    predict: bool = True
    predict_damping: float = 0.5
    sigma_frames: int = 50
    skip_coarse: int = 1
    starts: tuple = ((1.0, 0.0, 0.0), (0.9, 0.0, 0.0), (1.1, 0.0, 0.0), (1.0, -0.06, 0.0), (1.0, 0.06, 0.0),
                     (1.0, 0.0, -0.21), (1.0, 0.0, 0.21))


class Tracker:
    def __init__(self, model: Model, *, config: TrackerConfig = TrackerConfig(),
                 detector: HaarDetector | None = None):
        self.model = model
        self.config = config
        self.searcher = Searcher(model)
        self.detector = detector or HaarDetector()
        cfg = model.config
        self.box_points = np.asarray(cfg["detector_box_points"], float)
        self.r_good = float(cfg["residual_good"])
        self.r_bad = float(cfg["residual_bad"])
        # the ROI needs to cover only what the texture maps sample (Candide's scalp is not in them)
        self.roi_vertices = np.unique(np.concatenate([t.frame.pix_vid.ravel() for t in model.textures]))

    # -- one image -------------------------------------------------------------------------------------
    def confidence(self, residual: float) -> float:
        """0..1 from the finest couple's RMS residual: 1 at the training fits' median, 0 at a displaced fit."""
        return float(np.clip((self.r_bad - residual) / (self.r_bad - self.r_good), 0.0, 1.0))

    def fit_roi(self, image: np.ndarray, q0: np.ndarray, shape_params=None, *, person: bool = False,
                first: int = 0) -> tuple[FitResult, float, np.ndarray | None]:
        """Search on a crop around the face at q0 (exact: the model is translation-equivariant).
        Returns (result in frame coordinates, pyramid seconds, sigma estimate if ``person`` else None)."""
        t0 = time.perf_counter()
        sm = self.model.shape
        v = sm.project(q0, shape_params)[self.roi_vertices]
        lo, hi = v.min(0), v.max(0)
        m = self.config.roi_margin * (hi - lo).max()
        H, W = image.shape[:2]
        x0, y0 = int(max(0, np.floor(lo[0] - m))), int(max(0, np.floor(lo[1] - m)))
        x1, y1 = int(min(W, np.ceil(hi[0] + m))), int(min(H, np.ceil(hi[1] + m)))
        if x1 - x0 < 8 or y1 - y0 < 8:
            x0, y0, x1, y1 = 0, 0, W, H
        q = np.array(q0, float)
        q[4] -= x0
        q[5] -= y0
        factors = self.searcher.factors(q)
        levels = Levels(to_gray32(image[y0:y1, x0:x1]), self.searcher.lcn_sigma)  # grey of the crop only
        for r in sorted(factors[first:], reverse=True):  # now (timed apart from the search), fine to coarse
            levels.get(r)
        t_pyr = time.perf_counter() - t0
        res = self.searcher.fit(levels, q, shape_params, factors=factors, first=first)
        # each frame an independent estimate from the mean person (sigma 0); the caller takes their median
        sigma = self.searcher.fit_person(levels, res.p, None, factor=factors[-1])[1] if person else None
        p = res.p.copy()
        p[4] += x0
        p[5] += y0
        off = np.array([x0, y0], float)
        return FitResult(p=p, landmarks=res.landmarks + off, vertices=res.vertices + off, residual=res.residual,
                         iterations=res.iterations, errors=res.errors), t_pyr, sigma

    def fit_detection(self, image: np.ndarray, box, shape_params=None) -> tuple[FitResult, float]:
        """The best of the searches from the configured starts around the box's rough pose.
        Returns (result, pyramid seconds summed over the starts)."""
        q0 = self.initial_q(box, shape_params)
        best, t_pyr = None, 0.0
        for scale, shift, roll in self.config.starts:
            q = q0.copy()
            q[3] *= scale
            q[5] += shift * q0[3] * self.searcher.width
            q[2] += roll
            res, t, _ = self.fit_roi(image, q, shape_params)
            t_pyr += t
            if best is None or res.residual < best.residual:
                best = res
        return best, t_pyr

    def initial_q(self, box, shape_params=None) -> np.ndarray:
        """Rough pose from the detection box (poster: guessed feature points, least squares)."""
        return initial_pose(self.model.shape, guess_points(box, self.box_points), shape_params)

    def _inside(self, pts: np.ndarray, shape: tuple) -> float:
        H, W = shape
        ok = (pts[:, 0] >= 0) & (pts[:, 0] < W) & (pts[:, 1] >= 0) & (pts[:, 1] < H)
        return float(ok.mean())

    def _result(self, frame, status, res: FitResult | None, conf: float, shape_params, timings) -> FrameResult:
        if res is None or status not in ("detected", "tracked"):
            return FrameResult(frame=frame.index, timestamp=frame.timestamp, status=status, confidence=conf,
                               timings=timings)
        sm = self.model.shape
        q = res.p
        is3d = sm.kind == "3d"
        return FrameResult(
            frame=frame.index, timestamp=frame.timestamp, status=status, confidence=conf,
            landmarks=res.landmarks, landmarks3d=sm.landmarks3d(q, shape_params) if is3d else None,
            rotation=q[:3].copy(), translation=q[4:6].copy(), scale=float(q[3]),
            anim_params=q[N_POSE:].copy() if is3d else np.zeros(0),
            shape_params=(np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float))
            if is3d else q[N_POSE:].copy(),
            vertices=res.vertices, timings=timings)

    # -- a video ---------------------------------------------------------------------------------------
    def track(self, frames: Iterable) -> Iterator[FrameResult]:
        cfg = self.config
        q = None          # current parameters, None when there is no track
        q_prev = None     # previous frame's parameters (motion prediction)
        shape_params = None
        sigma_samples = []
        estimate = self.model.kind == "3d" and self.model.person is not None and cfg.sigma_frames > 0
        for frame in frames:
            if getattr(frame, "dropped", False):
                yield FrameResult(frame=frame.index, timestamp=frame.timestamp, status="dropped")
                continue
            if frame.image is None:
                yield FrameResult(frame=frame.index, timestamp=frame.timestamp, status="unreadable")
                q_prev = None
                continue
            timings = {}
            t0 = time.perf_counter()
            image = frame.image
            if q is None:
                box = self.detector.detect(image)
                timings["detect"] = time.perf_counter() - t0
                if box is None:
                    yield self._result(frame, "lost", None, 0.0, shape_params, timings)
                    continue
                status = "detected"
            else:
                start, status = q.copy(), "tracked"
                if cfg.predict and q_prev is not None:
                    step = cfg.predict_damping * (q - q_prev)
                    start[[2, 4, 5]] += step[[2, 4, 5]]
            t1 = time.perf_counter()
            person = estimate and len(sigma_samples) < cfg.sigma_frames
            if status == "detected":
                res, t_pyr = self.fit_detection(image, box, shape_params)
                if person:  # the person search on the chosen fit
                    last = len(self.model.couples) - 1
                    _, _, sigma = self.fit_roi(image, res.p, shape_params, person=True, first=last)
                else:
                    sigma = None
            else:
                res, t_pyr, sigma = self.fit_roi(image, start, shape_params, person=person, first=cfg.skip_coarse)
            timings["pyramid"] = t_pyr
            timings["search"] = time.perf_counter() - t1 - t_pyr
            conf = self.confidence(res.residual)
            ok = conf >= cfg.min_confidence and self._inside(res.landmarks, image.shape[:2]) >= cfg.min_inside
            if ok and status == "tracked":
                ok = (np.abs(res.p[:3] - q[:3]).max() <= cfg.max_turn
                      and abs(np.log(res.p[3] / q[3])) <= cfg.max_rescale)
            if ok:
                if sigma is not None:
                    sigma_samples.append(sigma)
                    shape_params = np.median(sigma_samples, axis=0)
                q_prev = q if status == "tracked" else None
                q = res.p
                yield self._result(frame, status, res, conf, shape_params, timings)
            else:
                q = q_prev = None
                yield self._result(frame, "lost", res, conf, shape_params, timings)
