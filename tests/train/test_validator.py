"""The landmark validator's learning (``aamtrack.train.validator``): synthetic data with a known answer."""

import numpy as np
import pytest

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


def test_held_out_logits_see_the_errors_the_training_fit_hides():
    """``held_out_logits``: on a rule the validator cannot learn perfectly, the samples scored by fits that did
    not see them err at least about as often as fresh samples do (more: each fit saw half the samples), where the
    samples' own fit flatters itself."""
    from aamtrack.train.validator import held_out_logits

    rng = np.random.default_rng(SEED)
    S, Z, y = _problem(rng, n=1600, d=400)  # many descriptors for the samples: room to overfit
    names = ("a", "b", "c")
    held = held_out_logits(S[:800], Z[:800], y[:800], names, l2=0.001)
    own = landmark_validator_fit(S[:800], Z[:800], y[:800], names, l2=0.001)
    own_err = np.mean([(own.logit(s, z) >= 0) != (t > 0.5) for s, z, t in zip(S[:800], Z[:800], y[:800])])
    fresh_err = np.mean([(own.logit(s, z) >= 0) != (t > 0.5) for s, z, t in zip(S[800:], Z[800:], y[800:])])
    held_err = np.mean((held >= 0) != (y[:800] > 0.5))
    assert own_err < 0.5 * fresh_err  # the training fit flatters itself (here 0 against 0.19)
    assert 0.8 * fresh_err < held_err < 2.0 * fresh_err  # held out: the error on fresh samples (here 0.27)


def test_false_accept_shift_leaves_the_rate_asked():
    """``false_accept_shift``: after lowering by the shift, at most the asked share of negatives keeps a logit
    of 0 or more, and one more would have stayed with a smaller shift; nothing to do when few enough are."""
    from aamtrack.train.validator import false_accept_shift

    rng = np.random.default_rng(SEED)
    neg = rng.normal(-2.0, 1.5, 1000)
    for rate in (0.003, 0.01, 0.05):
        shift = false_accept_shift(neg, rate)
        assert np.sum(neg - shift >= 0) <= rate * len(neg) and shift > 0
        assert np.sum(neg - 0.999 * shift >= 0) > np.sum(neg - shift >= 0)  # not lowered more than needed
    assert false_accept_shift(neg, 0.5) == 0.0  # already fewer than half at or above 0
    assert false_accept_shift(np.array([]), 0.01) == 0.0


def test_dim_copies_are_dark_or_flat_and_noisy_and_keep_the_image_format():
    """``dim_copy``: every copy has less contrast and more noise than the image (``signal_to_noise`` well below
    the original's, most below the models' dim threshold of 4.5 for a face of 100 px)."""
    import cv2

    from aamtrack.landmark_cascade import signal_to_noise
    from aamtrack.train.validator import dim_copy, dark_noise_image

    rng = np.random.default_rng(SEED)
    yy, xx = np.mgrid[0:200, 0:200].astype(np.float32)
    gray = cv2.GaussianBlur(rng.uniform(0, 255, (200, 200)).astype(np.float32), (0, 0), 6.0) * 2.0 - 128.0
    gray = np.clip(gray + 0.3 * xx, 0, 255).astype(np.float32)
    box = np.array([[50.0, 50.0], [150.0, 150.0]])
    snr0 = signal_to_noise(gray, 1.0, box)
    snr = []
    for _ in range(30):
        out = dim_copy(gray, 100.0, rng)
        assert out.shape == gray.shape and out.dtype == np.float32
        assert out.std() < gray.std()  # less contrast (noise included)
        snr.append(signal_to_noise(out, 1.0, box))
    assert max(snr) < 0.5 * snr0 and np.median(snr) < 4.5
    dark = dark_noise_image((60, 70), rng)
    assert dark.shape == (60, 70) and dark.dtype == np.float32 and 5 < dark.mean() < 45 and dark.std() > 2


