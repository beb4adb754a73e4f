"""The Gauss transform kernels against a slow, obvious numpy sum."""

import numpy as np
import pytest
from conftest import SEED

from aamtrack.refine.gmm import GaussGrid, gauss_moments, gauss_transform


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


def reference_moments(x, y, h):
    w = np.exp(-((x[:, None, :] - y[None, :, :]) ** 2).sum(-1) / h**2)
    return w.sum(1), (w @ y) / w.sum(1)[:, None]


@pytest.mark.parametrize("h", [0.3, 1.0])
def test_moments_direct_matches_reference(h):
    rng = np.random.default_rng(SEED + 3)
    x, y = rng.standard_normal((80, 3)), rng.standard_normal((70, 3))
    weight, mean = gauss_moments(x, y, h, tol=None)
    w_ref, m_ref = reference_moments(x, y, h)
    assert np.abs(weight - w_ref).max() <= 1e-12 * w_ref.max()  # exact up to rounding
    assert np.abs(mean - m_ref).max() <= 1e-9


@pytest.mark.parametrize("h", [0.1, 0.4])
def test_moments_grid_within_truncation(h):
    rng = np.random.default_rng(SEED + 4)
    x = rng.uniform(-2, 2, (300, 3))
    y = rng.uniform(-2, 2, (400, 3))
    tol = 1e-8
    weight, mean = gauss_moments(x, y, h, tol=tol)
    w_ref, m_ref = reference_moments(x, y, h)
    assert np.abs(weight - w_ref).max() <= tol * len(y)  # each skipped pair weighs < tol
    ok = w_ref > 1e-3  # means are defined where some weight is near
    # a skipped pair moves a mean by < tol * |y - mean| / weight
    assert np.abs(mean - m_ref)[ok].max() <= tol * len(y) * 8.0 / w_ref[ok].min()


def test_cell_table_and_binary_search_agree():
    rng = np.random.default_rng(SEED + 5)
    y = rng.uniform(-1, 1, (500, 3))
    x = np.ascontiguousarray(rng.uniform(-1.2, 1.2, (200, 3)))
    grid = GaussGrid(y, 0.2, tol=1e-6)
    assert len(grid.table) > 0  # few cells: the table is used
    w1, m1 = np.empty(200), np.empty((200, 3))
    s1 = grid.moments(x, w1, m1)
    g1 = grid.transform(x)[1].copy()
    grid.table = np.empty(0, dtype=np.int64)  # force the binary search
    w2, m2 = np.empty(200), np.empty((200, 3))
    s2 = grid.moments(x, w2, m2)
    assert s1 == s2 and np.array_equal(w1, w2) and np.array_equal(m1, m2)  # same pairs, same order
    assert np.array_equal(g1, grid.transform(x)[1])
