"""The shape prior (``mesh.shape_prior``, ``train.shape_prior``) on synthetic shapes with known modes of variation."""

import numpy as np
import pytest
import synth

from aamtrack.mesh.landmarks import similarity_fit
from aamtrack.train.shape_prior import learn_shape_prior

SEED = 7
MODE_SD = (0.04, 0.025)  # face widths
NOISE_SD = 0.003


def _modes() -> np.ndarray:
    """(2, 68, 2) two unit-norm ways a face varies: the mouth opening (lower lip and chin down) and the face
    widening (every point out from the midline)."""
    ref = synth.face_layout()
    a = np.zeros_like(ref)
    a[[56, 57, 58, 65, 66, 67], 1] = -1.0  # lower lip down (y up in the layout)
    a[5:12, 1] = -0.6
    b = np.zeros_like(ref)
    b[:, 0] = ref[:, 0]
    return np.stack([a / np.linalg.norm(a), b / np.linalg.norm(b)])


def _shapes(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """(n, 68, 2) shapes in image axes (y down), each the layout plus the two modes and noise, then turned, scaled
    and moved at random; and their mode coefficients (n, 2)."""
    ref = synth.face_layout()
    modes = _modes()
    coef = rng.normal(0.0, MODE_SD, (n, 2))
    out = np.empty((n, 68, 2))
    for i in range(n):
        s = ref + np.einsum("k,kld->ld", coef[i], modes) + rng.normal(0.0, NOISE_SD, ref.shape)
        out[i] = synth.project2d(s, rng.normal(0, 0.3), rng.uniform(60, 200), rng.uniform(50, 300),
                                 rng.uniform(50, 300))
    return out, coef


def test_scores_labelled_like_shapes_about_one_whatever_their_pose():
    rng = np.random.default_rng(SEED)
    train, _ = _shapes(1500, rng)
    prior = learn_shape_prior(train)
    test, _ = _shapes(200, rng)
    scores = np.array([prior.score(p) for p in test])
    # the prior's own kind of shape: about 1 (module docstring; a little above, as the smallest of 136 sample
    # variances, which the residual's is the mean of, come out below the noise's)
    assert 0.8 < np.median(scores) < 1.3
    p = test[0]
    theta = 0.7
    R = np.array([[np.cos(theta), np.sin(theta)], [-np.sin(theta), np.cos(theta)]])
    moved = 2.5 * p @ R + [40.0, -17.0]
    assert abs(prior.score(moved) - prior.score(p)) < 1e-9  # similarity-invariant
    assert prior.score(prior.mean) < 0.2  # the mean itself: only the residual's few hundredths


def test_learned_modes_span_the_true_ones():
    rng = np.random.default_rng(SEED + 1)
    prior = learn_shape_prior(_shapes(1500, rng)[0], variance=0.9)
    # the true modes in the prior's frame (image axes: y flipped), less what a similarity of the mean does (the
    # alignment takes that part out: widening moves the eye corners apart too), onto the two leading modes
    m0 = prior.mean
    tangent = np.stack([m0.ravel(), np.column_stack([-m0[:, 1], m0[:, 0]]).ravel(),
                        np.tile([1.0, 0.0], 68), np.tile([0.0, 1.0], 68)])
    q, _ = np.linalg.qr(tangent.T)
    for m in _modes() * [1.0, -1.0]:
        v = m.ravel() - q @ (q.T @ m.ravel())
        v /= np.linalg.norm(v)
        assert np.linalg.norm(prior.modes[:2] @ v) > 0.95  # within the two leading modes


def test_a_collapsed_lower_face_scores_far_out_while_a_wide_open_mouth_does_not():
    rng = np.random.default_rng(SEED + 2)
    prior = learn_shape_prior(_shapes(1500, rng)[0])
    ref = synth.project2d(synth.face_layout(), 0.1, 120.0, 150.0, 150.0)
    collapsed = ref.copy()
    collapsed[48:68, 1] -= 0.5 * (collapsed[48:68, 1].mean() - collapsed[30:36, 1].mean())  # mouth half-way to nose
    collapsed[4:13, 1] -= 0.3 * (collapsed[4:13, 1] - collapsed[30, 1]).clip(0)
    opened = synth.project2d(synth.face_layout() + 2.5 * MODE_SD[0] * _modes()[0], 0.1, 120.0, 150.0, 150.0)
    assert prior.score(collapsed) > 3.0 * prior.score(opened)
    assert prior.score(opened) < 1.5  # 2.5 sd along a mode the labels vary in: plausible
    assert prior.score(collapsed) > 3.0


def test_degenerate_points_and_bad_input():
    rng = np.random.default_rng(SEED + 3)
    prior = learn_shape_prior(_shapes(50, rng)[0])
    assert prior.score(np.full((68, 2), 5.0)) == np.inf  # every point in one place: no face
    nan = prior.mean.copy()
    nan[3] = np.nan
    assert prior.score(nan) == np.inf
    with pytest.raises(ValueError, match="expected"):
        learn_shape_prior(np.zeros((10, 5, 2)))


def test_the_prior_is_in_the_frame_it_scores_in():
    """The mean is centred, level, outer eye corners 1 apart; the modes orthonormal."""
    prior = learn_shape_prior(_shapes(100, np.random.default_rng(SEED + 4))[0])
    m = prior.mean
    assert np.abs(m.mean(0)).max() < 1e-9
    d = m[45] - m[36]
    assert abs(np.hypot(*d) - 1.0) < 1e-9 and abs(d[1]) < 1e-9
    assert np.allclose(prior.modes @ prior.modes.T, np.eye(prior.n_modes), atol=1e-9)
    s, _, _ = similarity_fit(m, m * 3.0)
    assert abs(s - 3.0) < 1e-12
