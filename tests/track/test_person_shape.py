"""The 3D model searches the person's shape units (sigma) with the pose: a search with sigma free lands closer to
the true landmarks than one held to the mean person."""

import numpy as np

from aamtrack.imaging import to_gray32
from aamtrack.search import Searcher
from aamtrack.train.shape_fit import fit_landmarks
from conftest import SEED
import synth3d

OBSERVABLE = ("eye_separation_distance", "mouth_width", "eyes_width")  # units a frontal face shows


def test_person_search_moves_towards_the_true_shape(synth_model3d):
    model3d, candide = synth_model3d
    sm = model3d.shape
    assert model3d.n_params == sm.n_q + sm.n_shape and len(model3d.couples[-1].free) == model3d.n_params
    rng = np.random.default_rng(SEED + 7)
    searcher = Searcher(model3d)
    gains, befores = [], []
    images, points, _, _ = synth3d.posed_faces(candide, 6, rng, yaw_sd=0.0, pitch_sd=0.0,
                                               observable=OBSERVABLE)  # new faces, each its own sigma
    for img, pts in zip(images, points):
        truth = fit_landmarks(sm, pts)  # the model's own best description of the face
        p0 = np.r_[truth.q, np.zeros(sm.n_shape)]
        levels = searcher.levels(to_gray32(img))
        held = searcher.fit(levels, p0, np.zeros(sm.n_shape))
        free = searcher.fit(levels, p0)
        before = np.linalg.norm(held.landmarks - pts, axis=1).mean()
        after = np.linalg.norm(free.landmarks - pts, axis=1).mean()
        gains.append(before - after)
        befores.append(before)
    print("landmark error with the mean person (px):", np.round(befores, 2),
          "gain from searching sigma (px):", np.round(gains, 2))
    # the searched sigma explains part of the shape the mean person misses; a search that ignored or broke sigma
    # would make the mean gain zero or negative
    assert np.mean(gains) > 0.05 * np.mean(befores)
