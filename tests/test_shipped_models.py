"""The shipped models load and track the bundled sample clip (nothing outside the repository needed)."""

from pathlib import Path

import numpy as np
import pytest

from aamtrack.io.frames import open_frames
from aamtrack.model import load_model
from aamtrack.models import default_model_path
from aamtrack.track.tracker import Tracker

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "cap12_first12s.mp4"


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_shipped_model_tracks_the_sample(kind):
    model = load_model(default_model_path(kind))
    assert model.kind == kind and model.features.kind == "gradient" and model.couples[-1].n_stages >= 1
    with open_frames(SAMPLE) as frames:
        results = [r for r, _ in zip(Tracker(model).track(frames), range(30), strict=False)]
    assert [r.frame for r in results] == list(range(30))
    assert all(r.success for r in results) and min(r.confidence for r in results) > 0.5
    eyes = np.array([np.linalg.norm(r.landmarks[45] - r.landmarks[36]) for r in results])
    assert 40 < np.median(eyes) < 90  # the sample's face: outer eye corners about 60 px apart at 400x300
    if kind == "3d":
        mm = np.array([np.linalg.norm(r.landmarks3d[45] - r.landmarks3d[36]) for r in results])
        assert np.all((mm > 75) & (mm < 105))  # millimetres, scaled to an 89 mm average; this person's own shape


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_landmarks3d_are_the_landmark_map_of_the_deformed_mesh(kind):
    """``ShapeModel.landmarks3d`` (from ``landmark_arrays``, the map applied once to the model's arrays) equals
    the landmark map applied to the whole deformed mesh, with and without the person's shape units."""
    sm = load_model(default_model_path(kind)).shape
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = np.r_[rng.normal(0, 0.2, 6), rng.normal(0, 0.5, sm.n_q - 6)]
        sigma = rng.normal(0, 0.5, sm.n_shape)
        for s in (sigma, None):
            want = sm.landmark_map @ sm.shape3d(q, s)
            assert np.abs(sm.landmarks3d(q, s) - want).max() < 1e-9 * max(1.0, np.abs(want).max())  # sums reordered
    moved, still = sm.landmarks3d(q, None), sm.landmarks3d(np.zeros_like(q), None)
    assert not np.allclose(moved, still)  # the coefficients move them
