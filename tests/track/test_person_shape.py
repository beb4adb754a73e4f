"""The 3D model searches the person's shape units (sigma) with the pose: a search with sigma free lands closer to
the true landmarks than one held to the mean person."""

import numpy as np

from aamtrack.imaging import to_gray32
from aamtrack.metrics import PIXEL_ORIGIN
from aamtrack.search import Searcher
from aamtrack.train.shape_fit import fit_landmarks
from conftest import SEED
import synth3d

OBSERVABLE = ("eye_separation_distance", "mouth_width", "eyes_width")  # units a frontal face shows


class _NONE:
    confidence = 0.0


def test_person_search_moves_towards_the_true_shape(synth_model3d):
    model3d, candide = synth_model3d
    sm = model3d.shape
    assert model3d.n_params == sm.n_q + sm.n_shape and len(model3d.couples[-1].free) == model3d.n_params
    rng = np.random.default_rng(SEED + 7)
    searcher = Searcher(model3d)
    gains, befores = [], []
    images, points, _, _ = synth3d.posed_faces(candide, 6, rng, yaw_sd=0.0, pitch_sd=0.0,
                                               observable=OBSERVABLE)  # new faces, each its own sigma
    points = points - PIXEL_ORIGIN  # labels are 1-based; the search works in OpenCV's pixels
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


def test_the_person_shape_is_estimated_anew_after_a_cut(synth_model3d):
    """``TrackerConfig.sigma_per_shot``: after a shot change (here two different synthetic people at different
    places in the frame) the held sigma of the first person is dropped and the second person's is estimated from
    their own frames; with it off the first one's is kept."""
    from aamtrack.imaging import thumbnail
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import Tracker, TrackerConfig

    model3d, candide = synth_model3d
    rng = np.random.default_rng(SEED + 7)
    faces, _, _, _ = synth3d.posed_faces(candide, 8, rng, yaw_sd=0.0, pitch_sd=0.0, observable=OBSERVABLE)
    tracker = Tracker(model3d)

    def found(image):
        return (tracker.detect_and_fit(image)[0] or _NONE).confidence >= 0.5

    # the second person 40 px to the right (the renders' background is about flat, so the wrapped strip is
    # background): a change of shot, not a motion; two people found as they are shown
    first = next(i for i, f in enumerate(faces) if found(f))
    second = next(np.roll(f, 40, axis=1) for f in faces[first + 1:] if found(np.roll(f, 40, axis=1)))
    images = [faces[first], second]
    corr = float((thumbnail(images[0]) * thumbnail(images[1])).sum())
    assert corr < TrackerConfig().cut_below  # the premise: a cut under the rule
    frames = [images[0]] * 6 + [images[1]] * 6
    runs = {}
    for per_shot in (True, False):
        cfg = TrackerConfig(sigma_frames=3, sigma_per_shot=per_shot)
        runs[per_shot] = list(Tracker(model3d, config=cfg).track(ReplayFrame(i, i / 25.0, f)
                                                                  for i, f in enumerate(frames)))
    on, off = runs[True], runs[False]
    assert all(r.success for r in on + off)
    assert on[6].status == "detected" and off[6].status == "detected"  # the cut restarts the track either way
    held_a = on[5].shape_params
    assert np.array_equal(off[11].shape_params, held_a)  # off: the first person's sigma goes on
    shift = np.abs(on[11].shape_params - held_a).max()
    print(f"sigma after the cut moved by {shift:.3f} (max over units)")
    assert shift > 0.01  # on: the second person's own estimate
    assert np.array_equal(on[10].shape_params, on[11].shape_params)  # and held again once estimated


