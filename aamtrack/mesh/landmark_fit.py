"""The model's 68 landmarks as a function of the search vector, fitted to 2D points: the least-squares problem
of shape learning (``aamtrack.train.shape_fit``, poster step 1)

    min  sum_i |P(q) L (M + S sigma + A alpha)_i - u_i|^2 / w^2  +  lam_s |sigma / sd|^2  +  lam_c |alpha|^2

with w the face width in pixels (so the weights do not depend on image size) and P the weak-perspective pose,
and the tracker's use of it: one Gauss-Newton step from the previous fit to the previous frame's final landmarks
(``LandmarkFitter.refit``), where a tracked frame's search starts.
"""

from __future__ import annotations

import numpy as np

from ..kernels import landmark_gauss_newton_step, landmark_residuals_jacobian, landmark_solve
from .shape_model import N_POSE, ShapeModel

LAMBDA_SHAPE = 1e-3
LAMBDA_COEF = 1e-4
SIGMA_BOUND_SD = 3.0  # fitted shape units stay within this many of their standard deviations


def free_pose(sm: ShapeModel) -> list:
    """The pose entries of q a landmark fit moves: all six for 3D, roll, scale and translation for 2D."""
    return [0, 1, 2, 3, 4, 5] if sm.kind == "3d" else [2, 3, 4, 5]


def unpack(x, sm: ShapeModel, free_pose, fit_sigma, sigma_fixed):
    """(q, sigma) from the fit's unknowns x = [free pose (log-scale for the scale), coefficients, sigma if
    ``fit_sigma``; else ``sigma_fixed``]."""
    q = np.zeros(sm.n_q)
    n_p = len(free_pose)
    q[free_pose] = x[:n_p]
    q[3] = np.exp(q[3])
    q[N_POSE:] = x[n_p:n_p + sm.n_coef]
    sigma = x[n_p + sm.n_coef:] if fit_sigma else sigma_fixed
    return q, sigma


