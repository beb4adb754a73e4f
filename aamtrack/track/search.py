"""Multi-resolution active search on one image (poster, "Multi-Resolution Active Model Search"): for each
couple, coarse to fine, warp, residual, delta = U e, p <- p + delta with step control, until convergence.
The loop of each couple runs in compiled code (``aamtrack._kernels.warp._search``)."""

from __future__ import annotations

import numpy as np

from .._kernels.warp import _residual, _search
from ..model import Model
from .pyramid import Levels, level_factor, level_offset, to_gray32
from .result import FitResult

MAX_ITER = 30
TOL = 1e-3
DELTA_TOL = 0.002  # an update below this (face widths, radians, log-scale; x5 in prior spreads) is convergence
N_STEPS = 4  # step sizes tried per iteration: 1, 1/2, 1/4, 1/8 (2 was tried: cap12 3D NME 0.048 -> 0.074)


class Searcher:
    """Holds a model's arrays in the layout the kernels take. Stateless between calls."""

    def __init__(self, model: Model):
        self.model = model
        sm = model.shape
        self.lo, self.hi = sm.bounds()
        self.basis = np.ascontiguousarray(sm.basis)
        self.width = sm.frontal_width()
        self.lcn_sigma = float(model.config.get("lcn_sigma", 0.0))
        self.delta_tol = {id(c): self._delta_tol(c.free) for c in model.couples + ((model.person,) if model.person
                                                                                   else ())}
        if model.person is not None:
            self.person_basis, _, self.person_lo, self.person_hi = sm.person_view()

    def _delta_tol(self, free: np.ndarray, tol: float = DELTA_TOL) -> np.ndarray:
        """(n_free,) update sizes that count as converged: tol radians / log-scale, tol face widths of
        translation (model units), 5 tol prior spreads of a coefficient."""
        sm = self.model.shape
        out = np.empty(len(free))
        for a, j in enumerate(free):
            if j <= 3:
                out[a] = tol
            elif j <= 5:
                out[a] = tol * sm.frontal_width()
            elif j < sm.n_q:
                out[a] = 5 * tol * (1.0 if sm.kind == "2d" else 0.5 * (sm.coef_hi[j - 6] - sm.coef_lo[j - 6]))
            else:
                out[a] = 5 * tol * sm.shape_sd[j - sm.n_q]
        return out

    def levels(self, image: np.ndarray) -> Levels:
        """The resampled images of a frame (H, W[, 3]) for the couples, built on demand."""
        return Levels(to_gray32(image), self.lcn_sigma)

    def factors(self, q: np.ndarray) -> list[float]:
        """Each couple's resampling factor for the face size of q (``pyramid.level_factor``)."""
        return [level_factor(q[3] * self.width, c.face_px) for c in self.model.couples]

    def _run(self, img, r, shape3d, basis, q, c, lo, hi, max_iter, tol, n_steps):
        t = self.model.textures[c.texture]
        d = level_offset(r)
        q[4] += d
        q[5] += d
        n_it, err = _search(img, r, shape3d, basis, q, c.free, lo, hi, c.U, c.prior_step, c.prior, t.mean,
                            t.appearance, t.frame.pix_vid, t.frame.pix_bary, max_iter, tol, n_steps,
                            self.delta_tol[id(c)])
        q[4] -= d
        q[5] -= d
        return n_it, err

    def fit(self, image_or_levels, q0: np.ndarray, shape_params: np.ndarray | None = None, *,
            max_iter: int = MAX_ITER, tol: float = TOL, factors: list[float] | None = None,
            first: int = 0, n_steps: int = N_STEPS) -> FitResult:
        """Search from q0 (n_q,) on an image (H, W[, 3]) or its ``levels``, couples ``first``..last, each at
        the resampling ``factors[k]`` (default: from q0's face size)."""
        lv = image_or_levels if isinstance(image_or_levels, Levels) else self.levels(image_or_levels)
        sm = self.model.shape
        shape3d = np.ascontiguousarray(sm.neutral(shape_params))
        q = np.array(q0, dtype=np.float64)
        factors = self.factors(q) if factors is None else factors
        iters, errs = [], []
        for k, c in enumerate(self.model.couples):
            if k < first:
                continue
            n_it, err = self._run(lv.get(factors[k]), factors[k], shape3d, self.basis, q, c, self.lo, self.hi,
                                  max_iter, tol, n_steps)
            iters.append(int(n_it))
            errs.append(float(np.sqrt(err)))
        verts = sm.project(q, shape_params)
        return FitResult(p=q, landmarks=sm.landmark_map @ verts, vertices=verts,
                         residual=errs[-1] if errs else float("nan"), iterations=tuple(iters), errors=tuple(errs))

    def fit_person(self, levels: Levels, q: np.ndarray, shape_params: np.ndarray | None = None, *,
                   max_iter: int = MAX_ITER, tol: float = TOL, n_steps: int = N_STEPS,
                   factor: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Search pose, coefficients and the shape units together (the model's person couple), from q and
        shape_params. Returns (q, shape_params, RMS residual)."""
        c = self.model.person
        if c is None:
            raise ValueError("this model has no person couple (2D models have no shape units)")
        sm = self.model.shape
        sigma = np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float)
        q_ext = np.r_[np.asarray(q, float), sigma]
        r = level_factor(q_ext[3] * self.width, c.face_px) if factor is None else factor
        _, err = self._run(levels.get(r), r, np.ascontiguousarray(sm.mean), self.person_basis, q_ext, c,
                           self.person_lo, self.person_hi, max_iter, tol, n_steps)
        return q_ext[: sm.n_q], q_ext[sm.n_q:], float(np.sqrt(err))

    def residual(self, levels: Levels, q: np.ndarray, shape_params=None, couple: int = -1) -> float:
        """RMS projected residual of q on one couple (default the finest)."""
        c = self.model.couples[couple]
        t = self.model.textures[c.texture]
        r = level_factor(q[3] * self.width, c.face_px)
        qd = np.array(q, np.float64)
        qd[4:6] += level_offset(r)
        sm = self.model.shape
        N = t.frame.n_pixels
        err = _residual(levels.get(r), r, np.ascontiguousarray(sm.neutral(shape_params)), self.basis, qd,
                        t.mean, t.appearance, t.frame.pix_vid, t.frame.pix_bary, np.empty((sm.n_vertices, 2)),
                        np.empty(N, np.float32), np.empty(t.appearance.shape[1]), np.empty(N))
        return float(np.sqrt(err))