def test_soft_copies_are_softer_and_keep_the_image_format():
    """``soft_copy``: every copy looks softer than the image (``sharpness`` up) and stays float32 of its shape."""
    import cv2

    from aamtrack.landmark_cascade import sharpness
    from aamtrack.train.validator import soft_copy

    rng = np.random.default_rng(SEED)
    gray = cv2.GaussianBlur(rng.uniform(0, 255, (200, 200)).astype(np.float32), (0, 0), 1.0)
    pts = np.array([[50.0, 50.0], [150.0, 150.0]])
    s0 = sharpness(gray, 1.0, pts)
    for _ in range(20):
        out = soft_copy(gray, 100.0, rng)
        assert out.shape == gray.shape and out.dtype == np.float32
        assert sharpness(out, 1.0, pts) > s0 + 0.05


def test_occluded_copies_cover_part_of_the_face_and_nothing_far_from_it():
    """``occluded_copy``: each copy changes a connected part of the image near the face's centre (at most about
    a face's extent away), covering between a few percent and about half of the face's box; nothing changes far
    from the face; float32 of the image's shape; ``donors`` patches are used."""
    from scipy import ndimage

    from aamtrack.train.validator import occluded_copy

    rng = np.random.default_rng(SEED)
    gray = rng.uniform(60, 200, (240, 320)).astype(np.float32)
    donors = [np.full((240, 320), 10.0, np.float32)]  # a donor far from every pixel of the image
    eye = 60.0
    centre = np.array([160.0, 120.0])
    face = np.zeros(gray.shape, bool)
    face[int(120 - 1.0 * eye):int(120 + 1.5 * eye), int(160 - 1.2 * eye):int(160 + 1.2 * eye)] = True
    shares, dark = [], 0
    for _ in range(40):
        out = occluded_copy(gray, eye, rng, donors=donors, centre=centre)
        assert out.shape == gray.shape and out.dtype == np.float32 and 0 <= out.min() and out.max() <= 255
        changed = np.abs(out - gray) > 0.5
        assert not changed[~ndimage.binary_dilation(face, iterations=int(0.8 * eye))].any()  # far from the face
        lab, n = ndimage.label(ndimage.binary_closing(changed, iterations=2))  # a fill may equal a pixel by chance
        sizes = np.bincount(lab.ravel())[1:]
        assert 1 <= np.sum(sizes > 0.02 * eye ** 2) <= 2  # one or two occluders
        shares.append(changed[face].mean())
        dark += np.mean(out[changed] < 15) > 0.5
    assert 0.01 < np.median(shares) < 0.35 and max(shares) < 0.8
    assert 5 <= dark <= 35  # about half from the donor (all 10), the rest flat grey levels


def test_tiny_dim_copies_shrink_the_face_to_its_far_size_with_its_box_and_points():
    """``tiny_dim_copy``: the photo shrunk until the face is 10-40 px between the outer eye corners, padded to at
    least 240x320, and its box and points shrunk with it: a bright blob drawn at a point of the photo is found
    at the returned point (its centroid, median over draws: the copy's sensor noise moves single draws)."""
    import cv2

    from aamtrack.train.validator import tiny_dim_copy

    rng = np.random.default_rng(SEED)
    H, W = 900, 1200
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    points = np.array([[400.0, 450.0], [800.0, 450.0]])  # the "outer eye corners": 400 px apart
    gray = np.zeros((H, W), np.float32)
    for x, y in points:
        gray += 255.0 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * 60.0 ** 2))
    box = np.array([350.0, 300.0, 500.0, 500.0])
    errs = []
    for _ in range(12):
        out, sbox, spts = tiny_dim_copy(np.clip(gray, 0, 255), box, points, 400.0, rng)
        assert out.dtype == np.float32 and out.shape[0] >= 240 and out.shape[1] >= 320
        f = (spts[1, 0] - spts[0, 0]) / 400.0  # the copy's true factor across (its height has its own)
        fy = sbox[3] / box[3]
        assert 10.0 <= 400.0 * f <= 40.0 and abs(fy - f) <= 0.5 / W + 0.5 / H
        assert np.allclose(sbox[[0, 2]], [(box[0] + 0.5) * f - 0.5, box[2] * f])
        assert np.allclose(sbox[1], (box[1] + 0.5) * fy - 0.5)
        assert np.allclose(spts[:, 1], (points[:, 1] + 0.5) * fy - 0.5)
        x0, y0 = np.round(spts[0]).astype(int)
        r = max(3, int(round(2.5 * 60.0 * f)))
        win = cv2.GaussianBlur(out, (0, 0), 1.0)[y0 - r:y0 + r + 1, x0 - r:x0 + r + 1].astype(np.float64)
        win = np.clip(win - np.median(out), 0, None)
        gy, gx = np.mgrid[y0 - r:y0 + r + 1, x0 - r:x0 + r + 1]
        errs.append(np.hypot((win * gx).sum() / win.sum() - spts[0, 0], (win * gy).sum() / win.sum() - spts[0, 1]))
    assert np.median(errs) < 0.3  # under a third of a pixel (0.15 measured; half a pixel off would read ~0.45)


