"""The compiled landmark fit (residuals, Jacobian, Gauss-Newton step) against the numpy version it replaced, and
its Jacobian against finite differences."""

import numpy as np
import pytest

from aamtrack.mesh.landmark_fit import LAMBDA_COEF, LAMBDA_SHAPE, SIGMA_BOUND_SD, LandmarkFitter, free_pose, unpack
from aamtrack.mesh.shape_model import N_POSE, rotation_matrix


def _cross(x, y, z):
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def reference_problem(sm, points, pose, fit_sigma, sigma_fixed):
    """The numpy residuals and analytic Jacobian (as shape learning had them until 2026-11-22)."""
    width = float(np.ptp(points[:, 0]) + 1e-9)
    LM = sm.landmark_map @ sm.mean
    LS = np.einsum("lv,kvd->kld", sm.landmark_map, sm.shape_units)
    LA = np.einsum("lv,kvd->kld", sm.landmark_map, sm.basis)
    n_p, n_c = len(pose), sm.n_coef

    def rot(q):
        R = rotation_matrix(*q[:3])
        cz, sz = np.cos(q[2]), np.sin(q[2])
        return R, {0: R @ _cross(1.0, 0.0, 0.0), 1: _cross(-sz, cz, 0.0) @ R, 2: _cross(0.0, 0.0, 1.0) @ R}

    def shape(q, sigma):
        return LM + np.tensordot(sigma, LS, axes=1) + np.tensordot(q[N_POSE:], LA, axes=1)

    def residuals(x):
        q, sigma = unpack(x, sm, pose, fit_sigma, sigma_fixed)
        R, _ = rot(q)
        X = shape(q, sigma)
        u = q[3] * X @ R[0] + q[4]
        v = -q[3] * X @ R[1] + q[5]
        res = [(u - points[:, 0]) / width, (v - points[:, 1]) / width, np.sqrt(LAMBDA_COEF) * q[N_POSE:]]
        if fit_sigma:
            res.append(np.sqrt(LAMBDA_SHAPE) * sigma / sm.shape_sd)
        return np.concatenate(res)

    def jacobian(x):
        q, sigma = unpack(x, sm, pose, fit_sigma, sigma_fixed)
        R, dR = rot(q)
        X = shape(q, sigma)
        s = q[3] / width
        n = len(points)
        J = np.zeros((2 * n + n_c + (sm.n_shape if fit_sigma else 0), len(x)))
        for a, j in enumerate(pose):
            if j < 3:
                J[:n, a], J[n:2 * n, a] = s * X @ dR[j][0], -s * X @ dR[j][1]
            elif j == 3:
                J[:n, a], J[n:2 * n, a] = s * X @ R[0], -s * X @ R[1]
            else:
                J[(j - 4) * n:(j - 3) * n, a] = 1.0 / width
        for B, c0 in [(LA, n_p)] + ([(LS, n_p + n_c)] if fit_sigma else []):
            J[:n, c0:c0 + len(B)] = s * (B @ R[0]).T
            J[n:2 * n, c0:c0 + len(B)] = -s * (B @ R[1]).T
        J[2 * n:2 * n + n_c, n_p:n_p + n_c] = np.sqrt(LAMBDA_COEF) * np.eye(n_c)
        if fit_sigma:
            J[2 * n + n_c:, n_p + n_c:] = np.diag(np.sqrt(LAMBDA_SHAPE) / sm.shape_sd)
        return J

    return residuals, jacobian


def _case(sm, rng, fit_sigma):
    pose = free_pose(sm)
    x = np.r_[rng.normal(0, 0.2, len(pose)), 0.2 * rng.normal(size=sm.n_coef)]
    x[pose.index(3)] = np.log(120.0)
    x[pose.index(4)], x[pose.index(5)] = 160.0, 120.0
    if fit_sigma:
        x = np.r_[x, 0.5 * sm.shape_sd * rng.normal(size=sm.n_shape)]
    points = rng.uniform(60, 260, (68, 2))
    sigma = 0.3 * sm.shape_sd * rng.normal(size=sm.n_shape)
    return pose, x, points, sigma


@pytest.mark.parametrize("kind,fit_sigma", [("2d", False), ("3d", False), ("3d", True)])
def test_compiled_fit_matches_the_numpy_reference(kind, fit_sigma, synth_model, synth_model3d):
    sm = (synth_model if kind == "2d" else synth_model3d[0]).shape
    rng = np.random.default_rng(21)
    for _ in range(3):
        pose, x, points, sigma = _case(sm, rng, fit_sigma and sm.n_shape > 0)
        res_c, jac_c = LandmarkFitter(sm).problem(points, pose, fit_sigma, sigma)
        res_n, jac_n = reference_problem(sm, points, pose, fit_sigma, sigma)
        assert np.abs(res_c(x) - res_n(x)).max() < 1e-12  # the same sums, reordered at most
        assert np.abs(jac_c(x) - jac_n(x)).max() < 1e-12
        # and the Jacobian is the residuals' derivative (central differences, step 1e-6)
        J = jac_c(x)
        for a in range(len(x)):
            h = np.zeros_like(x)
            h[a] = 1e-6
            fd = (res_c(x + h) - res_c(x - h)) / 2e-6
            assert np.abs(fd - J[:, a]).max() < 1e-6 * max(1.0, np.abs(J[:, a]).max())