class LandmarkFitter:
    """A shape model's landmarks in the form the fit needs, computed once: L M, L S and L A (the landmark map
    applied to the mean, the shape units and the animation units or PCA modes)."""

    def __init__(self, sm: ShapeModel, points=None):
        """``points``: the landmarks (indices into the 68) the fit uses (default all); ``refit`` still takes all 68
        points and picks these."""
        self.sm = sm
        self.LM, self.LS, self.LA = sm.landmark_arrays
        self._use = None
        if points is not None:
            self._use = np.asarray(points, np.int64)
            self.LM = np.ascontiguousarray(self.LM[self._use])
            self.LS = np.ascontiguousarray(self.LS[:, self._use])
            self.LA = np.ascontiguousarray(self.LA[:, self._use])
        lo_q, hi_q = sm.bounds()
        pose = free_pose(sm)
        self._lo = np.r_[np.full(len(pose), -np.inf), lo_q[N_POSE:]]
        self._hi = np.r_[np.full(len(pose), np.inf), hi_q[N_POSE:]]
        self._free = np.array(pose, np.int64)
        self._scale_at = pose.index(3)  # where the log-scale sits in the fit's unknowns
        self._sd = np.ascontiguousarray(sm.shape_sd, float) if sm.n_shape else np.ones(0)
        self._lo_sigma = np.r_[self._lo, -SIGMA_BOUND_SD * self._sd]  # the bounds with the shape units fitted too
        self._hi_sigma = np.r_[self._hi, SIGMA_BOUND_SD * self._sd]

    def bounds(self, fit_sigma: bool) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the fit's unknowns (``unpack``'s layout): the pose free (the scale as its log), the
        coefficients within the model's bounds, the shape units (if ``fit_sigma``) within ``SIGMA_BOUND_SD``."""
        return (self._lo_sigma, self._hi_sigma) if fit_sigma else (self._lo, self._hi)

    def refit(self, p: np.ndarray, points: np.ndarray, iterations: int = 1, damping: float = 1e-3, *,
              fit_sigma: bool = False) -> np.ndarray:
        """The search vector p = [q, sigma] with its pose and coefficients moved by ``iterations`` damped
        Gauss-Newton steps (Levenberg's diagonal, ``damping``) of the landmark fit to points (68, 2), sigma held
        (or, with ``fit_sigma``, fitted too, within ``SIGMA_BOUND_SD``, with its prior ``LAMBDA_SHAPE``), the
        coefficients kept in their bounds (compiled: ``kernels.landmark_gauss_newton_step``). One step from
        the previous frame's fit is what the tracker takes (``TrackerConfig.tracked_start``): close to the fit's
        minimum already, and about 0.02 ms."""
        sm = self.sm
        n_q, pose = sm.n_q, self._free
        fit_sigma = fit_sigma and sm.n_shape > 0
        p = np.asarray(p, float)
        sigma = np.ascontiguousarray(p[n_q:])
        points, width = self._points(points)
        x = np.concatenate((p[pose], p[N_POSE:n_q]))  # [free pose, coefficients]: ``unpack``'s layout
        lo, hi = self.bounds(fit_sigma)
        if fit_sigma:
            x = np.concatenate((x, sigma))
        i_scale = self._scale_at
        x[i_scale] = np.log(max(float(p[3]), 1e-12))
        for _ in range(iterations):
            landmark_gauss_newton_step(x, pose, sm.n_coef, sigma, self.LM, self.LS, self.LA, points,
                                       width, LAMBDA_COEF, damping, lo, hi, fit_sigma=fit_sigma,
                                       lam_s=LAMBDA_SHAPE, shape_sd=self._sd)
        out = p.copy()  # as ``unpack`` then copying its pose and coefficients into p, in fewer numpy calls
        out[pose] = x[:len(pose)]
        out[3] = np.exp(x[i_scale])
        out[N_POSE:n_q] = x[len(pose):len(pose) + sm.n_coef]
        if fit_sigma:
            out[n_q:] = x[len(pose) + sm.n_coef:]
        return out

    def solve(self, points: np.ndarray, x0: np.ndarray, fit_sigma: bool,
              sigma_fixed: np.ndarray) -> tuple[np.ndarray, float]:
        """The minimum of ``problem``'s least squares (all the model's free pose entries, ``free_pose``) within
        ``bounds``, from x0 (clipped into them), in one compiled call (``kernels.landmark_solve``: bounded
        Levenberg-Marquardt, run until a step changes the cost by under 1e-12 of it). Returns (x, 0.5 |r|^2
        there)."""
        points, width = self._points(points)
        x = np.array(x0, dtype=np.float64)
        cost, _ = landmark_solve(x, self._free, self.sm.n_coef, fit_sigma, np.asarray(sigma_fixed, float), self.LM,
                                 self.LS, self.LA, points, width, LAMBDA_COEF, LAMBDA_SHAPE, self._sd,
                                 *self.bounds(fit_sigma))
        return x, cost

    def _points(self, points: np.ndarray) -> tuple[np.ndarray, float]:
        """(the fit's points of (68, 2) points, their width in pixels: the residuals' unit)."""
        points = np.asarray(points, float)
        if self._use is not None:
            points = np.ascontiguousarray(points[self._use])
        xs = points[:, 0]
        return points, float(xs.max() - xs.min()) + 1e-9

    def problem(self, points: np.ndarray, free_pose: list, fit_sigma: bool, sigma_fixed: np.ndarray):
        """(residuals(x), jacobian(x)) of the fit of x = [free pose entries ``free_pose`` (log-scale for the
        scale), coefficients, sigma if ``fit_sigma``] to (68, 2) points (module docstring), both from the compiled
        ``kernels.landmark_residuals_jacobian``: what ``scipy.optimize.least_squares`` takes (the tests'
        reference for ``solve``)."""
        sm = self.sm
        points, width = self._points(points)
        pose = np.asarray(free_pose, np.int64)
        sigma_fixed = np.asarray(sigma_fixed, float)
        n_x = len(pose) + sm.n_coef + (sm.n_shape if fit_sigma else 0)
        n_r = 2 * len(points) + sm.n_coef + (sm.n_shape if fit_sigma else 0)
        sd = self._sd  # (n_shape,), empty for 2D

        def run(x, jacobian):
            r, J = np.empty(n_r), np.empty((n_r, n_x) if jacobian else (0, 0))
            landmark_residuals_jacobian(x, pose, sm.n_coef, fit_sigma, sigma_fixed, self.LM, self.LS, self.LA,
                                        points, width, LAMBDA_COEF, LAMBDA_SHAPE, sd, r, J, jacobian=jacobian)
            return r, J

        def residuals(x):
            return run(x, False)[0]

        def jacobian(x):
            """d residuals / dx, analytic."""
            return run(x, True)[1]

        return residuals, jacobian
