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


def test_soft_couples_search_blurred_faces_better(synth_model):
    """On blurred faces (Gaussian, 0.06 outer eye-corner distances, as the robustness suite's blur), the search
    with the model's soft couples (``Model.couples_for`` picks them there) ends closer to the truth than the same
    search with the sharp couples alone, from the same displaced starts."""
    import cv2
    from dataclasses import replace

    rng = np.random.default_rng(SEED + 2)
    images, points = synth.random_faces(8, rng, size=(220, 220), scale=130.0)
    points = points - PIXEL_ORIGIN
    soft, sharp = Searcher(synth_model), Searcher(replace(synth_model, soft_couples=()))
    sm = synth_model.shape
    err_soft, err_sharp = [], []
    for img, pts in zip(images, points):
        eye = float(np.linalg.norm(pts[45] - pts[36]))
        levels = soft.levels(to_gray32(cv2.GaussianBlur(img, (0, 0), 0.06 * eye)))
        q0 = fit_landmarks(sm, pts).q.copy()
        q0[4:6] += 0.05 * np.ptp(pts[:, 0]) * np.array([np.cos(2.0), np.sin(2.0)])
        q0[3] *= 0.96
        r = soft.factors(q0)[-1]
        assert synth_model.couples_for(levels.resampled(r), r, sm.landmarks(q0)) is synth_model.soft_couples
        err_soft.append(np.linalg.norm(soft.fit(levels, q0, landmarks=False).landmarks - pts, axis=1).mean())
        err_sharp.append(np.linalg.norm(sharp.fit(levels, q0, landmarks=False).landmarks - pts, axis=1).mean())
    print(f"blurred faces, mean px error: sharp couples {np.mean(err_sharp):.2f}, soft couples {np.mean(err_soft):.2f}")
    assert np.mean(err_soft) < np.mean(err_sharp)


def test_dim_faces_leave_out_the_cascade_repeats(synth_model):
    """``Searcher.refine_landmarks``: the landmark cascade's last stage runs its ``repeats`` more times on a clear
    face, not on one dim and noisy at the search's points (``Model.dim``: the threshold moved about the face's own
    signal-to-noise)."""
    from dataclasses import replace

    from aamtrack.landmark_cascade import signal_to_noise

    rng = np.random.default_rng(SEED + 3)
    images, points = synth.random_faces(1, rng, size=(220, 220), scale=130.0)
    base = Searcher(synth_model)
    levels = base.levels(to_gray32(images[0]))
    q0 = fit_landmarks(synth_model.shape, points[0] - PIXEL_ORIGIN).q
    res = base.fit(levels, q0, landmarks=False)
    r = base.factors(res.p)[-1]
    img = levels.resampled(r)
    s = signal_to_noise(img, r, res.landmarks)
    lc = synth_model.landmark_cascade
    assert lc.repeats == 2 and lc is synth_model.cascade_for(img, r, res.landmarks)  # a sharp face: the main one
    with_repeats = lc.run(img, r, res.landmarks, 0, 2)[0]
    without = lc.run(img, r, res.landmarks, 0, 0)[0]
    assert np.abs(with_repeats - without).max() > 1e-3  # px: the repeats do move the points
    for below, expected in ((s - 0.01, with_repeats), (s + 0.01, without)):
        model = replace(synth_model, dim_below=below)
        out = Searcher(model).refine_landmarks(levels, res, r)
        assert out.dim == (below > s) and np.array_equal(out.landmarks, expected)
