"""The landmark cascade (supervised descent on local descriptors): its face frame, and learning it on synthetic
faces with known landmarks recovers known displacements."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from aamtrack.landmark_cascade import DescriptorSpec, outside, similarity_to
from aamtrack.metrics import nme
from aamtrack.train.landmarks import learn_landmark_cascade, made_starts, reference_shape
from tests.synth import random_faces

SEED = 23


def test_similarity_to_recovers_a_known_similarity():
    rng = np.random.default_rng(SEED)
    ref = rng.normal(size=(68, 2))
    ref -= ref.mean(0)
    a, s, t = 0.7, 2.5, np.array([40.0, -3.0])
    M_true = s * np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    M, c = similarity_to(ref, ref @ M_true + t)
    assert np.abs(M - M_true).max() < 1e-12  # exact for an exact similarity
    assert np.abs(c - t).max() < 1e-12


def test_reference_shape_is_centred_level_and_unit():
    rng = np.random.default_rng(SEED)
    _, pts = random_faces(6, rng, size=(120, 120), scale=60.0)
    ref = reference_shape(pts)
    assert np.abs(ref.mean(0)).max() < 1e-9
    d = ref[45] - ref[36]
    assert abs(np.hypot(*d) - 1.0) < 1e-9 and abs(d[1]) < 1e-9  # outer eye corners 1 apart, level


def _errors(truth, rng, size):
    """Start errors: a per-face shift and per-point noise of half that size, in pixels."""
    return truth + rng.normal(0, size, (len(truth), 1, 2)) + rng.normal(0, size / 2, truth.shape)


def test_cascade_recovers_known_displacements_on_synthetic_faces():
    """Learned on 80 rendered faces whose "fits" are the labels plus known errors, applied to 20 new faces started
    off by about 0.09 eye distances: the points end more than twice as close (0.093 -> 0.035 when written)."""
    rng = np.random.default_rng(SEED)
    images, truth = random_faces(100, rng, size=(150, 150), scale=85.0)
    gray = [im.astype(np.float32) for im in images]
    train, test = slice(0, 80), slice(80, 100)
    eye = np.linalg.norm(truth[:, 45] - truth[:, 36], axis=1).mean()
    fits = _errors(truth[train], rng, 0.07 * eye)
    spec = DescriptorSpec(cells=2, cell=4, bins=6)
    cascade, record = learn_landmark_cascade(gray[train], [1.0] * 80, truth[train], fits, np.arange(80),
                                             np.arange(80), spec=spec, halves=(0.25, 0.18, 0.14), n_starts=16,
                                             n_components=24, rng=np.random.default_rng(SEED + 1))
    assert cascade.n_stages == 3 and len(record) == 3
    starts = _errors(truth[test], np.random.default_rng(SEED + 2), 0.07 * eye)
    before = nme(starts, truth[test])
    after = nme(np.array([cascade.apply(g, 1.0, s) for g, s in zip(gray[test], starts)]), truth[test])
    assert before.mean() > 0.08  # the starts really are off
    assert after.mean() < 0.45 * before.mean()  # and the cascade takes them more than half the way
    repeated = replace(cascade, repeats=2)
    last = replace(cascade, repeats=0)
    for g, s in zip(gray[test], starts):  # compiled against numpy steps, points and the validator's features
        for c in (cascade, repeated):
            (x, z, prior), (x_slow, z_slow, prior_slow) = c.run(g, 1.0, s), c.run_slow(g, 1.0, s)
            # px: the compiled cascade is the numpy one, float32 sums and its int16 regressors aside (0.00055 px
            # when written); the descriptors read at those points move with them
            assert np.abs(x - x_slow).max() < 1e-3
            assert np.abs(prior - prior_slow).max() < 1e-3 and np.abs(prior).max() > 1e-3  # px, and it moved them
            assert z.shape == (68 * 24,) and np.abs(z - z_slow).max() < 5e-4 * max(1.0, np.abs(z_slow).max())
            assert np.array_equal(c.apply(g, 1.0, s), x)
        # repeats: the last stage run again on the points it left, twice; z is the last pass's
        x2, z2, _ = repeated.run(g, 1.0, s)
        y = cascade.apply(g, 1.0, s)
        for _ in range(2):
            y, z_last, _ = last.run(g, 1.0, y, first=last.n_stages - 1)
        assert np.abs(x2 - y).max() < 1e-9 and np.array_equal(z2, z_last)
        # ``read``: the last stage's descriptors at given points, as the last stage run from them reads them
        # (compiled against numpy: float32 sums in another order); with a gain as the image multiplied by it
        _, z_from, _ = last.run(g, 1.0, y, first=last.n_stages - 1)
        assert np.abs(last.read(g, 1.0, y) - z_from).max() < 5e-4 * max(1.0, np.abs(z_from).max())
        assert np.abs(last.read(0.2 * g, 1.0, y, gain=5.0) - last.read(g, 1.0, y)).max() < 1e-3
        assert np.abs(x2 - cascade.apply(g, 1.0, s)).max() > 1e-3  # and the repeats did move the points
        # a gain reads the descriptors as the image multiplied by it would give them (the floor divided instead);
        # compiled and numpy alike
        dark = 0.2 * g
        x_gain, z_gain, _ = cascade.run(dark, 1.0, s, gain=5.0)
        x_times, z_times, _ = cascade.run(5.0 * dark, 1.0, s)
        assert np.abs(x_gain - x_times).max() < 1e-3 and np.abs(z_gain - z_times).max() < 1e-4  # float32 sums
        x_slow, z_slow, _ = cascade.run_slow(dark, 1.0, s, gain=5.0)
        assert np.abs(x_gain - x_slow).max() < 1e-3
        assert np.abs(cascade.apply(dark, 1.0, s) - x_gain).max() > 1e-2  # px: without it the dark face moves less
        # a face 40% past the image's left edge: the points whose patch lies wholly outside read the stage's mean
        # descriptor (z = 0), compiled and numpy alike, rather than the border smeared over their patch
        cut = s - [s[:, 0].min() + 0.4 * np.ptp(s[:, 0]), 0.0]
        k = last.n_stages - 1
        gone = outside(g, 1.0, cut, last.halves[k], similarity_to(last.ref, cut)[0])
        assert 0 < gone.sum() < 68  # the premise: some patches wholly outside, most not
        z_cut = last.read(g, 1.0, cut, blank=True).reshape(68, -1)
        assert not z_cut[gone].any() and np.abs(z_cut[~gone]).sum(1).min() > 0
        _, z_run, _ = last.run(g, 1.0, cut, first=k, repeats=0, blank=True)
        assert np.abs(z_run.reshape(68, -1) - z_cut).max() < 5e-4 * max(1.0, np.abs(z_cut).max())
        (x, _, _), (x_slow, _, _) = cascade.run(g, 1.0, cut, blank=True), cascade.run_slow(g, 1.0, cut, blank=True)
        assert np.abs(x - x_slow).max() < 1e-3  # px
        assert np.abs(x - cascade.run(g, 1.0, cut)[0]).max() > 1e-3  # and without blanking the points go elsewhere


def test_made_starts_carry_library_errors_in_the_face_frame():
    """A library error given in the face frame lands turned and scaled with each face."""
    rng = np.random.default_rng(SEED)
    _, truth = random_faces(3, rng, size=(120, 120), scale=60.0, roll_sd=0.5)
    ref = reference_shape(truth)
    lib = np.zeros((1, 68, 2))
    lib[0, 30] = [0.1, 0.0]  # the nose tip 0.1 eye distances along the eyes' axis
    out = made_starts(truth, ref, lib, 1, rng, error_scale=(1.0, 1.0), angle=0.0, log_scale=0.0, shift=0.0)
    for P, X in zip(truth, out[:, 0]):
        moved = X - P
        assert np.abs(np.delete(moved, 30, 0)).max() < 1e-9  # the other points stay
        axis = P[45] - P[36]
        M, _ = similarity_to(ref, P)
        expected = np.array([0.1, 0.0]) @ M
        assert np.abs(moved[30] - expected).max() < 1e-9
        cos = moved[30] @ axis / (np.linalg.norm(moved[30]) * np.linalg.norm(axis))
        assert cos > 0.95  # along this face's own eye axis, whatever its roll


def test_shape_features_are_the_points_in_the_reference_frame():
    """``shape_features``: zero for the reference moved by any similarity; a deformation comes back in reference
    units, undone of the face's roll, scale and position; the compiled cascade computes the same (a cascade whose
    only weights read the shape moves points by exactly S s @ M)."""
    from aamtrack.landmark_cascade import LandmarkCascade, shape_features

    rng = np.random.default_rng(SEED)
    _, pts = random_faces(4, rng, size=(120, 120), scale=60.0)
    ref = reference_shape(pts)
    a, s, t = 0.4, 80.0, np.array([60.0, 50.0])
    M_true = s * np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    P = ref @ M_true + t
    M, _ = similarity_to(ref, P)
    assert np.abs(shape_features(ref, P, M)).max() < 1e-12
    bump = np.zeros_like(ref)
    bump[8] = [0.0, 0.05]  # the chin 0.05 eye distances down, in the face's frame
    bump[0] = [-0.03, 0.0]
    bump -= bump.mean(0)  # about the centroid, as the features are
    Q = (ref + bump) @ M_true + t
    M, _ = similarity_to(ref, Q)
    feats = shape_features(ref, Q, M)
    # the bump, in reference units whatever the face's roll and size (the similarity fitted to the bumped points
    # absorbs a little of it)
    assert np.abs(feats - bump.reshape(-1)).max() < 0.003
    spec = DescriptorSpec(cells=2, cell=2, bins=4)
    S = rng.normal(0, 0.1, (1, 136, 136)).astype(np.float32)
    zero = LandmarkCascade(ref, spec, (0.2,), np.zeros((1, spec.size), np.float32),
                           np.zeros((1, spec.size, 3), np.float32), np.zeros((1, 136, 68 * 3), np.float32),
                           np.zeros((1, 136)), S)
    image = np.zeros((120, 120), np.float32)
    moved, _, prior = zero.run(image, 1.0, Q)
    assert np.abs(moved - (Q + (S[0] @ feats).reshape(-1, 2) @ M)).max() < 1e-4  # px (float32 features)
    assert np.abs(zero.apply_slow(image, 1.0, Q) - moved).max() < 1e-4
    assert zero.shape_from == 0 and np.abs(prior - (moved - Q)).max() < 1e-4  # the whole move is the shape's


def _blurred(images, truth, eyes_sigma):
    """Each image blurred by ``eyes_sigma`` of its own outer eye distance."""
    out = []
    for im, P in zip(images, truth):
        out.append(cv2.GaussianBlur(im, (0, 0), eyes_sigma * float(np.linalg.norm(P[45] - P[36]))))
    return out


def test_sharpness_tells_blurred_faces_whatever_their_contrast_and_noise():
    """``sharpness`` rises with blur on every face, does not move with the image's contrast or brightness, and
    sensor noise does not make a blurred face look sharp (both of its blurs are wider than a pixel)."""
    from aamtrack.landmark_cascade import sharpness

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(10, rng, size=(150, 150), scale=85.0)
    gray = [im.astype(np.float32) for im in images]
    soft_gray = _blurred(gray, truth, 0.05)
    sharp = np.array([sharpness(g, 1.0, P) for g, P in zip(gray, truth)])
    soft = np.array([sharpness(g, 1.0, P) for g, P in zip(soft_gray, truth)])
    assert (soft > sharp + 0.1).all() and (soft <= 1.0).all() and (sharp > 0).all()
    dim = np.array([sharpness(0.3 * g + 40.0, 1.0, P) for g, P in zip(gray, truth)])
    assert np.abs(dim - sharp).max() < 1e-4  # a ratio of energies: contrast and offset cancel
    noisy = np.array([sharpness(g + rng.normal(0, 12, g.shape).astype(np.float32), 1.0, P)
                      for g, P in zip(soft_gray, truth)])
    assert noisy.min() > sharp.max()  # blurred and noisy: still softer than every sharp face
    small = cv2.resize(gray[0], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    assert abs(sharpness(small, 0.5, truth[0]) - sharpness(gray[0], 1.0, truth[0])) < 0.2  # via ``scale``
    assert sharpness(np.zeros((150, 150), np.float32), 1.0, truth[0]) == 0.0  # flat: nothing to call soft
    assert sharpness(gray[0], 1.0, truth[0] + 1000.0) == 0.0  # off the image


def test_signal_to_noise_reads_the_added_noise_and_calls_dim_noisy_faces_low():
    """``signal_to_noise``: with Gaussian noise well above the face's own fine texture, the box's contrast over
    (0.5 + the noise's sigma) to 15%; it falls as the noise grows; a face at a third of the light with noise of 6
    grey levels reads below the dim threshold the models use (4.5), the same face clean above 10."""
    from aamtrack.landmark_cascade import signal_to_noise

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(10, rng, size=(150, 150), scale=85.0)
    gray = [im.astype(np.float32) for im in images]
    by_sigma = []
    for sigma in (2.0, 8.0, 16.0):
        row = []
        for g, P in zip(gray, truth):
            lo, hi = np.floor(P.min(0)).astype(int), np.ceil(P.max(0)).astype(int) + 1
            contrast = float(g[max(lo[1], 0):hi[1], max(lo[0], 0):hi[0]].std())
            snr = signal_to_noise(g + rng.normal(0.0, sigma, g.shape).astype(np.float32), 1.0, P)
            if sigma >= 8:
                assert abs(snr / (contrast / (sigma + 0.5)) - 1) < 0.15  # the added noise's sigma, to 15%
            row.append(snr)
        by_sigma.append(row)
    by_sigma = np.array(by_sigma)
    assert (np.diff(by_sigma, axis=0) < 0).all()  # more noise, lower on every face
    for g, P in zip(gray, truth):
        assert signal_to_noise(g, 1.0, P) > 10.0
        assert signal_to_noise(0.3 * g + 40.0 + rng.normal(0.0, 6.0, g.shape).astype(np.float32), 1.0, P) < 4.5
    assert signal_to_noise(np.full((150, 150), 90, np.float32), 1.0, truth[0]) == 0.0  # flat: no signal
    assert signal_to_noise(gray[0], 1.0, truth[0] + 1000.0) == 0.0  # off the image


def test_descriptor_gain_lifts_dim_faces_to_the_target_but_not_noisy_ones():
    """``descriptor_gain``: a face of contrast (the points' box's standard deviation) above ``GAIN_TARGET_SD``
    gets 1; darkened, the target over its contrast, at most ``GAIN_MAX``; darkened with noise of 6 grey levels
    (twice ``GAIN_NOISE_CAP``), no gain whatever its contrast, with noise of 1.5 at most the cap over it."""
    from aamtrack.kernels import face_noise_and_deviation
    from aamtrack.landmark_cascade import GAIN_MAX, GAIN_NOISE_CAP, GAIN_TARGET_SD, descriptor_gain

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(6, rng, size=(150, 150), scale=85.0)
    for im, P in zip(images, truth):
        g = im.astype(np.float32)
        g *= np.float32(2 * GAIN_TARGET_SD / face_noise_and_deviation(g, 1.0, P)[1])  # contrast twice the target
        assert descriptor_gain(g, 1.0, P) == 1.0
        for k in (0.3, 0.8):  # contrast 0.6 and 1.6 of the target
            assert abs(descriptor_gain(k * g, 1.0, P) - max(1.0, 1.0 / (2 * k))) < 1e-3
        assert descriptor_gain(0.05 * g, 1.0, P) == GAIN_MAX  # 0.1 of the target: capped
        noisy = 0.2 * g + rng.normal(0.0, 2 * GAIN_NOISE_CAP, g.shape).astype(np.float32)
        assert descriptor_gain(noisy, 1.0, P) == 1.0
        some = 0.2 * g + rng.normal(0.0, GAIN_NOISE_CAP / 2, g.shape).astype(np.float32)
        assert 1.0 < descriptor_gain(some, 1.0, P) <= 2.0 * 1.2  # the cap over the noise (to 20%), not 2.5
    assert descriptor_gain(np.full((150, 150), 90, np.float32), 1.0, truth[0]) == 1.0  # flat
    assert descriptor_gain(images[0].astype(np.float32), 1.0, truth[0] + 1000.0) == 1.0  # off the image


def test_fine_noise_reads_the_noise_and_less_of_a_small_faces_detail_than_the_laplacian():
    """``fine_noise_sd``: white noise of sd 2, 5 and 12 on smooth faces read to within 10%; a small face without
    added noise (the face drawn 25 px wide, its detail at the pixel's scale) read at under 0.75 of what the
    Laplacian's estimate (``noise_sd``) reads (measured 0.60-0.66; hard7 in ``benchmarks/hard_clips.py`` 0.65)."""
    from aamtrack.kernels import face_noise_and_deviation
    from aamtrack.landmark_cascade import fine_noise_sd, noise_sd

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(4, rng, size=(150, 150), scale=85.0)
    for im, P in zip(images, truth):
        smooth = cv2.GaussianBlur(im.astype(np.float32), (0, 0), 2.0)
        for s in (2.0, 5.0, 12.0):
            noisy = smooth + rng.normal(0.0, s, smooth.shape).astype(np.float32)
            assert abs(fine_noise_sd(noisy, 1.0, P) - s) < 0.1 * s
    small, small_truth = random_faces(4, rng, size=(60, 60), scale=25.0)
    for im, P in zip(small, small_truth):
        g = im.astype(np.float32)
        fine = fine_noise_sd(g, 1.0, P)
        lap = noise_sd(face_noise_and_deviation(g, 1.0, P)[0])
        assert fine < 0.75 * lap, (fine, lap)
    assert fine_noise_sd(images[0].astype(np.float32), 1.0, truth[0] + 1000.0) == -1.0  # off the image


def test_descriptor_view_smooths_a_noisy_face_down_to_the_cap_and_leaves_a_clear_one():
    """``descriptor_view``: a clear face is read as it is, with ``descriptor_gain``; the same face with noise of
    4x ``GAIN_NOISE_CAP`` is read from a smoothed copy (the level itself untouched) whose noise is near the cap
    (the noise alone, smoothed so, has an sd within 30% of the cap: the Gaussian's rule is for a continuous
    grid) and whose descriptors lie nearer the clear face's than the noisy ones do."""
    from aamtrack.landmark_cascade import GAIN_NOISE_CAP, descriptor_gain, descriptor_view, descriptors

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(4, rng, size=(150, 150), scale=85.0)
    spec = DescriptorSpec()
    for im, P in zip(images, truth):
        g = cv2.GaussianBlur(im.astype(np.float32), (0, 0), 1.5)
        view, gain = descriptor_view(g, 1.0, P)
        assert view is g and gain == descriptor_gain(g, 1.0, P)
        noise = rng.normal(0.0, 4 * GAIN_NOISE_CAP, g.shape).astype(np.float32)
        noisy = g + noise
        before = noisy.copy()
        view, gain = descriptor_view(noisy, 1.0, P)
        assert view is not noisy and np.array_equal(noisy, before)
        flat_view, _ = descriptor_view(np.float32(128.0) + noise, 1.0, P)
        assert abs(float(flat_view[10:-10, 10:-10].std()) - GAIN_NOISE_CAP) < 0.3 * GAIN_NOISE_CAP
        M, _ = similarity_to(P, P)
        clear = descriptors(spec, g, 1.0, P, 6.0, M)
        d_noisy = np.linalg.norm(descriptors(spec, noisy, 1.0, P, 6.0, M) - clear)
        d_view = np.linalg.norm(descriptors(spec, view, 1.0, P, 6.0, M, gain=gain) - clear)
        assert d_view < 0.8 * d_noisy, (d_view, d_noisy)


def test_signal_to_noise_is_its_definition_on_odd_and_even_boxes():
    """``signal_to_noise`` (a partition at one index, the lower middle value taken as the lower half's largest)
    against its definition written the slow way: np.std of the points' box over 0.5 + np.median of the absolute
    5-point Laplacian / 0.6745 / sqrt(20), on boxes with an odd and an even number of interior pixels."""
    from aamtrack.landmark_cascade import signal_to_noise

    rng = np.random.default_rng(SEED)
    img = cv2.GaussianBlur(rng.uniform(0, 255, (120, 130)).astype(np.float32), (0, 0), 1.0)
    img += rng.normal(0.0, 4.0, img.shape).astype(np.float32)
    n_odd = 0
    for w, h in ((31, 40), (32, 41), (41, 33), (50, 50), (57, 61)):
        x0, y0 = rng.integers(0, 60, 2)
        pts = np.array([[x0, y0], [x0 + w - 1, y0 + h - 1], [x0 + w // 2, y0 + h // 3]], np.float64)
        c = img[y0:y0 + h, x0:x0 + w]
        lap = np.abs(4.0 * c[1:-1, 1:-1] - c[:-2, 1:-1] - c[2:, 1:-1] - c[1:-1, :-2] - c[1:-1, 2:])
        n_odd += lap.size % 2
        noise = float(np.median(lap)) / (0.6745 * np.sqrt(20.0))
        expected = float(c.astype(np.float64).std()) / (noise + 0.5)
        assert abs(signal_to_noise(img, 1.0, pts) / expected - 1.0) < 1e-6  # float32 medians, float64 sums
    assert 0 < n_odd < 5  # both kinds of box were checked


def test_soft_cascade_learned_on_blurred_faces_fits_them_better_and_the_gate_finds_them():
    """A second cascade learned on blurred copies alone, with the first one's descriptor components (``like``),
    fits held-out blurred faces closer than the sharp cascade does, and ``_soft_threshold`` puts its gate between
    the sharp and the blurred training faces' sharpness."""
    from aamtrack.landmark_cascade import sharpness
    from aamtrack.train.pipeline import _soft_threshold

    rng = np.random.default_rng(SEED)
    images, truth = random_faces(100, rng, size=(150, 150), scale=85.0)
    gray = [im.astype(np.float32) for im in images]
    soft_gray = _blurred(gray, truth, 0.06)
    train, test = slice(0, 80), slice(80, 100)
    eye = np.linalg.norm(truth[:, 45] - truth[:, 36], axis=1).mean()
    fits = _errors(truth[train], rng, 0.05 * eye)
    kw = dict(spec=DescriptorSpec(cells=2, cell=4, bins=6), halves=(0.25, 0.18, 0.14), n_starts=12, n_components=24)
    sharp, _ = learn_landmark_cascade(gray[train], [1.0] * 80, truth[train], fits, np.arange(80), np.arange(80),
                                      rng=np.random.default_rng(SEED + 1), **kw)
    soft, _ = learn_landmark_cascade(soft_gray[train], [1.0] * 80, truth[train], fits, np.arange(80), np.arange(80),
                                     rng=np.random.default_rng(SEED + 1), like=sharp, **kw)
    assert np.array_equal(soft.basis, sharp.basis) and np.array_equal(soft.basis_mean, sharp.basis_mean)
    assert np.array_equal(soft.ref, sharp.ref) and not np.array_equal(soft.regressors, sharp.regressors)
    with pytest.raises(ValueError, match="halves"):  # another cascade's components fit only its own stages
        learn_landmark_cascade(soft_gray[train], [1.0] * 80, truth[train], fits, np.arange(80), np.arange(80),
                               rng=np.random.default_rng(SEED), like=sharp, **{**kw, "halves": (0.25, 0.18)})
    starts = _errors(truth[test], np.random.default_rng(SEED + 2), 0.05 * eye)
    on_soft = [(g, s) for g, s in zip(soft_gray[test], starts)]
    e_sharp = nme(np.array([sharp.apply(g, 1.0, s) for g, s in on_soft]), truth[test]).mean()
    e_soft = nme(np.array([soft.apply(g, 1.0, s) for g, s in on_soft]), truth[test]).mean()
    assert e_soft < 0.9 * e_sharp  # blurred faces: the soft cascade is closer (0.0244 vs 0.0307 when written)
    images_all = gray[train] + soft_gray[train]
    owner = np.arange(160)
    above, rec = _soft_threshold(sharp, soft, images_all, [1.0] * 160, np.concatenate([truth[train]] * 2),
                                 np.concatenate([fits, fits]), owner)
    s = np.array([sharpness(images_all[i], 1.0, x) for i, x in zip(owner, np.concatenate([fits, fits]))])
    assert np.mean(s[:80] <= above) > 0.9 and np.mean(s[80:] > above) > 0.9  # sharp below, blurred above (all, when written)
    assert rec["nme_gated"] <= min(rec["nme_sharp_only"], rec["nme_soft_only"]) + 1e-12