def test_a_shrunk_photo_reports_each_axis_true_factor_so_points_land_on_their_pixels():
    """``_shrunk`` rounds the image's size, so each axis has its own factor (new size over old); a blob drawn at a
    point of the photo is found where that factor maps it (noise-free, centroid): what the far faces' labels
    (``tiny_dim_copy``) are moved by. The factor asked for maps it half a pixel's worth off at this size."""
    from aamtrack.imaging import level_shift
    from aamtrack.train.validator import _shrunk

    H, W = 810, 1070
    f = 36.5 / W  # the width rounds from 36.5 to 36 (or 37): the worst case
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    point = np.array([900.0, 700.0])
    gray = 255.0 * np.exp(-((xx - point[0]) ** 2 + (yy - point[1]) ** 2) / (2 * 40.0 ** 2)).astype(np.float32)
    small, fxy = _shrunk(gray, f)
    assert np.allclose(fxy, [small.shape[1] / W, small.shape[0] / H]) and abs(fxy[0] - f) > 0.4 / W
    gy, gx = np.mgrid[0:small.shape[0], 0:small.shape[1]]
    found = np.array([(small * gx).sum(), (small * gy).sum()]) / small.sum()
    at = point * fxy + level_shift(fxy)
    assert np.abs(found - at).max() < 0.05  # a twentieth of a pixel (area resampling keeps the centroid)
    assert np.abs(found - (point * f + level_shift(f))).max() > 0.2  # the factor asked for: off


def test_noise_frames_are_grey_noise_of_the_stated_levels():
    """``noise_frame``: float32 of the shape, mean 20-160, its pixels' spread 5-40 grey levels (less where blurred,
    never flat), within 0-255."""
    from aamtrack.train.validator import noise_frame

    rng = np.random.default_rng(SEED)
    for _ in range(20):
        n = noise_frame((120, 160), rng)
        assert n.shape == (120, 160) and n.dtype == np.float32 and n.min() >= 0 and n.max() <= 255
        assert 15 < n.mean() < 165 and 0.5 < n.std() < 42


def test_textured_noise_is_blotchy_at_the_stated_levels():
    """``textured_noise``: float32 of the shape within 0-255, mean 40-160 and spread 5-40 grey levels before
    clipping (clipping only narrows them), and coarse: neighbouring pixels nearly equal (blurred by 3 px or more,
    or mostly the coarse octaves), unlike white noise of the same spread."""
    from aamtrack.train.validator import textured_noise

    rng = np.random.default_rng(SEED)
    for _ in range(30):
        n = textured_noise((120, 160), rng)
        assert n.shape == (120, 160) and n.dtype == np.float32 and n.min() >= 0 and n.max() <= 255
        assert 30 < n.mean() < 170 and 2 < n.std() < 41
        step = np.diff(n, axis=1).std() / n.std()  # white noise: sqrt(2) = 1.41
        assert step < 0.6, step


