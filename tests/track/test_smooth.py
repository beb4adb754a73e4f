"""One Euro smoothing of FrameResult streams on synthetic signals: less noise when still, the lag the filter's
formula predicts on a ramp (forwards only) and none when it also runs backwards from frames ahead, resets on
detection and after lost frames."""

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
    cfg = SmoothConfig(look_ahead=0)  # forwards only, as --realtime runs it
    v = widths_per_s * WIDTH / FPS  # px per frame
    shape = _shape()
    truth = np.stack([shape + [v * i, 0.0] for i in range(120)])
    out = list(smooth_results([_result(i, truth[i], "detected" if i == 0 else "tracked") for i in range(120)], cfg))
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
    for follow in (True, False):  # (forwards only: looking ahead sees the jump coming either way)
        out = list(smooth_results(results, SmoothConfig(follow_jumps=follow, look_ahead=0)))
        errors[follow] = float(np.linalg.norm(out[40].landmarks - truth[40], axis=-1).mean())
    assert errors[True] < 1.0  # px: within a fifth of the 5 px jump on the jump's frame
    assert errors[True] < 0.7 * errors[False]  # the low-passed speed alone holds the face back
    still = list(smooth_results(results[:40]))  # before the jump: the jitter is still halved
    lm = np.stack([r.landmarks for r in still])
    assert _jitter(lm[10:]) < 0.5 * _jitter(noisy[10:40])


@pytest.mark.parametrize("widths_per_s", [1.0, 0.25])
def test_looking_ahead_takes_out_the_lag(widths_per_s):
    v = widths_per_s * WIDTH / FPS  # px per frame
    shape = _shape()
    truth = np.stack([shape + [v * i, 0.0] for i in range(120)])
    results = [_result(i, truth[i], "detected" if i == 0 else "tracked") for i in range(120)]
    forwards = np.stack([r.landmarks for r in smooth_results(results, SmoothConfig(look_ahead=0))])
    both = np.stack([r.landmarks for r in smooth_results(results)])  # the default looks ahead
    lag_fwd = (truth[30:90, :, 0] - forwards[30:90, :, 0]).mean() / v
    lag = (truth[30:90, :, 0] - both[30:90, :, 0]).mean() / v
    assert SmoothConfig().look_ahead > 0
    assert lag_fwd > 0.1  # frames: the forward filter trails the ramp ...
    assert abs(lag) < 0.01  # ... and its mean with the backward one does not (the two lags cancel on a ramp)


def test_looking_ahead_smooths_a_still_face_at_least_as_much():
    rng = np.random.default_rng(SEED + 3)
    shape = _shape()
    noisy = shape + rng.normal(0.0, 0.3, size=(200, 68, 2))
    results = [_result(0, noisy[0], "detected")] + [_result(i, noisy[i]) for i in range(1, 200)]
    err = {}
    for ahead in (0, 8):
        lm = np.stack([r.landmarks for r in smooth_results(results, SmoothConfig(look_ahead=ahead))])
        err[ahead] = (_jitter(lm[50:]), np.linalg.norm(lm[50:] - shape, axis=-1).mean())
    assert err[8][0] <= err[0][0] and err[8][1] <= err[0][1]


def test_looking_ahead_is_the_mean_of_the_filter_run_both_ways():
    """On a stream shorter than two blocks the backward pass starts at its last frame: the output is exactly the
    mean of the One Euro filter run forwards and run over the reversed stream."""
    rng = np.random.default_rng(SEED + 4)
    shape = _shape()
    x = shape + np.cumsum(rng.normal(0.0, 0.5, size=(12, 68, 2)), axis=0)
    results = [_result(i, x[i], "detected" if i == 0 else "tracked") for i in range(12)]
    cfg = SmoothConfig(look_ahead=8)
    out = np.stack([r.landmarks for r in smooth_results(results, cfg)])
    fwd = np.stack([r.landmarks for r in smooth_results(results, SmoothConfig(look_ahead=0))])
    reversed_results = [_result(11 - i, x[i], "detected" if i == 11 else "tracked") for i in range(11, -1, -1)]
    bwd = np.stack([r.landmarks for r in smooth_results(reversed_results, SmoothConfig(look_ahead=0))])[::-1]
    assert np.allclose(out, 0.5 * (fwd + bwd), atol=1e-9)


def test_looking_ahead_streams_and_keeps_every_frame_in_order():
    shape = _shape()
    rng = np.random.default_rng(SEED + 5)
    statuses = ["detected"] + ["tracked"] * 99
    statuses[30], statuses[31], statuses[55], statuses[70] = "lost", "detected", "dropped", "detected"
    place = np.where(np.arange(100) < 31, 0.0, np.where(np.arange(100) < 70, 30.0, -30.0))  # a face per stretch
    results = []
    for i, st in enumerate(statuses):
        if st in ("lost", "dropped"):
            results.append(FrameResult(frame=i, timestamp=i / FPS, status=st))
        else:
            results.append(_result(i, shape + [place[i], 0.0] + rng.normal(0.0, 0.3, (68, 2)), st))
    fed = []

    def source():
        for r in results:
            fed.append(r.frame)
            yield r

    cfg = SmoothConfig(look_ahead=8)
    out = []
    for r in smooth_results(source(), cfg):
        assert len(fed) <= r.frame + 1 + 3 * cfg.look_ahead  # a frame comes out at most 3 x look_ahead after it went in
        out.append(r)
    assert [r.frame for r in out] == list(range(100)) and [r.status for r in out] == statuses
    for i in (29, 31, 69, 70):  # either side of a loss and of a re-detection: no pull towards the other face
        assert abs(float((out[i].landmarks - shape)[:, 0].mean()) - place[i]) < 0.2  # px (noise 0.3 per point)
    assert np.isnan(out[30].landmarks).all() and out[55].status == "dropped"
    with pytest.raises(ValueError):
        SmoothConfig(look_ahead=-1)
