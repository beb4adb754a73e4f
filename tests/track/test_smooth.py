"""One Euro smoothing of FrameResult streams on synthetic signals: less noise when still, the lag the filter's
formula predicts on a ramp, resets on detection and after lost frames."""

import math

import numpy as np
import pytest

from aamtrack.result import FrameResult
from aamtrack.track.smooth import OneEuroFilter, SmoothConfig, smooth_results
from conftest import SEED

FPS = 25.0
WIDTH = 100.0  # face width (x extent of the landmarks), px


def _shape() -> np.ndarray:
    rng = np.random.default_rng(SEED)
    shape = rng.uniform(0.0, WIDTH, size=(68, 2))
    shape[0, 0], shape[1, 0] = 0.0, WIDTH  # exact x extent
    return shape + 100.0


def _result(i, landmarks, status="tracked", rotation=(0.0, 0.0, 0.0)):
    return FrameResult(frame=i, timestamp=i / FPS, status=status, confidence=0.9, landmarks=landmarks,
                       rotation=np.array(rotation, float), translation=landmarks.mean(axis=0), scale=2.0,
                       vertices=landmarks[:10].copy())


def _jitter(track: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(track, axis=0), axis=-1).mean())


def test_still_face_loses_most_of_its_noise():
    rng = np.random.default_rng(SEED)
    shape = _shape()
    noisy = shape + rng.normal(0.0, 0.3, size=(200, 68, 2))
    rot_noise = rng.normal(0.0, 0.01, size=(200, 3))
    results = [_result(0, noisy[0], "detected")] + [_result(i, noisy[i], rotation=rot_noise[i])
                                                    for i in range(1, 200)]
    out = list(smooth_results(results))
    lm = np.stack([r.landmarks for r in out])
    raw_j, smooth_j = _jitter(noisy[50:]), _jitter(lm[50:])
    assert smooth_j < 0.5 * raw_j  # target of issue 12: at most half
    err_raw = np.linalg.norm(noisy[50:] - shape, axis=-1).mean()
    err = np.linalg.norm(lm[50:] - shape, axis=-1).mean()
    assert err < 0.6 * err_raw  # closer to the true still shape, not just calmer
    rot = np.stack([r.rotation for r in out])
    assert np.abs(np.diff(rot[50:], axis=0)).mean() < 0.5 * np.abs(np.diff(rot_noise[50:], axis=0)).mean()
    # the mesh vertices get the landmarks' filter: they stay on the smoothed landmarks they were copied from
    assert np.allclose(np.stack([r.vertices for r in out]), lm[:, :10])


@pytest.mark.parametrize("widths_per_s", [1.0, 0.25])
def test_ramp_lags_by_what_the_filter_predicts(widths_per_s):
    cfg = SmoothConfig()
    v = widths_per_s * WIDTH / FPS  # px per frame
    shape = _shape()
    truth = np.stack([shape + [v * i, 0.0] for i in range(120)])
    out = list(smooth_results([_result(i, truth[i], "detected" if i == 0 else "tracked") for i in range(120)]))
    lm = np.stack([r.landmarks for r in out])
    lag_frames = (truth[60:, :, 0] - lm[60:, :, 0]).mean() / v  # steady state
    # cutoff min_cutoff + beta * speed; a first-order low-pass trails a ramp by (1 - alpha) / alpha samples
    alpha = 1.0 / (1.0 + FPS / (2 * math.pi * (cfg.min_cutoff + cfg.beta * widths_per_s)))
    assert abs(lag_frames - (1 - alpha) / alpha) < 0.02  # the formula in the module docstring
    assert 0.0 < lag_frames <= 1.0  # at most one frame at these speeds
    assert np.allclose(lm[60:, :, 1], truth[60:, :, 1])  # no motion in y: nothing to lag


def test_reset_on_detection_and_after_a_lost_frame():
    shape = _shape()
    a, b = shape, shape + [30.0, 0.0]
    results = [_result(0, a, "detected"), _result(1, a), _result(2, b, "detected"),   # re-detection elsewhere
               _result(3, b), FrameResult(frame=4, timestamp=4 / FPS, status="lost"),
               _result(5, a), _result(6, a)]                                        # back after a loss
    out = list(smooth_results(results))
    assert np.array_equal(out[2].landmarks, b)  # detection: passes through, no pull towards the old face
    assert out[4].status == "lost" and np.isnan(out[4].landmarks).all()
    assert np.array_equal(out[5].landmarks, a)  # first frame after the loss: reset
    assert np.array_equal(out[5].rotation, results[5].rotation) and out[5].scale == results[5].scale
    assert [r.frame for r in out] == list(range(7)) and [r.status for r in out] == [r.status for r in results]


def test_dropped_frames_do_not_reset_but_widen_the_step():
    shape = _shape()
    rng = np.random.default_rng(SEED + 1)
    results = [_result(0, shape, "detected"), _result(1, shape),
               FrameResult(frame=2, timestamp=2 / FPS, status="dropped"),
               _result(3, shape + rng.normal(0, 1.0, (68, 2)))]
    out = list(smooth_results(results))
    assert out[2].status == "dropped"
    assert not np.array_equal(out[3].landmarks, results[3].landmarks)  # still filtered


def test_one_euro_filter_basics():
    with pytest.raises(ValueError):
        SmoothConfig(min_cutoff=0.0)
    f = OneEuroFilter(SmoothConfig(min_cutoff=1.0, beta=0.0))
    y, a0 = f.filter(np.zeros(3), 0.0)
    assert a0 == 1.0 and np.array_equal(y, np.zeros(3))
    y, a = f.filter(np.ones(3), 0.04)
    expected = 1.0 / (1.0 + 1.0 / (2 * math.pi * 1.0 * 0.04))  # beta 0: fixed cutoff 1 Hz
    assert a == pytest.approx(expected) and np.allclose(y, expected)
    f.reset()
    assert np.array_equal(f.filter(np.full(3, 5.0), 1.0)[0], np.full(3, 5.0))


def test_a_sudden_move_of_the_whole_face_is_followed_at_once():
    rng = np.random.default_rng(SEED + 2)
    shape = _shape()
    jump = 0.05 * WIDTH  # a camera shake of 5% of the face's width between two frames
    truth = np.stack([shape + [jump if i >= 40 else 0.0, 0.0] for i in range(60)])
    noisy = truth + rng.normal(0.0, 0.3, size=truth.shape)
    results = [_result(i, noisy[i], "detected" if i == 0 else "tracked") for i in range(60)]
    errors = {}
    for follow in (True, False):
        out = list(smooth_results(results, SmoothConfig(follow_jumps=follow)))
        errors[follow] = float(np.linalg.norm(out[40].landmarks - truth[40], axis=-1).mean())
    assert errors[True] < 1.0  # px: within a fifth of the 5 px jump on the jump's frame
    assert errors[True] < 0.7 * errors[False]  # the low-passed speed alone holds the face back
    still = list(smooth_results(results[:40]))  # before the jump: the jitter is still halved
    lm = np.stack([r.landmarks for r in still])
    assert _jitter(lm[10:]) < 0.5 * _jitter(noisy[10:40])