def test_searches_hold_the_running_median_while_the_shape_is_estimated(synth_model3d):
    """``TrackerConfig.sigma_running``: once the person's shape has one estimate, every tracked search of a clear
    face holds the shape units at the median of the estimates so far, as it holds the final median after
    ``sigma_frames``, and each frame reports the median with its own estimate in (what the next search holds);
    off, the searches before the hold search them."""
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import Tracker, TrackerConfig

    model3d, candide = synth_model3d
    rng = np.random.default_rng(SEED + 7)
    faces, _, _, _ = synth3d.posed_faces(candide, 4, rng, yaw_sd=0.0, pitch_sd=0.0, observable=OBSERVABLE)

    class Recording(Tracker):
        def search_from(self, image, start, shape_params=None, **kw):
            self.held.append(None if shape_params is None else np.array(shape_params))
            return super().search_from(image, start, shape_params, **kw)

    plain = Tracker(model3d)
    face, fit = next((f, r) for f in faces if (r := plain.detect_and_fit(f)[0]).confidence >= 0.5)
    assert not fit.dim  # a clear face
    for running in (True, False):
        tracker = Recording(model3d, config=TrackerConfig(sigma_frames=4, sigma_running=running))
        tracker.held = []
        results = list(tracker.track(ReplayFrame(i, i / 25.0, face) for i in range(8)))
        assert all(r.success for r in results)
        assert len(tracker.held) == 8  # the detection's second search (frame 0), then one per tracked frame
        assert tracker.held[0] is None  # no estimate yet
        if running:
            assert all(h is not None for h in tracker.held[1:])  # held from the first estimate on
            for r, h in zip(results[:-1], tracker.held[1:]):  # a frame reports the median with its own estimate
                assert np.array_equal(r.shape_params, h)  # in, which the next frame's search holds
        else:
            assert all(h is None for h in tracker.held[1:4])  # searched until the 4 estimates are in
            assert all(h is not None for h in tracker.held[4:])


def test_weighted_median_matches_the_median_of_repeated_values():
    """``weighted_median`` with integer weights is the lower median of each value repeated weight times (a slow
    reference), column by column; equal weights give the lower middle value of an even count."""
    from aamtrack.track.tracker import weighted_median

    rng = np.random.default_rng(SEED)
    for n in (1, 2, 5, 8, 13):
        values = rng.normal(size=(n, 4))
        weights = rng.integers(1, 6, n)
        want = [np.sort(np.repeat(values[:, j], weights))[(weights.sum() - 1) // 2] for j in range(4)]
        np.testing.assert_array_equal(weighted_median(values, weights.astype(float)), want)
    np.testing.assert_array_equal(weighted_median(np.array([[4.0], [1.0], [3.0], [2.0]]), np.ones(4)), [2.0])


def test_the_person_shape_weighs_frontal_frames_most(synth_model3d):
    """``TrackerConfig.sigma_yaw_weight``: estimates read at a turned pose count for little while frontal ones are
    there, even when they are the majority; a shot turned throughout still keeps its estimates (relative weights,
    no underflow at 1.5 rad); 0 gives the plain median."""
    from dataclasses import replace

    from aamtrack.track.tracker import Tracker

    model3d, _ = synth_model3d
    tracker = Tracker(model3d)
    frontal, turned = np.full(3, 0.2), np.full(3, -0.4)
    samples = [frontal] * 4 + [turned] * 7
    yaws = [0.02, -0.05, 0.08, 0.0] + [0.6] * 7
    np.testing.assert_allclose(tracker._person(samples, yaws), frontal)
    assert tracker.config.sigma_yaw_weight > 0  # on by default
    # turned throughout (yaw 1.5-1.6 rad: absolute weights exp(-56) and less): weighed relative to the most frontal
    # one, which leads (the next is weighed 0.22 of it, the rest less), rather than all underflowing to 0
    turned_only = [turned + 0.01 * k for k in range(5)]
    np.testing.assert_allclose(tracker._person(turned_only, [1.5, 1.52, 1.55, 1.58, 1.6]), turned)
    np.testing.assert_allclose(tracker._person(turned_only[::-1], [1.6, 1.58, 1.55, 1.52, 1.5]), turned)
    plain = Tracker(model3d, config=replace(tracker.config, sigma_yaw_weight=0.0))
    np.testing.assert_allclose(plain._person(samples, yaws), turned)  # the majority, read with the turn
