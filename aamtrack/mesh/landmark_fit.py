"""The model's 68 landmarks as a function of the search vector, fitted to 2D points: the least-squares problem
of shape learning (``aamtrack.train.shape_fit``, poster step 1)

    min  sum_i |P(q) L (M + S sigma + A alpha)_i - u_i|^2 / w^2  +  lam_s |sigma / sd|^2  +  lam_c |alpha|^2

with w the face width in pixels (so the weights do not depend on image size) and P the weak-perspective pose,
and the tracker's use of it: one Gauss-Newton step from the previous fit to the previous frame's final landmarks
(``LandmarkFitter.refit``), where a tracked frame's search starts.
"""

from __future__ import annotations

import numpy as np

from .shape_model import N_POSE, ShapeModel, rotation_matrix

LAMBDA_SHAPE = 1e-3
LAMBDA_COEF = 1e-4


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


def _cross(x: float, y: float, z: float) -> np.ndarray:
    """K(v): K(v) @ w = v x w."""
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def landmark_problem(sm: ShapeModel, points: np.ndarray, free_pose: list, fit_sigma: bool, sigma_fixed: np.ndarray):
    """(residuals(x), jacobian(x)) of the fit of x = [free pose (log-scale for the scale), coefficients, sigma if
    ``fit_sigma``] to (68, 2) points (module docstring)."""
    return LandmarkFitter(sm).problem(points, free_pose, fit_sigma, sigma_fixed)


class LandmarkFitter:
    """A shape model's landmarks in the form the fit needs, computed once: L M, L S and L A (the landmark map
    applied to the mean, the shape units and the animation units or PCA modes)."""

    def __init__(self, sm: ShapeModel):
        self.sm = sm
        self.LM = sm.landmark_map @ sm.mean
        self.LS = np.einsum("lv,kvd->kld", sm.landmark_map, sm.shape_units)
        self.LA = np.einsum("lv,kvd->kld", sm.landmark_map, sm.basis)
        lo_q, hi_q = sm.bounds()
        n_p = len(free_pose(sm))
        self._lo = np.r_[np.full(n_p, -np.inf), lo_q[N_POSE:]]
        self._hi = np.r_[np.full(n_p, np.inf), hi_q[N_POSE:]]

    def refit(self, p: np.ndarray, points: np.ndarray, iterations: int = 1, damping: float = 1e-3) -> np.ndarray:
        """The search vector p = [q, sigma] with its pose and coefficients moved by ``iterations`` damped
        Gauss-Newton steps (Levenberg's diagonal, ``damping``) of the landmark fit to points (68, 2), sigma held,
        the coefficients kept in their bounds. One step from the previous frame's fit is what the tracker takes
        (``TrackerConfig.tracked_start``): close to the fit's minimum already, and about 0.1 ms."""
        sm = self.sm
        n_q = sm.n_q
        pose = free_pose(sm)
        sigma = np.asarray(p[n_q:], float)
        residuals, jacobian = self.problem(np.asarray(points, float), pose, False, sigma)
        x = np.r_[p[pose], p[N_POSE:n_q]].astype(float)
        k = pose.index(3)
        x[k] = np.log(max(float(p[3]), 1e-12))
        for _ in range(iterations):
            J = jacobian(x)
            A = J.T @ J
            A[np.diag_indices_from(A)] *= 1.0 + damping
            A[np.diag_indices_from(A)] += 1e-12
            x = np.clip(x - np.linalg.solve(A, J.T @ residuals(x)), self._lo, self._hi)
        q, _ = unpack(x, sm, pose, False, sigma)
        out = np.array(p, float)
        out[pose] = q[pose]
        out[N_POSE:n_q] = q[N_POSE:]
        return out

    def problem(self, points: np.ndarray, free_pose: list, fit_sigma: bool, sigma_fixed: np.ndarray):
        """``landmark_problem`` with this model's precomputed arrays."""
        LM, LS, LA = self.LM, self.LS, self.LA
        sm = self.sm
        width = float(np.ptp(points[:, 0]) + 1e-9)
        n_p = len(free_pose)
        n_c = sm.n_coef

        def _rot(q):
            """(R, {axis: dR / d angle}) of R = Rz Ry Rx: dR/drx = R K(x), dR/dry = K(Rz y) R, dR/drz = K(z) R,
            with K(v) the cross-product matrix of v."""
            R = rotation_matrix(*q[:3])
            cz, sz = np.cos(q[2]), np.sin(q[2])
            return R, {0: R @ _cross(1.0, 0.0, 0.0), 1: _cross(-sz, cz, 0.0) @ R, 2: _cross(0.0, 0.0, 1.0) @ R}

        def _shape(q, sigma):
            return LM + np.tensordot(sigma, LS, axes=1) + np.tensordot(q[N_POSE:], LA, axes=1)

        def residuals(x):
            q, sigma = unpack(x, sm, free_pose, fit_sigma, sigma_fixed)
            R, _ = _rot(q)
            X = _shape(q, sigma)
            u = q[3] * X @ R[0] + q[4]
            v = -q[3] * X @ R[1] + q[5]
            res = [(u - points[:, 0]) / width, (v - points[:, 1]) / width, np.sqrt(LAMBDA_COEF) * q[N_POSE:]]
            if fit_sigma:
                res.append(np.sqrt(LAMBDA_SHAPE) * sigma / sm.shape_sd)
            return np.concatenate(res)

        def jacobian(x):
            """d residuals / dx, analytic (the numerical one cost a residual evaluation per unknown)."""
            q, sigma = unpack(x, sm, free_pose, fit_sigma, sigma_fixed)
            R, dR = _rot(q)
            X = _shape(q, sigma)
            s = q[3] / width
            n_lm = len(points)
            J = np.zeros((2 * n_lm + n_c + (sm.n_shape if fit_sigma else 0), len(x)))
            for a, j in enumerate(free_pose):
                if j < 3:
                    J[:n_lm, a], J[n_lm:2 * n_lm, a] = s * X @ dR[j][0], -s * X @ dR[j][1]
                elif j == 3:
                    J[:n_lm, a], J[n_lm:2 * n_lm, a] = s * X @ R[0], -s * X @ R[1]
                else:
                    J[(j - 4) * n_lm:(j - 3) * n_lm, a] = 1.0 / width
            cols = [(LA, n_p)] + ([(LS, n_p + n_c)] if fit_sigma else [])
            for B, c0 in cols:
                J[:n_lm, c0:c0 + len(B)] = s * (B @ R[0]).T
                J[n_lm:2 * n_lm, c0:c0 + len(B)] = -s * (B @ R[1]).T
            J[2 * n_lm:2 * n_lm + n_c, n_p:n_p + n_c] = np.sqrt(LAMBDA_COEF) * np.eye(n_c)
            if fit_sigma:
                J[2 * n_lm + n_c:, n_p + n_c:] = np.diag(np.sqrt(LAMBDA_SHAPE) / sm.shape_sd)
            return J

        return residuals, jacobian
