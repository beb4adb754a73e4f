"""Helpers of benchmarks/smoothing.py on signals whose answers are known by construction."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from smoothing import moving_frames, xcorr_delay  # noqa: E402
from conftest import SEED  # noqa: E402


def _face(n_frames, x_of_t):
    """(n, 68, 2): a fixed random shape with outer eye corners 60 px apart, translated to x_of_t(t)."""
    shape = np.random.default_rng(SEED).uniform(0, 100, (68, 2))
    shape[36], shape[45] = (20.0, 40.0), (80.0, 40.0)
    return np.stack([shape + [x_of_t(t), 0.0] for t in range(n_frames)])


def test_moving_frames_finds_the_ramp_only():
    # still for 40 frames, then 30 frames at 3 px/frame (0.05 eye distances), then still again
    x = lambda t: 3.0 * min(max(t - 40, 0), 30)  # noqa: E731
    mask = moving_frames(_face(110, x))
    idx = np.flatnonzero(mask)
    assert idx.min() >= 36 and idx.max() <= 74  # the ramp (frames 41..70) grown by 2 and the 5-frame window
    assert mask[45:66].all() and not mask[:35].any() and not mask[76:].any()


def test_xcorr_delay_recovers_a_known_shift_despite_an_offset():
    ref = _face(200, lambda t: 20 * np.sin(t / 7.0))
    track = _face(200, lambda t: 20 * np.sin((t - 2.5) / 7.0)) + 3.0  # 2.5 frames late, 3 px off everywhere
    mask = np.zeros(200, bool)
    mask[30:80] = mask[120:170] = True
    assert abs(xcorr_delay(track, ref, mask) - 2.5) <= 0.05  # to the 0.05-frame grid
    assert abs(xcorr_delay(ref, track, mask) + 2.5) <= 0.05  # early is negative
    track[40:45] = np.nan  # lost frames are left out
    assert abs(xcorr_delay(track, ref, mask) - 2.5) <= 0.05
    assert np.isnan(xcorr_delay(track, ref, np.zeros(200, bool)))
