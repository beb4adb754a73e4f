"""The sampler's smooth offset field: from the key points' offsets along the scan's normals alone, a smooth field in
3D whose moves along a curved surface follow from the neighbours' normal moves (synthetic ground truth)."""

import numpy as np
from conftest import SEED

from aamtrack.refine.sampler import _bending, _smooth_offsets


def _cap(rng, n_fixed=40, n_free=400):
    """Key points on a sphere cap of radius 1 (polar angle < 60 deg): ``n_fixed`` on its rim (the landmarks, which
    do not move), ``n_free`` inside; the true offset field is a bump (zero on the rim) times a fixed direction that
    is mostly along the surface at the cap's top."""
    theta_rim = np.radians(60.0)
    phi = np.linspace(0, 2 * np.pi, n_fixed, endpoint=False)
    u = rng.uniform(np.cos(theta_rim) + 0.02, 1.0, n_free)  # uniform on the sphere's area
    theta, az = np.r_[np.full(n_fixed, theta_rim), np.arccos(u)], np.r_[phi, rng.uniform(0, 2 * np.pi, n_free)]
    points = np.stack([np.sin(theta) * np.cos(az), np.sin(theta) * np.sin(az), np.cos(theta)], 1)
    bump = np.cos(0.5 * np.pi * theta / theta_rim) ** 2
    truth = 0.05 * bump[:, None] * np.array([1.0, 0.5, 0.3])
    return points, truth


def test_field_recovers_motion_along_a_curved_surface():
    rng = np.random.default_rng(SEED)
    points, truth = _cap(rng)
    n_fixed = 40
    normals = points[n_fixed:]  # the sphere's normals
    offsets = truth[n_fixed:] + 0.05 * rng.standard_normal((len(normals), 3)) * [1, 1, 0]  # along the surface: wrong
    offsets -= normals * ((offsets - truth[n_fixed:]) * normals).sum(1)[:, None]  # normal parts exact
    normal_only = normals * (offsets * normals).sum(1)[:, None]  # what a step along the normal gives
    delta = _smooth_offsets(offsets, normals, _bending(points, n_fixed), 0.1, 1e-3)
    err = np.linalg.norm(delta - truth[n_fixed:], axis=1).mean()
    err_normal_only = np.linalg.norm(normal_only - truth[n_fixed:], axis=1).mean()
    # (seen 0.76x) the motion along the surface comes from the neighbours' normal moves
    assert err < 0.85 * err_normal_only, (err, err_normal_only)
    assert np.allclose((delta * normals).sum(1), (offsets * normals).sum(1), atol=1e-12)  # the measured normal parts


def test_without_smoothness_only_the_normal_parts_stay_and_held_points_move_less():
    rng = np.random.default_rng(SEED + 1)
    points, truth = _cap(rng)
    normals = points[40:]
    offsets = truth[40:] + 0.01 * rng.standard_normal(truth[40:].shape)
    bending = _bending(points, 40)
    delta = _smooth_offsets(offsets, normals, bending, 0.0, 1e-2)  # no smoothness
    expected = normals * (offsets * normals).sum(1)[:, None]  # the step along the normal alone
    assert np.abs(delta - expected).max() < 1e-6 * np.abs(expected).max()  # CG to its 1e-6
    held = rng.random(len(normals)) < 0.3
    free = _smooth_offsets(offsets, normals, bending, 0.1, 1e-2)
    firm = _smooth_offsets(offsets, normals, bending, 0.1, 1e-2, held, 1.0)
    along_free, along_firm = (np.linalg.norm(d - expected, axis=1) for d in (free, firm))
    assert along_free[held].mean() > 1e-4  # (seen 3e-3) the smoothness moves key points along the surface
    assert along_firm[held].mean() < 0.3 * along_free[held].mean()  # (seen 0.15x) less where held
    assert np.allclose((firm * normals).sum(1), (offsets * normals).sum(1), atol=1e-12)  # normal parts kept


def test_key_points_without_confidence_follow_their_neighbours():
    # a tenth of the key points get a wildly wrong normal offset (what a fit at the scan's border or between two
    # layers gives); with confidence 0 the field ignores it and moves them with their neighbours instead
    rng = np.random.default_rng(SEED + 2)
    points, truth = _cap(rng)
    normals = points[40:]
    offsets = normals * (truth[40:] * normals).sum(1)[:, None]  # exact normal parts
    bad = rng.random(len(normals)) < 0.1
    offsets[bad] += normals[bad] * rng.choice([-0.2, 0.2], (bad.sum(), 1))  # 4x the largest true offset
    bending = _bending(points, 40)
    trusting = _smooth_offsets(offsets, normals, bending, 0.1, 1e-3)
    confidence = (~bad).astype(float)
    careful = _smooth_offsets(offsets, normals, bending, 0.1, 1e-3, confidence=confidence)
    err_trusting = np.linalg.norm(trusting - truth[40:], axis=1)[bad].mean()
    err_careful = np.linalg.norm(careful - truth[40:], axis=1)[bad].mean()
    assert err_careful < 0.15 * err_trusting, (err_careful, err_trusting)  # (seen 0.06x)
    good = ~bad  # the others keep their measured normal parts exactly
    assert np.allclose((careful[good] * normals[good]).sum(1), (offsets[good] * normals[good]).sum(1), atol=1e-12)
