"""Compiled residuals and Jacobian of the landmark fit (``aamtrack.mesh.landmark_fit``: the model's 68 landmarks
under a weak-perspective pose fitted to 2D points), one damped Gauss-Newton step of it (the tracker's start of a
tracked frame, ``_gauss_newton_step``) and its bounded minimum (shape learning, ``_solve_lm``). One implementation
serves both: the numpy version it replaced cost 0.12 ms a step in Python overhead on arrays of 68 points.
``scipy.optimize.least_squares`` (trust-region reflective, on ``LandmarkFitter.problem``), which shape learning
called until 2026-12-02, is the tests' reference for ``_solve_lm``: on helen_train's points (the first 300, three
starts each, /tmp harness) the compiled fit's cost was never above scipy's by more than 3e-14 of it (below by up to
1e-8: scipy stops earlier) and took 0.39 ms a fit against 4.9 ms; ``train.pipeline.learn_shape`` for the 3D model
(1,740 photos and mirrors, one core) 6 s, where it had taken 62 s.

Unknowns x = [free pose entries (angles in radians, the scale as its log, translation in pixels), coefficients,
sigma if fitted]; residuals [(u - px) / w, (v - py) / w, sqrt(lam_c) coef, sqrt(lam_s) sigma / sd (if fitted)]
with u = s (R X)_x + tx, v = -s (R X)_y + ty, X = LM + sum sigma_k LS_k + sum coef_c LA_c, R = Rz Ry Rx.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT
from .warp import _rotation


@numba.njit(**NJIT)
def _landmark_rj(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s, shape_sd,
                 r, J, jacobian):
    """Residuals into r and (if ``jacobian``) d r / d x into J (zeroed here) for the unknowns x."""
    L = LM.shape[0]
    n_p = free_pose.shape[0]
    n_s = LS.shape[0]
    q = np.zeros(6)
    for a in range(n_p):
        q[free_pose[a]] = x[a]
    s = math.exp(q[3])
    sigma = np.empty(n_s)
    for k in range(n_s):
        sigma[k] = x[n_p + n_c + k] if fit_sigma else sigma_fixed[k]
    X = LM.copy()
    for k in range(n_s):
        sk = sigma[k]
        if sk != 0.0:
            for i in range(L):
                for d in range(3):
                    X[i, d] += sk * LS[k, i, d]
    for c in range(n_c):
        cc = x[n_p + c]
        if cc != 0.0:
            for i in range(L):
                for d in range(3):
                    X[i, d] += cc * LA[c, i, d]
    R = np.empty((3, 3))
    _rotation(q[0], q[1], q[2], R)
    inv_w = 1.0 / width
    for i in range(L):
        rx = R[0, 0] * X[i, 0] + R[0, 1] * X[i, 1] + R[0, 2] * X[i, 2]
        ry = R[1, 0] * X[i, 0] + R[1, 1] * X[i, 1] + R[1, 2] * X[i, 2]
        r[i] = (s * rx + q[4] - points[i, 0]) * inv_w
        r[L + i] = (-s * ry + q[5] - points[i, 1]) * inv_w
    sc = math.sqrt(lam_c)
    for c in range(n_c):
        r[2 * L + c] = sc * x[n_p + c]
    ss = math.sqrt(lam_s)
    if fit_sigma:
        for k in range(n_s):
            r[2 * L + n_c + k] = ss * sigma[k] / shape_sd[k]
    if not jacobian:
        return
    J[:, :] = 0.0
    # rows 0 and 1 of dR / d angle: dR/drx = R K(x), dR/dry = K(Rz y) R, dR/drz = K(z) R (K: cross product)
    cz, sz = math.cos(q[2]), math.sin(q[2])
    dR = np.empty((3, 2, 3))
    for i in range(2):
        dR[0, i, 0] = 0.0
        dR[0, i, 1] = R[i, 2]
        dR[0, i, 2] = -R[i, 1]
    for d in range(3):
        dR[1, 0, d] = cz * R[2, d]
        dR[1, 1, d] = sz * R[2, d]
        dR[2, 0, d] = -R[1, d]
        dR[2, 1, d] = R[0, d]
    f = s * inv_w
    for a in range(n_p):
        j = free_pose[a]
        for i in range(L):
            if j < 3:
                J[i, a] = f * (dR[j, 0, 0] * X[i, 0] + dR[j, 0, 1] * X[i, 1] + dR[j, 0, 2] * X[i, 2])
                J[L + i, a] = -f * (dR[j, 1, 0] * X[i, 0] + dR[j, 1, 1] * X[i, 1] + dR[j, 1, 2] * X[i, 2])
            elif j == 3:
                J[i, a] = f * (R[0, 0] * X[i, 0] + R[0, 1] * X[i, 1] + R[0, 2] * X[i, 2])
                J[L + i, a] = -f * (R[1, 0] * X[i, 0] + R[1, 1] * X[i, 1] + R[1, 2] * X[i, 2])
            elif j == 4:
                J[i, a] = inv_w
            else:
                J[L + i, a] = inv_w
    for c in range(n_c):
        for i in range(L):
            J[i, n_p + c] = f * (R[0, 0] * LA[c, i, 0] + R[0, 1] * LA[c, i, 1] + R[0, 2] * LA[c, i, 2])
            J[L + i, n_p + c] = -f * (R[1, 0] * LA[c, i, 0] + R[1, 1] * LA[c, i, 1] + R[1, 2] * LA[c, i, 2])
        J[2 * L + c, n_p + c] = sc
    if fit_sigma:
        for k in range(n_s):
            for i in range(L):
                J[i, n_p + n_c + k] = f * (R[0, 0] * LS[k, i, 0] + R[0, 1] * LS[k, i, 1] + R[0, 2] * LS[k, i, 2])
                J[L + i, n_p + n_c + k] = -f * (R[1, 0] * LS[k, i, 0] + R[1, 1] * LS[k, i, 1]
                                                 + R[1, 2] * LS[k, i, 2])
            J[2 * L + n_c + k, n_p + n_c + k] = ss / shape_sd[k]


@numba.njit(**NJIT)
def _gauss_newton_step(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s, shape_sd,
                       damping, lo, hi):
    """x (in place) <- one damped Gauss-Newton step of the fit, sigma fitted too (the last entries of x, with its
    prior) if ``fit_sigma``, else held at ``sigma_fixed``: solve (J^T J + damping diag(J^T J)) d = J^T r, x - d
    clipped to [lo, hi]."""
    L = LM.shape[0]
    n = x.shape[0]
    n_r = 2 * L + n_c + (LS.shape[0] if fit_sigma else 0)
    r = np.empty(n_r)
    J = np.empty((n_r, n))
    _landmark_rj(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s, shape_sd, r, J,
                 True)
    A = J.T @ J
    g = J.T @ r
    for i in range(n):
        A[i, i] = A[i, i] * (1.0 + damping) + 1e-12
    d = np.linalg.solve(A, g)
    for i in range(n):
        v = x[i] - d[i]
        x[i] = min(max(v, lo[i]), hi[i])


@numba.njit(**NJIT)
def _half_square(r):
    """0.5 |r|^2."""
    c = 0.0
    for i in range(r.shape[0]):
        c += r[i] * r[i]
    return 0.5 * c


@numba.njit(**NJIT)
def _solve_lm(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s, shape_sd, lo, hi,
              max_iter, ftol, xtol, gtol):
    """x (in place) <- the minimum of the landmark fit's 0.5 |r|^2 within [lo, hi], from x (clipped into them), by
    Levenberg-Marquardt (Marquardt's scaling: (J^T J + mu diag(J^T J)) d = -J^T r; mu shrunk after a step that
    lowers the cost by Nielsen's rule, raised otherwise). Bounds by projection: the unknowns at a bound whose
    gradient pushes outwards are held there for the step (the others solved for), and the step is clipped.
    Stops when a step lowers the cost by less than ``ftol`` of it, moves x by less than ``xtol`` (|x| + xtol),
    the largest projected gradient entry is under ``gtol``, or after ``max_iter`` steps tried. Returns
    (0.5 |r|^2 at x, steps tried)."""
    L = LM.shape[0]
    n = x.shape[0]
    n_r = 2 * L + n_c + (LS.shape[0] if fit_sigma else 0)
    r = np.empty(n_r)
    r_try = np.empty(n_r)
    J = np.empty((n_r, n))
    x_try = np.empty(n)
    idx = np.empty(n, np.int64)  # the unknowns solved for in a step (its first m entries)
    for i in range(n):
        x[i] = min(max(x[i], lo[i]), hi[i])
    _landmark_rj(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s, shape_sd, r, J,
                 True)
    cost = _half_square(r)
    A = J.T @ J
    g = J.T @ r
    mu = -1.0
    nu = 2.0
    tried = 0
    while tried < max_iter:
        m = 0
        pg = 0.0
        for i in range(n):  # held: at a bound, the descent direction -g pointing out of it
            if not ((x[i] <= lo[i] and g[i] > 0.0) or (x[i] >= hi[i] and g[i] < 0.0)):
                idx[m] = i
                m += 1
                pg = max(pg, abs(g[i]))
        if m == 0 or pg < gtol:
            break
        if mu < 0.0:  # the first damping: 1e-3 of each diagonal entry
            mu = 1e-3
        Af = np.empty((m, m))
        gf = np.empty(m)
        moved = False
        while tried < max_iter:
            tried += 1
            for a in range(m):
                gf[a] = -g[idx[a]]
                for b in range(m):
                    Af[a, b] = A[idx[a], idx[b]]
                Af[a, a] = A[idx[a], idx[a]] * (1.0 + mu) + 1e-12
            d = np.linalg.solve(Af, gf)
            for i in range(n):
                x_try[i] = x[i]
            for a in range(m):
                i = idx[a]
                x_try[i] = min(max(x[i] + d[a], lo[i]), hi[i])
            _landmark_rj(x_try, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s,
                         shape_sd, r_try, J, False)
            c_try = _half_square(r_try)
            if c_try < cost:
                # the model's predicted fall for the step taken (its clipped form): -g.s - 0.5 s^T A s
                pred = 0.0
                ss = 0.0
                xx = 0.0
                for i in range(n):
                    si = x_try[i] - x[i]
                    pred -= g[i] * si
                    ss += si * si
                    xx += x[i] * x[i]
                    for j in range(n):
                        pred -= 0.5 * si * A[i, j] * (x_try[j] - x[j])
                rho = (cost - c_try) / pred if pred > 0.0 else 1.0
                fall = cost - c_try
                for i in range(n):
                    x[i] = x_try[i]
                cost = c_try
                _landmark_rj(x, free_pose, n_c, fit_sigma, sigma_fixed, LM, LS, LA, points, width, lam_c, lam_s,
                             shape_sd, r, J, True)
                A = J.T @ J
                g = J.T @ r
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                moved = True
                if fall <= ftol * cost or math.sqrt(ss) <= xtol * (xtol + math.sqrt(xx)):
                    return cost, tried
                break
            mu *= nu
            nu *= 2.0
            if mu > 1e16:
                return cost, tried
        if not moved:
            break
    return cost, tried
