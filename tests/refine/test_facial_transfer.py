"""Facial transfer: zero motion is the identity; a similarity-transformed, resampled target gets the motion."""

import numpy as np
from conftest import SEED, shared_path
from synthetic import bumpy_surface, smooth_warp

from aamtrack.refine.transfer import similarity, transfer

LANDMARKS = np.array([i * 20 + j for i in (1, 6, 10, 14, 18) for j in (1, 6, 10, 14, 18)])


def _rotation(rng):
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_similarity_recovers_known_transform():
    rng = np.random.default_rng(SEED)
    src = rng.standard_normal((68, 3))
    rot, s, t = _rotation(rng), 2.5, rng.standard_normal(3)
    s_hat, r_hat, t_hat = similarity(src, s * src @ rot.T + t)
    assert abs(s_hat - s) < 1e-10 and np.abs(r_hat - rot).max() < 1e-10 and np.abs(t_hat - t).max() < 1e-10


def test_zero_motion_is_identity():
    rng = np.random.default_rng(SEED)
    source = np.repeat(bumpy_surface(20)[None], 4, axis=0)
    target = 3.0 * smooth_warp(bumpy_surface(20), 0.5) @ _rotation(rng).T
    result = transfer(source, LANDMARKS, target, LANDMARKS)
    assert np.abs(result.frames - target.astype(np.float32)).max() == 0.0  # exactly T^0 in every frame


def test_transfer_to_resampled_scaled_target():
    rng = np.random.default_rng(SEED + 1)
    neutral = bumpy_surface(20)
    source = np.stack([smooth_warp(neutral, a) for a in (0.0, 0.5, 1.0)])
    # target: the same face, 2x larger, rotated, its vertices shuffled (only the landmarks are given)
    rot, scale = _rotation(rng), 2.0
    order = rng.permutation(len(neutral))
    target = scale * neutral[order] @ rot.T
    t_lm = np.argsort(order)[LANDMARKS]
    truth = scale * source[:, order] @ rot.T
    result = transfer(source, LANDMARKS, target, t_lm)
    err = np.linalg.norm(result.frames - truth, axis=2).mean() / scale
    motion = np.linalg.norm(source - source[0], axis=2).mean()
    assert abs(result.scale - scale) < 1e-9  # landmarks match exactly up to the similarity
    assert err < 0.1 * motion  # within 10% of the mean motion


def test_ict_transfer_between_identities():
    from aamtrack.refine.sequences import apply_weights, load_face_model, make_sequence, neutral_face
    from aamtrack.refine.sequences import random_identity

    model = load_face_model(shared_path("ict_facekit", "ict_face_light_head11248.npz"))
    seq = make_sequence(model, n_frames=12, seed=SEED)
    id_b = random_identity(model, np.random.default_rng(SEED + 5))
    rng = np.random.default_rng(SEED)
    n = len(model.neutral)
    subset = rng.permutation(np.union1d(rng.choice(n, n // 2, replace=False), model.landmark68))
    s_lm = np.searchsorted(np.sort(subset), model.landmark68)
    s_lm = np.argsort(subset)[s_lm]  # positions of the landmarks in the shuffled subset
    result = transfer(seq.frames[:, subset], s_lm, neutral_face(model, id_b), model.landmark68)
    truth = apply_weights(model, id_b, seq.weights)
    err_mm = 10 * np.linalg.norm(result.frames - truth, axis=2).mean()
    assert err_mm < 1.5  # identity B with the same expression weights (seen ~0.6 mm)
