"""The landmark validator's learning (``aamtrack.train.validator``): synthetic data with a known answer."""

import numpy as np

from aamtrack.model import Validator
from aamtrack.train.validator import DEGRADATIONS, degraded, landmark_validator_fit
from conftest import SEED


def _problem(rng, n=1200, d=60):
    """Statistics S (n, 3) and descriptors Z (n, d) on very different scales; the label is a noisy linear rule
    on both."""
    S = rng.normal(size=(n, 3)) * [1.0, 50.0, 0.01] + [0.0, 300.0, 2.0]
    Z = rng.normal(size=(n, d)) * rng.uniform(0.01, 10.0, d) + rng.normal(0, 5, d)
    Zs = (Z - Z.mean(0)) / Z.std(0)
    t = 2.0 * (S[:, 0] - S[:, 0].mean()) + Zs[:, :5].sum(1) - Zs[:, 5:8].sum(1) + rng.normal(0, 0.3, n)
    return S, Z, (t > 0.4).astype(float)


def test_landmark_validator_learns_a_linear_rule_and_folds_its_scaling():
    rng = np.random.default_rng(SEED)
    S, Z, y = _problem(rng)
    tr = np.arange(len(y)) < 900
    v = landmark_validator_fit(S[tr], Z[tr], y[tr], ("a", "b", "c"), l2=0.001)
    assert isinstance(v, Validator) and v.descriptor_weights.dtype == np.float32
    conf = np.array([v(s, z) for s, z in zip(S[~tr], Z[~tr])])
    acc = np.mean((conf > 0.5) == (y[~tr] > 0.5))
    print("held-out accuracy", acc)
    assert acc > 0.9  # a noisy but linear rule (noise 0.3 against a spread of ~3)
    # the descriptors' standardisation is folded into their weights: rescaled and shifted descriptors give the
    # same confidences once refitted
    k = rng.uniform(0.1, 10.0, Z.shape[1])
    v2 = landmark_validator_fit(S[tr], Z[tr] * k + 3.0, y[tr], ("a", "b", "c"), l2=0.001)
    conf2 = np.array([v2(s, z * k + 3.0) for s, z in zip(S[~tr], Z[~tr])])
    assert np.abs(conf - conf2).max() < 1e-3  # L-BFGS tolerance


def test_validator_without_descriptors_ignores_them_and_one_with_them_needs_them():
    v = Validator(("a",), np.array([1.0]), np.array([0.0]), np.array([1.0]), 0.0)
    assert v(np.array([0.0])) == 0.5
    w = Validator(("a",), np.array([1.0]), np.array([0.0]), np.array([1.0]), 0.0, np.array([2.0], np.float32))
    assert abs(w(np.array([0.0]), np.array([1.0])) - 1 / (1 + np.exp(-2.0))) < 1e-12
    try:
        w(np.array([0.0]))
    except ValueError as exc:
        assert "descriptors" in str(exc)
    else:
        raise AssertionError("a descriptor validator scored without descriptors")


def test_degraded_copies_differ_and_keep_the_image_format():
    rng = np.random.default_rng(SEED)
    gray = rng.uniform(0, 255, (80, 90)).astype(np.float32)
    seen = set()
    for _ in range(40):
        out = degraded(gray, 30.0, rng)
        assert out.shape == gray.shape and out.dtype == np.float32
        assert np.abs(out - gray).mean() > 1.0  # really changed
        # which kind it was: blur and low contrast keep the mean level near, dark lowers it, noise keeps it but
        # adds spread
        seen.add("dark" if out.mean() < 0.6 * gray.mean() else "other")
    assert seen == {"dark", "other"} and len(DEGRADATIONS) == 4
