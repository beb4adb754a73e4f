"""RBF deformation: affine maps are reproduced exactly; key points are interpolated."""

import numpy as np
import pytest
from conftest import SEED

from aamtrack.refine.rbf import KERNELS, fit_rbf, rbf_system


@pytest.mark.parametrize("kernel", KERNELS)
def test_reproduces_affine_map(kernel):
    rng = np.random.default_rng(SEED)
    centres = rng.uniform(-1, 1, (40, 3))
    a = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    b = rng.standard_normal(3)
    d = fit_rbf(centres, centres @ a + b, kernel=kernel, scale=0.8)
    pts = rng.uniform(-3, 3, (500, 3))  # also far outside the centres
    err = np.abs(d.apply(pts) - (pts @ a + b)).max()
    assert err < 1e-6  # exact affine (up to the conditioning of the solve)
    assert np.abs(d.linear - a).max() < 1e-6


@pytest.mark.parametrize("kernel", KERNELS)
def test_interpolates_key_points(kernel):
    rng = np.random.default_rng(SEED + 1)
    centres = rng.uniform(-1, 1, (60, 3))
    targets = centres + 0.2 * np.sin(3 * centres[:, [1, 2, 0]])
    d = fit_rbf(centres, targets, kernel=kernel, scale=0.8)
    assert np.abs(d.apply(centres) - targets).max() < 1e-8  # exact interpolation


def test_operator_is_linear_in_targets():
    rng = np.random.default_rng(SEED + 2)
    centres = rng.uniform(-1, 1, (30, 3))
    targets = rng.standard_normal((30, 3))
    pts = rng.uniform(-1, 1, (70, 3))
    system = rbf_system(centres)
    via_operator = system.operator(pts) @ targets
    assert np.abs(via_operator - fit_rbf(centres, targets).apply(pts)).max() < 1e-9  # same linear map


def test_smoothing_gives_smoother_fit():
    rng = np.random.default_rng(SEED + 3)
    centres = rng.uniform(-1, 1, (50, 3))
    noisy = centres + 0.05 * rng.standard_normal((50, 3))
    exact = fit_rbf(centres, noisy)
    smooth = fit_rbf(centres, noisy, smoothing=10.0)
    assert np.abs(exact.apply(centres) - noisy).max() < 1e-8  # interpolates
    # a smoothed fit no longer passes through the noise but stays near it
    resid = np.abs(smooth.apply(centres) - noisy).max()
    assert 1e-4 < resid < 0.3
