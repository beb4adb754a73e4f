"""Shape learning recovers known parameters from synthetic projections."""

import numpy as np

from aamtrack.mesh.candide import read_wfm
from aamtrack.mesh.candide_model import candide_shape_model
from aamtrack.mesh.landmarks import candide_landmark_map
from aamtrack.mesh.shape_model import ShapeModel
from aamtrack.train.shape2d import pca_shape_model
from aamtrack.train.shape_fit import fit_landmarks
from conftest import SEED, shared_path
from synth import face_layout


def synthetic_3d_model(rng) -> ShapeModel:
    mean = np.column_stack([face_layout(), 0.3 * np.cos(3 * face_layout()[:, 0])])
    return ShapeModel(kind="3d", mean=mean, shape_units=0.05 * rng.normal(size=(3, 68, 3)),
                      basis=0.05 * rng.normal(size=(2, 68, 3)), triangles=np.zeros((0, 3), np.int32),
                      landmark_map=np.eye(68), shape_names=("a", "b", "c"), coef_names=("u", "v"),
                      coef_lo=np.full(2, -1.0), coef_hi=np.full(2, 1.0), shape_sd=np.ones(3))


def test_3d_fit_recovers_projection():
    rng = np.random.default_rng(SEED)
    sm = synthetic_3d_model(rng)
    for _ in range(5):
        q = np.r_[rng.normal(0, 0.2, 3), 150 * np.exp(rng.normal(0, 0.2)), rng.uniform(100, 200, 2),
                  rng.uniform(-0.8, 0.8, 2)]
        sigma = rng.normal(0, 0.7, 3)
        pts = sm.landmarks(q, sigma)
        fit = fit_landmarks(sm, pts)
        assert fit.rms_px < 0.3  # sub-pixel (the weak priors on sigma and alpha cost a little)
        assert np.abs(fit.q[:3] - q[:3]).max() < np.radians(2.0)  # pose angles within 2 degrees


def test_2d_fit_recovers_points_within_the_model():
    rng = np.random.default_rng(SEED)
    base = face_layout() * np.array([1, -1]) * 100 + 200
    shapes = base + rng.normal(0, 2.0, (40, 68, 2))
    sm = pca_shape_model(shapes)
    q = np.zeros(sm.n_q)
    q[2:6] = 0.1, 180.0, 160.0, 150.0
    q[6:9] = 1.0, -0.5, 0.7
    pts = sm.landmarks(q)
    fit = fit_landmarks(sm, pts)
    assert fit.rms_px < 0.1  # sub-pixel: the points lie in the model's span
    assert fit.q[0] == 0 and fit.q[1] == 0  # the 2D pose is a similarity


def test_candide_fit_recovers_projection():
    c = read_wfm(shared_path("candide3", "candide3.wfm"))
    layout = face_layout() * np.array([1.0, -1.0])
    sm = candide_shape_model(c, candide_landmark_map(c.vertices, c.triangles, layout))
    rng = np.random.default_rng(SEED)
    q = np.r_[0.1, -0.25, 0.05, 120.0, 180.0, 170.0, 0.4, 0.2, 0, 0, -0.3, 0.2, 0.1]
    sigma = rng.normal(0, 0.5, sm.n_shape)
    pts = sm.landmarks(q, sigma)
    fit = fit_landmarks(sm, pts)
    assert fit.rms_px < 0.5  # sub-pixel


def test_analytic_jacobian_matches_finite_differences():
    from aamtrack.mesh.landmark_fit import LandmarkFitter

    rng = np.random.default_rng(SEED)
    sm = synthetic_3d_model(rng)
    pts = face_layout() * np.array([120.0, -120.0]) + 100 + rng.normal(0, 2, (68, 2))
    for free_pose, fit_sigma in (([0, 1, 2, 3, 4, 5], True), ([0, 1, 2, 3, 4, 5], False), ([2, 3, 4, 5], True)):
        residuals, jacobian = LandmarkFitter(sm).problem(pts, free_pose, fit_sigma, np.zeros(3))
        n = len(free_pose) + 2 + (3 if fit_sigma else 0)
        x = rng.normal(0, 0.2, n)
        x[free_pose.index(3)] = np.log(110.0)
        x[free_pose.index(4)] += 100
        x[free_pose.index(5)] += 100
        J = jacobian(x)
        h = 1e-6
        num = np.column_stack([(residuals(x + h * e) - residuals(x - h * e)) / (2 * h) for e in np.eye(n)])
        assert J.shape == num.shape
        assert np.abs(J - num).max() < 1e-6 * max(1.0, np.abs(num).max())  # central differences, O(h^2)


def test_compiled_solver_reaches_scipys_least_squares_minimum_with_bounds_active():
    """``LandmarkFitter.solve`` (compiled bounded Levenberg-Marquardt) against ``scipy.optimize.least_squares``
    (trust-region reflective, what shape learning called until 2026-12-02) on noisy points from poses, coefficients
    and shape units beyond their bounds, so that the bounds hold some unknowns at the minimum: the same minimum."""
    from scipy.optimize import least_squares

    from aamtrack.mesh.landmark_fit import LandmarkFitter, free_pose

    rng = np.random.default_rng(SEED)
    sm = synthetic_3d_model(rng)
    fitter = LandmarkFitter(sm)
    pose = free_pose(sm)
    held = 0
    for _ in range(6):
        q = np.r_[rng.normal(0, 0.3, 3), 150 * np.exp(rng.normal(0, 0.2)), rng.uniform(100, 200, 2),
                  rng.uniform(-1.6, 1.6, 2)]  # coefficients past their bounds of +-1 half the time
        sigma = rng.normal(0, 2.5, 3)  # shape units past their 3 sd now and then
        pts = sm.landmarks(q, sigma) + rng.normal(0, 1.0, (68, 2))
        lo, hi = fitter.bounds(True)
        x0 = np.clip(np.r_[0.0, 0.0, 0.0, np.log(140.0), pts.mean(0), 0.0, 0.0, np.zeros(3)], lo + 1e-9, hi - 1e-9)
        residuals, jacobian = fitter.problem(pts, pose, True, np.zeros(3))
        ref = least_squares(residuals, x0, jac=jacobian, bounds=(lo, hi), x_scale="jac", max_nfev=200)
        x, cost = fitter.solve(pts, x0, True, np.zeros(3))
        assert np.all(x >= lo) and np.all(x <= hi)
        assert abs(cost - 0.5 * residuals(x) @ residuals(x)) < 1e-12 * max(cost, 1e-12)  # the cost it returns is x's
        assert cost <= ref.cost * (1 + 1e-9)  # as low as scipy's (to its stopping tolerance)
        assert np.abs(x - ref.x).max() < 1e-3  # the same minimum (unknowns in radians, log-scale, px, units)
        held += int(np.sum((x == lo) | (x == hi)))
    assert held > 0  # the cases did press unknowns against their bounds
