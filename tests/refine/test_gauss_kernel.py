"""The Gauss transform kernels against a slow, obvious numpy sum."""

import numpy as np
import pytest
from conftest import SEED

from aamtrack.refine.gmm import GaussGrid, gauss_transform


def reference(x, y, h):
    d = x[:, None, :] - y[None, :, :]
    w = np.exp(-(d**2).sum(-1) / h**2)
    return w.sum(), (-2.0 / h**2 * d * w[..., None]).sum(1)


@pytest.mark.parametrize("h", [0.1, 0.5, 3.0])
def test_direct_matches_reference(h):
    rng = np.random.default_rng(SEED)
    x, y = rng.standard_normal((120, 3)), rng.standard_normal((90, 3))
    s, g = gauss_transform(x, y, h, tol=None)
    s_ref, g_ref = reference(x, y, h)
    assert abs(s - s_ref) <= 1e-12 * max(s_ref, 1.0)  # exact up to rounding
    assert np.abs(g - g_ref).max() <= 1e-12 * max(np.abs(g_ref).max(), 1.0)


@pytest.mark.parametrize("h", [0.05, 0.3, 1.0])
def test_grid_within_truncation(h):
    rng = np.random.default_rng(SEED + 1)
    x = rng.uniform(-2, 2, (300, 3))
    y = rng.uniform(-2, 2, (250, 3))
    tol = 1e-8
    s, g = gauss_transform(x, y, h, tol=tol)
    s_ref, g_ref = reference(x, y, h)
    # each skipped pair contributes < tol (and < tol * 2 r / h^2 to a gradient, r ~ h sqrt(ln 1/tol))
    assert abs(s - s_ref) <= tol * x.shape[0] * y.shape[0]
    assert np.abs(g - g_ref).max() <= tol * y.shape[0] * 20.0 / h


def test_grid_points_outside_and_empty():
    rng = np.random.default_rng(SEED + 2)
    y = rng.standard_normal((50, 3))
    far = y[:5] + 100.0  # far outside the grid of y: nothing within the cutoff
    s, g = GaussGrid(y, 0.5, tol=1e-6).transform(np.ascontiguousarray(far))
    assert s == 0.0 and not g.any()  # exactly zero: every pair is skipped
    s, _ = gauss_transform(np.zeros((3, 3)), np.zeros((0, 3)), 1.0)
    assert s == 0.0
