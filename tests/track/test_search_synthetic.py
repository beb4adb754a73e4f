"""One search from a perturbed start recovers the true parameters of a synthetic render."""

import numpy as np

from aamtrack.imaging import to_gray32
from aamtrack.metrics import PIXEL_ORIGIN
from aamtrack.search import Searcher
from aamtrack.train.shape_fit import fit_landmarks
from conftest import SEED
import synth


def test_search_recovers_true_landmarks(synth_model):
    rng = np.random.default_rng(SEED + 1)
    images, points = synth.random_faces(8, rng, size=(220, 220), scale=130.0)  # faces not seen in training
    points = points - PIXEL_ORIGIN  # labels are 1-based; the search works in OpenCV's pixels
    searcher = Searcher(synth_model)
    sm = synth_model.shape
    before, after, floor = [], [], []
    for img, pts in zip(images, points):
        truth = fit_landmarks(sm, pts)
        q0 = truth.q.copy()
        width = np.ptp(pts[:, 0])
        q0[4:6] += 0.05 * width * np.array([np.cos(1.0), np.sin(1.0)])  # 5% of the face width
        q0[2] += np.radians(5.0)
        q0[3] *= 1.04
        res = searcher.fit(searcher.levels(to_gray32(img)), q0)
        before.append(np.linalg.norm(sm.landmarks(q0) - pts, axis=1).mean())
        after.append(np.linalg.norm(res.landmarks - pts, axis=1).mean())
        floor.append(np.linalg.norm(sm.landmarks(truth.q) - pts, axis=1).mean())
        assert len(res.iterations) == len(synth_model.couples)
    assert np.mean(before) > 4.0  # the start is really off
    print(f"mean px error: start {np.mean(before):.2f}, after search {np.mean(after):.2f}, "
          f"best the model can represent {np.mean(floor):.2f}")
    assert np.mean(after) < 1.0  # mean landmark error under a pixel
    assert np.mean(after) - np.mean(floor) < 0.5  # within half a pixel of the model's own best fit
