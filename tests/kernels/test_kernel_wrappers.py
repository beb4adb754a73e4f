"""The checked entry points (``aamtrack.kernels``): read-only arrays of another dtype or layout are cast (same
result, no new compiled specialisation); arrays the kernels write into must already be right."""

import numpy as np
import pytest

from aamtrack import kernels
from aamtrack._kernels import warp as raw
from aamtrack.landmark_cascade import quantise_rows
from conftest import SEED
from kernels.test_warp_kernels import _toy_problem


def _cascade_args(rng):
    image, shape3d, basis, vid, bary, q = _toy_problem(rng)
    D = 2 * len(vid)
    R = quantise_rows(rng.normal(0, 1e-3, (2, 3, D)).astype(np.float32))
    b = np.full((2, 3), 0.05)
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.linalg.qr(rng.normal(0, 1, (D, 2)))[0].astype(np.float32)
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    scratch = (np.empty((4, 2)), np.empty(D, np.float32), np.empty(2), np.empty(D), np.empty(3))
    return image, shape3d, basis, q, np.array([4, 5, 6]), lo, hi, R, b, mean, app, vid, bary, scratch


def test_cast_inputs_give_the_same_fit_without_a_new_specialisation():
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, q, free, lo, hi, R, b, mean, app, vid, bary, scratch = _cascade_args(rng)
    p_ref = q.copy()
    kernels.cascade(image, 0.9, 0.1, shape3d, basis, p_ref, free, lo, hi, *R, b, mean, app, vid, bary, 1, *scratch)
    n_sigs = len(raw._cascade.signatures)
    p = q.copy()
    # float64 matrices, a strided image, int32 indices, a Python list of bounds: all cast on the way in
    strided = np.repeat(image, 2, axis=2)[:, :, ::2]
    kernels.cascade(strided, 0.9, 0.1, shape3d.astype(np.float32), basis, p, free.astype(np.int32), list(lo), hi,
                    R[0].astype(np.int64), R[1].astype(np.float64), b, mean.astype(np.float64), app.astype(np.float64), vid.astype(np.int64),
                    bary.astype(np.float64), 1, *scratch)
    assert np.abs(p - p_ref).max() < 1e-6  # shape3d cast through float32: rounding only
    assert len(raw._cascade.signatures) == n_sigs  # nothing new compiled


@pytest.mark.parametrize("bad", ["float32 q", "strided q", "read-only q"])
def test_outputs_of_the_wrong_kind_are_refused(bad):
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, q, free, lo, hi, R, b, mean, app, vid, bary, scratch = _cascade_args(rng)
    if bad == "float32 q":
        q = q.astype(np.float32)
    elif bad == "strided q":
        q = np.repeat(q, 2)[::2]
    else:
        q.setflags(write=False)
    with pytest.raises(TypeError, match="q: a writable C-contiguous 1-d float64"):
        kernels.cascade(image, 1.0, 0.0, shape3d, basis, q, free, lo, hi, *R, b, mean, app, vid, bary, 1, *scratch)


def test_wrong_dimensions_are_named():
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, q, *_ = _cascade_args(rng)
    with pytest.raises(ValueError, match="basis: a 3-d array expected"):
        kernels.project(shape3d, basis[0], q, np.empty((4, 2)))


def test_project_and_rotation_agree_with_the_kernels():
    rng = np.random.default_rng(SEED)
    _, shape3d, basis, *_, q = _toy_problem(rng)
    out = np.empty((4, 2))
    raw._project(shape3d, basis, q, out)
    assert np.array_equal(kernels.project(shape3d, basis, q, np.empty((4, 2))), out)
    R = kernels.rotation(0.1, -0.2, 0.3)
    assert np.abs(R @ R.T - np.eye(3)).max() < 1e-12 and np.linalg.det(R) == pytest.approx(1.0)
