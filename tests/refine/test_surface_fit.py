"""The sampler's projection onto a robust local quadric of the scan (:func:`_fit_heights`): against a sampled,
noisy, curved sheet whose true surface is known."""

import numpy as np
from conftest import SEED

from aamtrack.refine.scan_surface import _fit_heights, _project, _Surface


def _sheet(rng, n=6000, noise=0.0):
    """A curved sheet z = 0.3 (x^2 - 0.5 y^2) + 0.1 sin(2 x) over [-1, 1]^2, sampled at random, with isotropic
    Gaussian noise of ``noise``; returns the scan and the true height function."""
    def height(x, y):
        return 0.3 * (x * x - 0.5 * y * y) + 0.1 * np.sin(2.0 * x)

    u = rng.uniform(-1, 1, (n, 2))
    return np.column_stack([u, height(u[:, 0], u[:, 1])]) + noise * rng.standard_normal((n, 3)), height


def _distance_to_sheet(points, height):
    """Distance along z to the sheet, times the cosine of its slope: the distance to it, to first order."""
    x, y = points[:, 0], points[:, 1]
    gx, gy = 0.6 * x + 0.2 * np.cos(2.0 * x), -0.3 * y
    return np.abs(points[:, 2] - height(x, y)) / np.sqrt(1.0 + gx * gx + gy * gy)


def test_quadric_lands_nearer_the_surface_than_tangent_planes_on_a_noisy_scan():
    rng = np.random.default_rng(SEED)
    spacing = 0.02  # about the distance between neighbouring scan points (6000 points on 4 square units: 0.026)
    scan, height = _sheet(rng, noise=0.1 * spacing)  # noise of a tenth of the spacing, like 0.05 mm at 2 mm
    surface = _Surface(scan)
    q = rng.uniform(-0.7, 0.7, (400, 2))
    query = np.column_stack([q, height(q[:, 0], q[:, 1]) + rng.uniform(-0.05, 0.05, 400)])  # off the sheet
    moved, normals, sigma = _fit_heights(query, surface)
    planes = _project(query, surface, cap=0.2)
    ok = np.isfinite(sigma)
    assert ok.mean() > 0.95  # inside the scan: few taken for border (random sampling: seen 2% elsewhere)
    err, err_planes = _distance_to_sheet(moved[ok], height), _distance_to_sheet(planes[ok], height)
    moved, normals, sigma, query = moved[ok], normals[ok], sigma[ok], query[ok]
    assert err.mean() < 0.15 * spacing  # (seen 0.06) below the noise of one scan point (0.1 spacing, x 3 axes)
    assert err.mean() < 0.7 * err_planes.mean(), (err.mean(), err_planes.mean())  # (seen 0.57x)
    along = np.linalg.norm(np.cross(moved - query, normals), axis=1)
    assert along.max() < 1e-12  # the move is along the scan's normal
    # sigma (the fitted height's standard error) follows the scan's noise: three times the noise, about three
    # times sigma (it is approximate: under the robust weights it is below the actual error, seen 0.28x of it)
    _, _, sigma3 = _fit_heights(query, _Surface(_sheet(np.random.default_rng(SEED), noise=0.3 * spacing)[0]))
    assert 2.0 < np.median(sigma3) / np.median(sigma) < 4.5, (np.median(sigma3), np.median(sigma))
    assert 0.1 < np.median(sigma) / np.median(err) < 1.0, (np.median(sigma), np.median(err))


def test_border_and_second_layer():
    rng = np.random.default_rng(SEED + 1)
    scan, height = _sheet(rng)
    # past the sheet's border (x > 1): an extrapolation, flagged with an infinite standard error
    outside = np.array([[1.15, 0.0, height(1.15, 0.0)], [0.0, -1.2, height(0.0, -1.2)]])
    _, _, sigma = _fit_heights(outside, _Surface(scan))
    assert np.isinf(sigma).all()
    # a second layer 3 spacings under part of the sheet (a fold, an ear): the robust weights follow the nearer one
    under = scan[scan[:, 0] > 0.2] - [0.0, 0.0, 0.06]
    query = np.array([[0.5, 0.1, height(0.5, 0.1) + 0.01], [0.6, -0.3, height(0.6, -0.3) + 0.01]])
    moved, _, sigma = _fit_heights(query, _Surface(np.concatenate([scan, under])), k=24)
    assert _distance_to_sheet(moved, height).max() < 0.005  # on the upper sheet, not between the two (0.03)
