"""Multi-resolution active search on one image (below ``train`` and ``track``: training evaluates its fits and
learns the fit validator with the same code that tracks) (poster, "Multi-Resolution Active Model Search"): for each
couple, coarse to fine, warp, residual, delta = R e, p <- p + delta, in compiled code: the learned cascade
(``aamtrack._kernels.warp._cascade``) or the Jacobian update with step control (``_search``).

The search vector p is [pose, coefficients, shape units] (``Model``); ``shape_params`` given to ``fit`` pins the
shape units (the tracker's held estimate of the person) by setting both their bounds to it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .imaging import Levels, level_factor, level_shift
from .kernels import cascade, project, residual, search
from .landmark_cascade import descriptor_view
from .mesh.shape_model import N_POSE
from .model import Model
from .result import FitResult

MAX_ITER = 30
TOL = 1e-3
DELTA_TOL = 0.002  # Jacobian search: an update below this (face widths, radians, log-scale; x5 in prior spreads) stops
N_STEPS = 4  # Jacobian search: step sizes tried per iteration, 1, 1/2, 1/4, 1/8


class Searcher:
    """A model's arrays in the layout the kernels take, and scratch buffers allocated once (so one Searcher
    serves one thread at a time). Holds no state between calls. ``adaptive_view``: the landmark cascade reads a
    low-contrast face's descriptors brightened and a noisy face's smoothed (``landmark_cascade.descriptor_view``;
    False: as they are, as before 2026-11-29)."""

    def __init__(self, model: Model, *, adaptive_view: bool = True):
        self.model = model
        self.adaptive_view = adaptive_view
        sm = model.shape
        self.width = sm.frontal_width()
        self.shape3d = np.ascontiguousarray(sm.mean)
        basis, free, lo, hi = sm.person_view()
        self.basis, self.lo, self.hi = basis, lo, hi
        self.n_params = len(lo)
        self.mode = model.features.mode
        self._scratch = {}
        for t in model.textures:
            D = len(t.mean)
            if D not in self._scratch:
                self._scratch[D] = (np.empty((sm.n_vertices, 2)), np.empty(D, np.float32),
                                    np.empty(max(t.appearance.shape[1], 1)), np.empty(D), np.empty(self.n_params))
        self._delta_tol = [self._tolerances(c.free) for c in model.couples]
        # what the fit statistics need of the finest couple, prepared once: the rows of its (last) update that move
        # the pose, as float64 (numpy would cast on every @), and each row's unit (1, or face widths)
        last = model.couples[-1]
        pose = [a for a, j in enumerate(last.free) if j < N_POSE]
        self._stat_update = (last.cascade[-1] if last.n_stages else last.update_matrix)[pose].astype(np.float64)
        self._stat_bias = last.cascade_bias[-1][pose] if last.n_stages else np.zeros(len(pose))
        self._stat_unit = [1.0 if last.free[a] <= 3 else self.width for a in pose]
        self._mean_norm = [float(np.linalg.norm(t.mean)) for t in model.textures]

    def _tolerances(self, free: np.ndarray, tol: float = DELTA_TOL) -> np.ndarray:
        """(n_free,) Jacobian-search update sizes that count as converged: tol radians / log-scale, tol face
        widths of translation (model units), 5 tol prior spreads of a coefficient or shape unit."""
        free = np.asarray(free)
        return np.where(free <= 3, tol, np.where(free < N_POSE, tol * self.width,
                                                5 * tol * self.model.shape.spreads()[free]))

    def levels(self, gray: np.ndarray, *, edge: bool = False) -> Levels:
        """The feature images of a grey frame (H, W) float32 for the couples, built on demand (``edge``: what lies
        past its edges is missing, as past the frame's, ``Levels``)."""
        return Levels(gray, self.model.features, edge=edge)

    def factors(self, p: np.ndarray) -> list[float]:
        """Each couple's resampling factor for the face size of p (``imaging.level_factor``)."""
        return [level_factor(p[3] * self.width, c.face_px) for c in self.model.couples]

    def bounds(self, shape_params: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of p, with the shape units pinned to ``shape_params`` when given."""
        if shape_params is None or self.model.shape.n_shape == 0:
            return self.lo, self.hi
        lo, hi = self.lo.copy(), self.hi.copy()
        n_q = self.model.shape.n_q
        lo[n_q:] = hi[n_q:] = np.clip(shape_params, self.lo[n_q:], self.hi[n_q:])
        return lo, hi

    def _couple_run(self, c, k: int, img: np.ndarray, r: float, p: np.ndarray, lo, hi, fill: bool) -> int:
        """One couple c (the model's couple k, or its soft twin) on p (in place) on the level ``img`` resampled by
        r (``fill``: samples past its edge read as missing, ``kernels.residual``). Returns iterations."""
        t = self.model.textures[c.texture]
        shift = level_shift(r)
        if c.n_stages:
            verts, tex, coef, e, delta = self._scratch[len(t.mean)]
            cascade(img, r, shift, self.shape3d, self.basis, p, c.free, lo, hi, *c.quantised, c.cascade_bias, t.mean,
                    t.appearance, t.frame.pix_vid, t.frame.pix_bary, self.mode, verts, tex,
                    coef[:t.appearance.shape[1]], e, delta[:len(c.free)], fill=fill)
            return c.n_stages
        n_it, _ = search(img, r, shift, self.shape3d, self.basis, p, c.free, lo, hi, c.update_matrix, c.prior_step,
                         c.prior, t.mean, t.appearance, t.frame.pix_vid, t.frame.pix_bary, self.mode, MAX_ITER, TOL,
                         N_STEPS, self._delta_tol[k], fill=fill)
        return int(n_it)

    def fit(self, levels: Levels, p0: np.ndarray, shape_params: np.ndarray | None = None, *,
            factors: list[float] | None = None, first: int = 0, landmarks: bool = True,
            soft: bool | None = None) -> FitResult:
        """Search from p0 (n_params,) on a frame's ``levels``, couples ``first``..last, each at the resampling
        ``factors[k]`` (default: from p0's face size), with the shape units pinned to ``shape_params`` if given
        (a face that looks soft at p0 takes the model's soft couples, ``Model.couples_for``, unless ``soft`` says
        which: a tracked frame takes its previous frame's verdict, ``FitResult.soft``, for free);
        then the landmark cascade on the result (``refine_landmarks``) unless ``landmarks`` is False (a caller
        choosing among several fits refines only the one it keeps)."""
        p = np.array(p0, dtype=np.float64)
        if len(p) != self.n_params:
            raise ValueError(f"search vector of {len(p)} values, the model has {self.n_params}")
        factors = self.factors(p) if factors is None else factors
        lo, hi = self.bounds(shape_params)
        np.clip(p, lo, hi, out=p)
        couples = self.model.couples
        if self.model.soft_couples and soft is None:  # a soft face takes the couples learned on soft faces
            couples = self.model.couples_for(levels.resampled(factors[-1]), factors[-1],
                                             self.model.shape.landmark_map @ self.project(p))
        elif self.model.soft_couples and soft:
            couples = self.model.soft_couples
        iters = tuple(self._couple_run(couples[k], k, levels.get(factors[k]), factors[k], p, lo, hi, levels.edge)
                      for k in range(first, len(couples)))
        stats = self.statistics(levels, p, factors[-1])
        verts = self.project(p)
        res = FitResult(p=p, landmarks=self.model.shape.landmark_map @ verts, vertices=verts, residual=stats[0],
                        iterations=iters, stats=stats, confidence=self.model.validator(stats))
        return self.refine_landmarks(levels, res, factors[-1]) if landmarks else res

    def refine_landmarks(self, levels: Levels, res: FitResult, r: float | None = None, *,
                         last: int = 0, dim: bool | None = None, still: bool = False) -> FitResult:
        """The fit with its 68 points moved by the model's landmark cascade (``aamtrack.landmark_cascade``),
        read on the grey level resampled by r (default: the finest couple's factor for the fit's face size; the
        search passes the one it used, whose level is made already); the fit itself when the model has none. A
        soft face takes the model's soft cascade (``Model.cascade_for``).
        A dark or flat face's descriptors are read brightened, a noisy face's smoothed
        (``landmark_cascade.descriptor_view``, unless ``adaptive_view`` is off). The pose and mesh stay the
        search's; the confidence becomes the landmark validator's (the fit statistics and the cascade's last
        descriptors, ``LandmarkCascade.run``) when the model has one (for a dim, noisy face, its validator for
        those; for the soft cascade's fit, the soft one's: ``Model.validator_for``).
        ``last`` > 0 runs only the cascade's last ``last`` stages (the tracker's tracked frames,
        ``TrackerConfig.landmark_stages_tracked``). The last stage's ``LandmarkCascade.repeats`` are left out for a
        face that is dim and noisy at the search's points (``Model.dim``), or, given ``dim``, as it says (a tracked
        frame passes its previous frame's verdict, ``FitResult.dim``, for free). ``still``: a still's fit
        (``Tracker.fit_still``), which for a dim face takes the model's cascade for those (``Model.dim_cascade``,
        learned from detections' fits; ``TrainConfig.dim_cascade``: not in video, where it measured worse)."""
        if self.model.landmark_cascade is None:
            return res
        if r is None:
            r = self.factors(res.p)[-1]
        img = levels.resampled(r)
        lc = self.model.cascade_for(img, r, res.landmarks)
        first = max(0, lc.n_stages - last) if last > 0 else 0
        by_dim = still and first == 0 and self.model.dim_cascade is not None
        if (lc.repeats or by_dim) and dim is None:
            dim = self.model.dim(img, r, res.landmarks)
        repeats = 0 if dim else lc.repeats
        soft = lc is self.model.soft_cascade
        if by_dim and dim:
            lc = self.model.dim_cascade
        view, gain = descriptor_view(img, r, res.landmarks) if self.adaptive_view else (img, 1.0)
        pts, z, prior = lc.run(view, r, res.landmarks, first, repeats, gain, blank=levels.edge)
        if view is not img:  # the validators learned faces as they are (``descriptor_view``); a face noisy enough
            # to be smoothed is past the gain's noise cap: its gain as it is is 1
            z = lc.read(img, r, pts, blank=levels.edge)
        lv = self.model.validator_for(img, r, pts, soft=soft)
        conf = res.confidence if lv is None else lv(res.stats, z)
        return replace(res, landmarks=pts, confidence=conf, landmark_prior=prior,
                       dim=lv is not None and lv is self.model.dim_validator,
                       soft=soft)

    def project(self, p: np.ndarray) -> np.ndarray:
        """(n_vertices, 2) image pixels of the search vector p."""
        return project(self.shape3d, self.basis, p, np.empty((self.model.shape.n_vertices, 2)))

    def statistics(self, levels: Levels, p: np.ndarray, r: float | None = None) -> tuple:
        """The fit statistics the validator reads (``model.STAT_NAMES``), on the finest couple at p: RMS projected
        residual, correlation of the texture with the mean texture, mean texture magnitude, and the size of the
        pose update the couple would still make (log10 of 0.001 + face widths + radians + log-scale: a fit the
        cascade would move no further has about -3)."""
        k = len(self.model.couples) - 1
        c = self.model.couples[k]
        t = self.model.textures[c.texture]
        r = level_factor(p[3] * self.width, c.face_px) if r is None else r
        verts, tex, coef, e, _ = self._scratch[len(t.mean)]
        m = t.appearance.shape[1]
        err = residual(levels.get(r), r, level_shift(r), self.shape3d, self.basis, p, t.mean, t.appearance,
                       t.frame.pix_vid, t.frame.pix_bary, self.mode, verts, tex, coef[:m], e, fill=levels.edge)
        tn = float(np.linalg.norm(tex))
        corr = float(np.dot(tex, t.mean) / (tn * self._mean_norm[c.texture])) if tn > 1e-9 else 0.0
        energy = tn / math.sqrt(len(tex))
        upd = (self._stat_update @ e + self._stat_bias).tolist()
        pose_update = 0.0
        for u, unit in zip(upd, self._stat_unit, strict=True):  # radians and log-scale; translation in face widths
            pose_update += abs(u) if unit == 1.0 else abs(u) / unit
        return (float(math.sqrt(err)), corr, energy, math.log10(pose_update + 1e-3))