def numpy_step(sm, points, pose, x, sigma, fit_sigma, damping=1e-3):
    """One damped Gauss-Newton step in numpy: (J^T J + damping diag) d = J^T r, x - d clipped to the
    coefficients' bounds (and +-``SIGMA_BOUND_SD`` sd for the shape units when fitted); (q, sigma) after it."""
    res_n, jac_n = reference_problem(sm, points, pose, fit_sigma, sigma)
    J = jac_n(x)
    A = J.T @ J
    A[np.diag_indices_from(A)] *= 1.0 + damping
    A[np.diag_indices_from(A)] += 1e-12
    lo_q, hi_q = sm.bounds()
    lo = np.r_[np.full(len(pose), -np.inf), lo_q[N_POSE:], -SIGMA_BOUND_SD * sm.shape_sd if fit_sigma else []]
    hi = np.r_[np.full(len(pose), np.inf), hi_q[N_POSE:], SIGMA_BOUND_SD * sm.shape_sd if fit_sigma else []]
    return unpack(np.clip(x - np.linalg.solve(A, J.T @ res_n(x)), lo, hi), sm, pose, fit_sigma, sigma)


@pytest.mark.parametrize("kind", ["2d", "3d"])
def test_compiled_step_is_the_numpy_gauss_newton_step(kind, synth_model, synth_model3d):
    """``LandmarkFitter.refit``: one step equals (J^T J + damping diag) d = J^T r solved in numpy, clipped to the
    coefficients' bounds, the shape units untouched."""
    sm = (synth_model if kind == "2d" else synth_model3d[0]).shape
    rng = np.random.default_rng(4)
    pose, x, points, sigma = _case(sm, rng, False)
    q, _ = unpack(x, sm, pose, False, sigma)
    got = LandmarkFitter(sm).refit(np.r_[q, sigma], points, damping=1e-3)
    want, _ = numpy_step(sm, points, pose, x, sigma, False)
    assert np.abs(got[:sm.n_q] - want).max() < 1e-9
    assert np.array_equal(got[sm.n_q:], sigma)


def test_compiled_step_fits_the_shape_units_too(synth_model3d):
    """``LandmarkFitter.refit(fit_sigma=True)``: one step equals the numpy step of the fit with the shape units
    among the unknowns (their prior rows included), clipped to the coefficients' bounds and +-3 sd."""
    sm = synth_model3d[0].shape
    rng = np.random.default_rng(5)
    pose, x, points, sigma = _case(sm, rng, True)
    q, s0 = unpack(x, sm, pose, True, sigma)
    got = LandmarkFitter(sm).refit(np.r_[q, s0], points, damping=1e-3, fit_sigma=True)
    want_q, want_sigma = numpy_step(sm, points, pose, x, sigma, True)
    assert np.abs(got[:sm.n_q] - want_q).max() < 1e-9
    assert np.abs(got[sm.n_q:] - want_sigma).max() < 1e-9


def test_three_steps_reach_the_least_squares_shape_fit(synth_model3d):
    """From near the answer (the tracker's case: the search's fit of the same frame), three steps with the shape
    units free reach scipy's least-squares fit (``train.shape_fit.fit_landmarks``) of noisy points of a known
    face: the same pose to 0.01 degrees and coefficients and shape units to 1e-3 (relative to their scales;
    scipy stops at its own tolerance, about 0.002 degrees here), at a cost no higher than scipy's."""
    from aamtrack.train.shape_fit import fit_landmarks

    sm = synth_model3d[0].shape
    rng = np.random.default_rng(6)
    fitter = LandmarkFitter(sm)
    for _ in range(3):
        q = np.zeros(sm.n_q)
        q[:3] = rng.normal(0, 0.15, 3)
        q[3], q[4:6] = 150.0 / sm.frontal_width(), (200.0, 180.0)
        q[N_POSE:] = rng.uniform(0.0, 0.3, sm.n_coef)
        sigma = rng.normal(0, 1, sm.n_shape) * sm.shape_sd
        points = sm.landmarks(q, sigma) + rng.normal(0, 1.0, (68, 2))  # 1 px of noise on a face 150 px wide
        want = fit_landmarks(sm, points, shape_params=np.zeros(sm.n_shape), q0=q)
        start = np.r_[q, np.zeros(sm.n_shape)]
        start[:3] += np.radians([2.0, -2.0, 1.0])
        start[4:6] += (1.0, -1.0)
        got = fitter.refit(start, points, 3, fit_sigma=True)
        assert np.degrees(np.abs(got[:3] - want.q[:3])).max() < 0.01  # degrees
        assert np.abs(got[3:6] - want.q[3:6]).max() < 1e-3 * max(1.0, abs(want.q[3]))
        assert np.abs(got[N_POSE:sm.n_q] - want.q[N_POSE:]).max() < 1e-3
        assert np.abs((got[sm.n_q:] - want.shape_params) / sm.shape_sd).max() < 1e-3
        residuals, _ = fitter.problem(points, free_pose(sm), True, np.zeros(sm.n_shape))
        cost = [float(np.sum(residuals(_unknowns(sm, q_, s_)) ** 2))
                for q_, s_ in ((got[:sm.n_q], got[sm.n_q:]), (want.q, want.shape_params))]
        assert cost[0] <= cost[1] * (1 + 1e-6)  # as low as scipy's


def _unknowns(sm, q, sigma):
    """The fit's x for (q, sigma) with the shape units free (``unpack``'s inverse)."""
    pose = free_pose(sm)
    x = np.r_[q[pose], q[N_POSE:], sigma]
    x[pose.index(3)] = np.log(q[3])
    return x