def test_tiny_dim_negatives_found_ahead_are_the_ones_drawn_and_a_changed_sequence_is_caught():
    """``TinyDimNegatives``: the far faces and noise frames come in photo order from their own seed, the noise
    frames' Haar boxes found ahead (on another thread with workers) belong to the frames the validator draws; if
    the draws change after the boxes were found (here a photo's labels: its far face is shrunk by another factor,
    which draws another number of noise values), the validator is stopped rather than handed another frame's
    boxes."""
    from aamtrack.train.pipeline import TinyDimNegatives, TrainConfig

    rng = np.random.default_rng(SEED)
    gray = [rng.uniform(0, 255, (480, 560)).astype(np.float32) for _ in range(5)]
    pts = rng.uniform(200, 300, (5, 68, 2))
    pts[:, 36], pts[:, 45] = (230.0, 240.0), (260.0, 240.0)  # outer eye corners 30 px apart
    boxes = np.tile([180.0, 180.0, 140.0, 140.0], (5, 1))
    boxes[3] = np.nan  # no box: no far face from this photo
    cfg = TrainConfig(dim_tiny=1)
    one = list(TinyDimNegatives(gray, boxes, pts, 5, cfg).draws())
    two = list(TinyDimNegatives(gray, boxes, pts, 5, cfg, workers=2).draws())
    assert [d[0] for d in one] == [0, 1, 2, 4]
    for a, b in zip(one, two, strict=True):
        assert all(np.array_equal(x, y) for x, y in zip(a[1:], b[1:], strict=True))
    changed = TinyDimNegatives(gray, boxes, pts, 5, cfg, workers=2)
    changed.found()
    changed.pts = pts.copy()
    changed.pts[1, 45] = (380.0, 240.0)  # 150 px: shrunk 5 times as much
    with pytest.raises(RuntimeError, match="photo 1"):
        list(changed.draws())


def test_textured_negatives_give_each_photo_the_same_frame_whichever_validator_asks_first():
    """``TexturedNegatives``: a photo's frame comes from its own seed (the landmark validator and the validator for
    soft faces ask in their own orders and must see the same frames), Haar's boxes on it are found once and lie in
    the frame, at most ``textured_boxes`` of them, largest first; another photo gets another frame."""
    from aamtrack.train.pipeline import TexturedNegatives, TrainConfig

    shapes = [(240, 200), (200, 240), (240, 240)] * 4
    # b's boxes found on a thread of its own (``train.workers.beside``) while this one goes on
    a, b = TexturedNegatives(TrainConfig(), shapes), TexturedNegatives(TrainConfig(), shapes, workers=2)
    order = np.random.default_rng(SEED).permutation(len(shapes))
    first = [a.get(i) for i in range(len(shapes))]
    again = {i: b.get(i) for i in order}
    assert sum(len(boxes) for _, boxes in first) >= 4  # Haar finds "faces" in such frames (10 boxes in these)
    for i, (frame, boxes) in enumerate(first):
        other, other_boxes = again[i]
        assert frame.shape == shapes[i] and np.array_equal(frame, other) and np.array_equal(boxes, other_boxes)
        assert len(boxes) <= TrainConfig().textured_boxes
        assert np.all(boxes[:, :2] >= 0) and np.all(boxes[:, 0] + boxes[:, 2] <= shapes[i][1] + 1)
        assert np.all(boxes[:, 1] + boxes[:, 3] <= shapes[i][0] + 1)
        assert np.all(np.diff(boxes[:, 2] * boxes[:, 3]) <= 0)  # largest first
    assert a.get(2)[1] is a.found()[2]  # found once, kept
    assert not np.array_equal(first[1][0][:200, :200], first[2][0][:200, :200])
