"""Each kernel against a slow, obvious reference."""

import numpy as np
import pytest
from scipy.ndimage import map_coordinates
from scipy.spatial.transform import Rotation

from aamtrack._kernels.warp import _compose, _normalize, _project, _warp
from conftest import SEED


def test_project_matches_scipy_rotation():
    rng = np.random.default_rng(SEED)
    shape = rng.normal(size=(20, 3))
    basis = rng.normal(size=(2, 20, 3))
    q = np.r_[0.2, -0.3, 0.4, 50.0, 100.0, 80.0, 0.5, -0.25]
    X = shape + 0.5 * basis[0] - 0.25 * basis[1]
    R = Rotation.from_euler("xyz", q[:3]).as_matrix()  # extrinsic x, then y, then z: Rz @ Ry @ Rx
    ref = np.column_stack([50 * (X @ R.T)[:, 0] + 100, -50 * (X @ R.T)[:, 1] + 80])
    out = np.empty((20, 2))
    _project(shape, basis, q, out)
    assert np.abs(out - ref).max() < 1e-9  # exact up to rounding


def test_warp_matches_map_coordinates():
    rng = np.random.default_rng(SEED)
    image = rng.uniform(0, 255, (60, 80)).astype(np.float32)
    verts = np.array([[10.0, 5.0], [70.0, 12.0], [30.0, 50.0], [65.5, 55.25]])
    vid = rng.integers(0, 4, (500, 3)).astype(np.int32)
    bary = rng.dirichlet([1, 1, 1], 500).astype(np.float32)
    out = np.empty(500, np.float32)
    for scale in (1.0, 0.5):
        _warp(image, verts, scale, vid, bary, out)
        pos = scale * np.einsum("pk,pkd->pd", bary.astype(float), verts[vid])
        ref = map_coordinates(image.astype(float), [pos[:, 1], pos[:, 0]], order=1)
        assert np.abs(out - ref).max() < 1e-3  # bilinear, float32


def test_warp_clamps_outside_samples():
    image = np.arange(12, dtype=np.float32).reshape(3, 4)
    verts = np.array([[-5.0, -5.0], [10.0, 10.0]])
    vid = np.array([[0, 0, 0], [1, 1, 1]], np.int32)
    bary = np.array([[1, 0, 0], [1, 0, 0]], np.float32)
    out = np.empty(2, np.float32)
    assert _warp(image, verts, 1.0, vid, bary, out) == 2
    assert out.tolist() == [0.0, 11.0]  # nearest corners


def test_normalize():
    tex = np.random.default_rng(SEED).normal(5, 3, 400).astype(np.float32)
    _normalize(tex)
    assert abs(tex.mean()) < 1e-5 and abs(tex.std() - 1) < 1e-4


def test_compose_moves_in_the_face_frame():
    q = np.r_[0.0, 0.0, np.pi / 2, 10.0, 100.0, 100.0]
    free = np.arange(6)
    out = np.empty(6)
    inf = np.full(6, np.inf)
    _compose(q, free, np.r_[0, 0, 0, np.log(2.0), 1.0, 0.0], 1.0, -inf, inf, out)
    # one model unit along the face's x axis, rolled by 90 degrees: straight up in the image (y down)
    assert np.allclose(out[4:6], [100.0, 90.0]) and out[3] == pytest.approx(20.0)
    _compose(q, free, np.r_[0, 0, 0, 0, 1.0, 0.0], 0.5, -inf, inf, out)
    assert np.allclose(out[4:6], [100.0, 95.0])  # half a step


def test_compose_clips_to_bounds():
    q = np.r_[0, 0, 0, 10.0, 0, 0, 0.9]
    out = np.empty(7)
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    hi[6] = 1.0
    _compose(q, np.array([6]), np.array([0.5]), 1.0, lo, hi, out)
    assert out[6] == 1.0
