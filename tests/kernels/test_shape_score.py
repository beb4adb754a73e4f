"""The compiled shape-prior score (``_kernels.shape_score``) against the obvious numpy computation."""

import numpy as np

from aamtrack.kernels import shape_prior_score
from aamtrack.mesh.landmarks import similarity_fit

SEED = 11


def _reference(pts, mean, modes, variances, rho) -> float:
    """The score step by step: similarity of the mean onto the points, the points taken back, split into modes and
    the rest."""
    s, R, t = similarity_fit(mean, pts)
    x = ((pts - t) @ R.T / s - mean).ravel()
    b = modes @ x
    r = x - b @ modes
    return float(np.sqrt(((b * b / variances).sum() + r @ r / rho) / x.size))


def _prior(rng, k=6):
    mean = rng.normal(0.0, 1.0, (68, 2))
    mean -= mean.mean(0)
    q, _ = np.linalg.qr(rng.normal(size=(136, k)))
    return mean, q.T.copy(), rng.uniform(0.01, 0.2, k), 0.003


def test_matches_the_numpy_reference():
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        mean, modes, var, rho = _prior(rng)
        pts = (mean + rng.normal(0.0, 0.1, mean.shape)) @ np.array([[0.8, 0.6], [-0.6, 0.8]]) * 37.0 + [200, 120]
        got = shape_prior_score(pts, mean, modes, var, rho)
        assert abs(got - _reference(pts, mean, modes, var, rho)) < 1e-9 * max(1.0, got)


def test_non_finite_or_collapsed_points_score_inf():
    mean, modes, var, rho = _prior(np.random.default_rng(SEED + 1))
    pts = mean.copy()
    pts[5, 1] = np.nan
    assert shape_prior_score(pts, mean, modes, var, rho) == np.inf
    assert shape_prior_score(np.full((68, 2), 3.0), mean, modes, var, rho) == np.inf
    assert shape_prior_score(mean * 4.0 + 9.0, mean, modes, var, rho) < 1e-6  # the mean itself, moved: 0
