"""benchmarks/robustness.py: the image transforms move a rendered marker exactly as they move the points, the
mirror permutation fits a symmetric face, the blank-gap inserter keeps the reference aligned, the scores are
right on hand-made arrays, and the script runs end to end on synthetic faces."""

import json
import math
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import robustness as rb  # noqa: E402
from conftest import SEED  # noqa: E402

from aamtrack.mesh.landmarks import IBUG_MIRROR  # noqa: E402
from aamtrack.metrics import PIXEL_ORIGIN  # noqa: E402

SIZE = (200, 160)  # w, h


def _marker(p, *, size=SIZE, sigma=2.0) -> np.ndarray:
    """(h, w, 3) uint8: a Gaussian blob of ``sigma`` px centred at the sub-pixel point ``p`` (the package's 1-based
    pixel convention, ``PIXEL_ORIGIN``) on black."""
    w, h = size
    yy, xx = np.mgrid[0:h, 0:w] + PIXEL_ORIGIN
    g = 200.0 * np.exp(-((xx - p[0]) ** 2 + (yy - p[1]) ** 2) / (2 * sigma * sigma))
    return np.repeat(np.rint(g)[..., None], 3, axis=2).astype(np.uint8)


def _centroid(image) -> np.ndarray:
    g = image[..., 1].astype(np.float64)
    yy, xx = np.mgrid[0:g.shape[0], 0:g.shape[1]] + PIXEL_ORIGIN
    return np.array([(g * xx).sum() / g.sum(), (g * yy).sum() / g.sum()])


def _points(rng) -> np.ndarray:
    return rng.uniform(50.0, 110.0, size=(68, 2))


# --------------------------------------------------------------------------------------- geometric transforms


@pytest.mark.parametrize("degrees", [30.0, -30.0, 17.3])
def test_rotation_moves_points_with_a_rendered_marker(degrees):
    rng = np.random.default_rng(SEED)
    for _ in range(3):
        pts = _points(rng)
        image = _marker(pts[5])
        out, moved = rb.rotate(image, pts, degrees=degrees)
        assert out.shape == image.shape and out.dtype == np.uint8
        err = np.abs(_centroid(out) - moved[5]).max()
        assert err < 0.05  # px; the blob's own rounding error is about 0.005 px
        # a rotation keeps distances: the points' shape is only turned
        np.testing.assert_allclose(np.linalg.norm(moved[1:] - moved[0], axis=1),
                                   np.linalg.norm(pts[1:] - pts[0], axis=1), rtol=1e-12)
    # counter-clockwise on screen (y down): a point right of the centre moves up
    centre = ((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2)
    (_, y), = rb.affine_points([[centre[0] + 10.0, centre[1]]],
                               rb.cv2.getRotationMatrix2D(centre, 30.0, 1.0))
    assert y < centre[1]


@pytest.mark.parametrize("dx, dy", [(12.3, -7.6), (-20.0, 0.0)])
def test_translate_moves_points_with_a_rendered_marker(dx, dy):
    pts = _points(np.random.default_rng(SEED))
    out, moved = rb.translate(_marker(pts[5]), pts, dx=dx, dy=dy)
    np.testing.assert_allclose(moved - pts, np.broadcast_to([dx, dy], pts.shape), atol=1e-12)
    assert np.abs(_centroid(out) - moved[5]).max() < 0.05  # px


def test_shake_jumps_are_as_large_as_stated_and_stay_near():
    rng = np.random.default_rng(SEED)
    eye = 60.0
    o = rb.shake_offsets(2000, eye, rng)
    held = o[1:] - rb.SHAKE_HOLD * o[:-1]  # each frame's jump
    jump = np.linalg.norm(held, axis=1)
    assert np.all(o[0] == 0) and jump.max() <= rb.SHAKE_EYE * eye + 1e-9
    assert jump.max() > 0.95 * rb.SHAKE_EYE * eye and abs(np.median(jump) / (rb.SHAKE_EYE * eye) - 0.5) < 0.05
    # never far: |o| <= max jump / (1 - hold)
    assert np.linalg.norm(o, axis=1).max() <= rb.SHAKE_EYE * eye / (1 - rb.SHAKE_HOLD)
    # the frame-to-frame motion is as large as the jumps (not smoothed away)
    assert np.median(np.linalg.norm(np.diff(o, axis=0), axis=1)) > 0.4 * rb.SHAKE_EYE * eye


def test_mirror_moves_points_with_a_marker_and_renumbers_them():
    rng = np.random.default_rng(SEED)
    pts = _points(rng)
    image = _marker(pts[36])  # the subject's right outer eye corner
    out, moved = rb.mirror(image, pts)
    # after the flip it is the image-right outer corner: iBUG 45 of the mirrored face
    assert np.abs(_centroid(out) - moved[45]).max() < 0.05  # px
    assert moved[45, 0] == pytest.approx(SIZE[0] + 1 - pts[36, 0])  # 1-based: column 1 <-> column w


def test_mirror_twice_is_identity():
    rng = np.random.default_rng(SEED)
    image = rng.integers(0, 256, size=(SIZE[1], SIZE[0], 3), dtype=np.uint8)
    pts = _points(rng)
    once_img, once_pts = rb.mirror(image, pts)
    back_img, back_pts = rb.mirror(once_img, once_pts)
    assert np.array_equal(back_img, image)
    np.testing.assert_allclose(back_pts, pts, atol=1e-12)
    assert not np.array_equal(once_img, image)


def test_ibug_mirror_permutation_fits_a_symmetric_face():
    import synth

    perm = IBUG_MIRROR
    assert sorted(perm) == list(range(68))
    assert np.array_equal(perm[perm], np.arange(68))  # an involution
    # synth.face_layout is a left-right symmetric face in iBUG order (x right, centred on x = 0): flipped and
    # renumbered, it must be itself
    face = synth.face_layout()
    flipped = face * (-1.0, 1.0)
    np.testing.assert_allclose(flipped[perm], face, atol=1e-12)
    assert np.abs(flipped - face).max() > 0.3  # without the renumbering points land far from their labels
    assert {(36, 45), (39, 42), (48, 54), (0, 16), (17, 26), (31, 35)} <= {(i, int(perm[i])) for i in range(68)}


@pytest.mark.parametrize("scale", [0.5, 0.37, 0.23])
def test_shrink_moves_points_with_a_marker(scale):
    rng = np.random.default_rng(SEED)
    pts = _points(rng)
    image = _marker(pts[0], sigma=4.0)
    out, moved = rb.shrink(image, pts, scale=scale, fill=0)
    assert out.shape == image.shape
    assert np.abs(_centroid(out) - moved[0]).max() < 0.05  # px (half a pixel off would be 0.25-0.38 px)
    d_in = np.linalg.norm(pts[36] - pts[45])
    d_out = np.linalg.norm(moved[36] - moved[45])
    assert d_out == pytest.approx(scale * d_in, rel=0.01)  # the size is rounded to whole pixels
    with pytest.raises(ValueError, match="does not shrink"):
        rb.shrink(image, pts, scale=1.5)


def test_small30_variant_puts_the_eyes_30_px_apart():
    rng = np.random.default_rng(SEED)
    frames = [rng.integers(0, 256, size=(300, 400, 3), dtype=np.uint8) for _ in range(3)]
    pts = np.stack([_points(rng) for _ in range(3)])
    pts[:, 36] = (100.0, 100.0)
    pts[:, 45] = [(160.0, 100.0), (165.0, 100.0), (170.0, 100.0)]  # eye gaps 60, 65, 70 px
    small = next(v for v in rb.VARIANTS if v.name == "small30")
    _, each, _ = small.build(frames, pts, rng=rng, per_image=True)  # stills: every face to 30 px
    np.testing.assert_allclose(np.linalg.norm(each[:, 45] - each[:, 36], axis=1), 30.0, atol=0.1)
    _, video, _ = small.build(frames, pts, rng=rng, per_image=False)  # video: one scale, from the median (65)
    np.testing.assert_allclose(np.linalg.norm(video[:, 45] - video[:, 36], axis=1),
                               np.array([60.0, 65.0, 70.0]) * 30.0 / 65.0, atol=0.1)


def test_close_up_moves_points_with_a_marker_and_fills_the_frame():
    """close_up zooms about the face so its points span CLOSE_FILL of the frame's height, the face's centre at the
    frame's centre; a rendered marker lands where its point is moved to. The video zooms every frame alike (by the
    median face), stills each by its own."""
    rng = np.random.default_rng(SEED)
    pts = _points(rng)  # about 60 px tall, in a 160 px frame
    out, moved = rb.close_up(_marker(pts[5], sigma=1.5), pts, centre=pts.mean(0) - PIXEL_ORIGIN,
                             height=float(np.ptp(pts[:, 1])))
    assert np.ptp(moved[:, 1]) == pytest.approx(rb.CLOSE_FILL * SIZE[1], rel=1e-9)
    np.testing.assert_allclose(moved.mean(0) - PIXEL_ORIGIN, [(SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2], atol=1e-9)
    assert np.abs(_centroid(out) - moved[5]).max() < 0.05  # px
    frames = [rng.integers(0, 256, size=(160, 200, 3), dtype=np.uint8) for _ in range(3)]
    faces = np.stack([_points(rng) * k for k in (0.9, 1.0, 1.1)])
    variant = next(v for v in rb.VARIANTS if v.name == "close_up")
    _, each, _ = variant.build(frames, faces, rng=rng, per_image=True)
    np.testing.assert_allclose(np.ptp(each[:, :, 1], axis=1), rb.CLOSE_FILL * 160, rtol=1e-9)
    _, video, _ = variant.build(frames, faces, rng=rng, per_image=False)
    heights = np.ptp(faces[:, :, 1], axis=1)
    np.testing.assert_allclose(np.ptp(video[:, :, 1], axis=1), heights / np.median(heights) * 160, rtol=1e-9)


def test_dim_small_variant_shrinks_to_45_px_never_enlarges_and_darkens():
    rng = np.random.default_rng(SEED)
    frames = [np.full((300, 400, 3), 200, np.uint8) for _ in range(2)]
    pts = np.stack([_points(rng) for _ in range(2)])
    pts[:, 36] = (100.0, 100.0)
    pts[:, 45] = [(190.0, 100.0), (130.0, 100.0)]  # eye gaps 90 px (shrunk to 45) and 30 px (kept)
    dim = next(v for v in rb.VARIANTS if v.name == "dim_small")
    out, moved, is_face = dim.build(frames, pts, rng=rng, per_image=True)
    np.testing.assert_allclose(np.linalg.norm(moved[:, 45] - moved[:, 36], axis=1), [45.0, 30.0], atol=0.1)
    np.testing.assert_array_equal(moved[1], pts[1])  # a face already smaller than 45 px is not moved
    assert is_face.all() and all(o.shape == f.shape for o, f in zip(out, frames))
    # the light is dark_cast's: a flat 200 becomes about 200 x gain per channel, with noise of sd 8 on it
    centre = out[1][100:200, 150:250].reshape(-1, 3).astype(float)
    np.testing.assert_allclose(centre.mean(0), 200.0 * np.array(rb.DARK_GAINS), atol=1.0)
    assert 6.0 < centre.std(0).min() < 10.0  # sensor noise sd 8 (the blur is before it)


def test_small30_hd_variant_puts_the_eyes_30_px_apart_in_a_full_hd_frame():
    rng = np.random.default_rng(SEED)
    frames = [rng.integers(0, 256, size=(300, 400, 3), dtype=np.uint8) for _ in range(2)]
    pts = np.stack([_points(rng) for _ in range(2)])
    pts[:, 36] = (100.0, 100.0)
    pts[:, 45] = [(160.0, 100.0), (170.0, 100.0)]
    hd = next(v for v in rb.VARIANTS if v.name == "small30_hd")
    assert hd.stills and not hd.video
    out, each, _ = hd.build(frames, pts, rng=rng, per_image=True)
    assert all(im.shape == (1080, 1920, 3) for im in out)
    np.testing.assert_allclose(np.linalg.norm(each[:, 45] - each[:, 36], axis=1), 30.0, atol=0.1)
    # the shrunk photo sits in the middle of the grey frame, and the points moved with it
    small, moved = rb.shrink(frames[0], pts[0], scale=0.5, frame=(1920, 1080))
    assert small.shape == (1080, 1920, 3) and small[0, 0].tolist() == [rb.FILL_GREY] * 3
    np.testing.assert_array_equal(small[465:615, 860:1060], cv2.resize(frames[0], (200, 150),
                                                                      interpolation=cv2.INTER_AREA))
    np.testing.assert_allclose(moved, (pts[0] - 1.0 + 0.5) * 0.5 - 0.5 + [860, 465] + 1.0, atol=1e-9)


# -------------------------------------------------------------------------------------- photometric transforms


def test_photometric_transforms_keep_the_points_and_do_what_they_say():
    rng = np.random.default_rng(SEED)
    image = rng.integers(60, 200, size=(SIZE[1], SIZE[0], 3), dtype=np.uint8)
    pts = _points(rng)
    f = image.astype(np.float64)

    out, p = rb.dark_cast(image, pts)
    np.testing.assert_allclose(out.reshape(-1, 3).mean(0), f.reshape(-1, 3).mean(0) * rb.DARK_GAINS, atol=0.5)
    assert np.array_equal(p, pts) and p is not pts

    out, p = rb.low_contrast(image, pts)
    assert out.std() == pytest.approx(rb.CONTRAST * f.std(), rel=0.02)
    assert np.array_equal(p, pts)

    out, p = rb.blur(image, pts, sigma=3.0)
    assert out.std() < 0.2 * f.std()  # independent pixels: a sigma-3 blur averages about 100 of them
    assert out.mean() == pytest.approx(f.mean(), abs=1.0)
    assert np.array_equal(p, pts)

    grey = np.full_like(image, 128)
    out, p = rb.add_noise(grey, pts, sigma=25.0, rng=np.random.default_rng(SEED))
    assert (out.astype(np.float64) - 128).std() == pytest.approx(25.0, rel=0.03)
    assert np.array_equal(p, pts)

    out, p = rb.jpeg(image, pts, quality=20)
    assert out.shape == image.shape and not np.array_equal(out, image)
    assert out.mean() == pytest.approx(f.mean(), abs=2.0)
    assert np.array_equal(p, pts)

    out, p = rb.overexposed(image, pts, gain=2.0)
    np.testing.assert_array_equal(out, np.clip(2 * image.astype(np.int64), 0, 255))
    assert np.array_equal(p, pts)

    out, p = rb.side_light(image, pts)
    (cx, _), w = pts.mean(0), np.ptp(pts[:, 0])
    left, right = out[:, : int(cx - w)].astype(float), out[:, int(cx + w):].astype(float)
    fl, fr = f[:, : int(cx - w)], f[:, int(cx + w):]
    assert left.mean() == pytest.approx(1.3 * rb.SIDE_FLOOR * fl.mean(), rel=0.1)  # the dark side
    assert right.mean() == pytest.approx(min(255, 1.3 * fr.mean()), rel=0.1)  # the lit side
    assert np.array_equal(p, pts)

    out, p = rb.spotlight(image, pts)
    c = np.rint(pts.mean(0)).astype(int)
    at_face = out[c[1], c[0]].astype(float)
    np.testing.assert_allclose(at_face, np.clip(np.rint(np.rint(f[c[1], c[0]] * 1.68) * rb.SPOT_GAINS), 0, 255),
                               atol=1.0)  # the spot's centre: 0.08 + 1.6
    assert out[0, 0].max() < 0.2 * 255 and np.array_equal(p, pts)  # the corners are dark
    assert rb.spotlight(image[..., 0], pts)[0].shape == image.shape  # a grey image comes back BGR


# ----------------------------------------------------------------------------------------------- blank gaps


@pytest.mark.parametrize("kind", rb.BLANK_KINDS)
def test_blank_gap_keeps_the_reference_aligned(kind):
    rng = np.random.default_rng(SEED)
    n, n_blank = 9, 4
    # frame k is filled with k + 1 (so no face frame is black), its reference is k + a fixed random shape
    frames = [np.full((20, 30, 3), k + 1, np.uint8) for k in range(n)]
    shape = _points(rng)
    ref = np.stack([shape + k for k in range(n)])
    images, pts, is_face = rb.insert_gap(frames, ref, n_blank=n_blank, kind=kind, rng=rng)
    assert len(images) == len(pts) == len(is_face) == n + n_blank
    assert list(np.flatnonzero(~is_face)) == [4, 5, 6, 7]  # in the middle: before frame n // 2
    for j in np.flatnonzero(is_face):
        k = int(images[j][0, 0, 0]) - 1  # which original frame this is
        np.testing.assert_array_equal(pts[j], ref[k])
    assert [int(images[j][0, 0, 0]) - 1 for j in np.flatnonzero(is_face)] == list(range(n))  # order kept
    assert np.isnan(pts[~is_face]).all()
    blanks = np.stack([images[j] for j in np.flatnonzero(~is_face)]).astype(np.float64)
    if kind == "noise":
        assert blanks.std() > 60  # uniform 0..255: std 74
    else:
        expected = {"black": (0, 0, 0), "grey": (128, 128, 128), "colour": rb.SKIN_BGR}[kind]
        assert (blanks == np.asarray(expected, np.float64)).all()  # every pixel of every blank frame


def test_blank_gap_position_and_bad_kind():
    rng = np.random.default_rng(SEED)
    frames = [np.zeros((4, 4, 3), np.uint8)] * 5
    ref = np.zeros((5, 68, 2))
    _, _, is_face = rb.insert_gap(frames, ref, n_blank=2, kind="grey", rng=rng, at=0)
    assert list(is_face) == [False, False] + [True] * 5
    with pytest.raises(ValueError, match="unknown blank kind"):
        rb.insert_gap(frames, ref, n_blank=2, kind="purple", rng=rng)
    with pytest.raises(ValueError, match="outside"):
        rb.insert_gap(frames, ref, n_blank=2, kind="grey", rng=rng, at=9)


# ---------------------------------------------------------------------------------------------------- scores


def _face(eye_gap=10.0):
    shape = np.random.default_rng(SEED).uniform(0.0, 50.0, size=(68, 2))
    shape[36] = (20.0, 30.0)
    shape[45] = (20.0 + eye_gap, 30.0)
    return shape


def test_score_video_with_a_gap():
    # 6 frames: 0, 1 face; 2, 3 blank; 4, 5 face. Eye gap 10 px; tracked landmarks 0.5 px off in x: NME 0.05.
    ref = np.stack([_face()] * 6)
    is_face = np.array([True, True, False, False, True, True])
    ref[~is_face] = np.nan
    landmarks = np.stack([_face() + (0.5, 0.0)] * 6)
    landmarks[1] += 100.0  # a frame the tracker called lost: its landmarks must not count
    success = np.array([True, False, True, False, False, True])
    s = rb.score_video(success, landmarks, ref, is_face)
    assert s["n_face"] == 4 and s["n_blank"] == 2
    assert s["tracked"] == pytest.approx(0.5)  # frames 0 and 5 of the 4 face frames
    assert s["nme"] == pytest.approx(0.05)
    assert s["bias_px"] == pytest.approx([0.5, 0.0])  # frames 0 and 5 only
    assert s["blank_tracked"] == 1  # frame 2
    assert s["resume"] == 1  # frame 4 lost, frame 5 tracked
    never = rb.score_video(np.array([True, True, False, False, False, False]), landmarks, ref, is_face)
    assert math.isnan(never["resume"])
    plain = rb.score_video(np.ones(2, bool), landmarks[:2], ref[:2], np.ones(2, bool))
    assert plain["resume"] is None and plain["blank_tracked"] == 0 and plain["tracked"] == 1.0


def test_score_stills():
    ref = np.stack([_face()] * 3)
    landmarks = ref + np.array([0.5, 1.0, 0.0])[:, None, None] * (1.0, 0.0)  # NME 0.05, 0.10, (not fitted)
    s = rb.score_stills(np.array([True, True, False]), landmarks, ref)
    assert s["n_images"] == 3 and s["n_fitted"] == 2
    assert s["good"] == pytest.approx(1 / 3)  # 0.05 <= 0.08; 0.10 and the unfitted one are not
    assert s["nme"] == pytest.approx(0.075)
    assert s["bias_px"] == pytest.approx([0.75, 0.0])


def test_judge_goals():
    video = {"tracked": 1.0, "nme": 0.030, "n_blank": 0, "blank_tracked": 0, "resume": None}
    assert rb.judge("video", "clean", video, 0.030)[1]
    assert not rb.judge("video", "clean", {**video, "tracked": 0.999}, 0.030)[1]  # clean: every frame
    assert not rb.judge("video", "clean", {**video, "nme": 0.036}, 0.036)[1]
    assert rb.judge("video", "blur", {**video, "tracked": 0.95, "nme": 0.0395}, 0.030)[1]
    assert not rb.judge("video", "blur", {**video, "tracked": 0.949, "nme": 0.03}, 0.030)[1]
    assert not rb.judge("video", "blur", {**video, "nme": 0.0405}, 0.030)[1]
    assert not rb.judge("video", "blur", {**video, "nme": math.nan}, 0.030)[1]
    gap = {**video, "n_blank": 20, "resume": 3}
    assert rb.judge("video", "blank_grey", gap, 0.030)[1]
    assert not rb.judge("video", "blank_grey", {**gap, "blank_tracked": 1}, 0.030)[1]
    assert not rb.judge("video", "blank_grey", {**gap, "resume": 26}, 0.030)[1]
    assert not rb.judge("video", "blank_grey", {**gap, "resume": math.nan}, 0.030)[1]
    still = {"good": 0.92, "nme": 0.035}
    assert rb.judge("stills", "clean", still, 0.035)[1]
    assert not rb.judge("stills", "clean", {**still, "good": 0.91}, 0.035)[1]
    assert rb.judge("stills", "noise", {**still, "nme": 0.044}, 0.035)[1]
    assert not rb.judge("stills", "noise", {**still, "nme": 0.046}, 0.035)[1]


def test_markdown_table_rows():
    row = {"variant": "blank_grey", "model_name": "aamtrack 3D", "n_face": 40, "tracked": 1.0, "nme": 0.0454,
           "delta": 0.0024, "n_blank": 20, "blank_tracked": 20, "resume": 0, "goal": "g", "pass": False}
    table = rb.markdown_table("video", [row, {**row, "resume": math.nan, "spearman_confidence_nme": -0.614,
                                              "nme_smoothed": 0.0431, "delta_smoothed": -0.0012}])
    lines = table.splitlines()
    assert len(lines) == 4 and all(line.count("|") == 13 for line in lines)
    # no correlation and no smoothed figures in the row: dashes
    assert "| +0.0024 | –, – | – | 20 / 20 | 0 frames | g | FAIL |" in lines[2]
    assert "| 0.0431, -0.0012 | -0.61 | 20 / 20 | never |" in lines[3]


# ------------------------------------------------------------------------------------ end to end, synthetic


def test_adapter_and_script_on_synthetic_faces(synth_model, tmp_path, capsys):
    import synth

    from aamtrack.io.pts import write_pts
    from aamtrack.model import save_model

    model_path = tmp_path / "synth.npz"
    save_model(synth_model, model_path)
    frames, truth = synth.moving_face_frames(10)

    tracker = rb.Aamtrack(model_path)
    assert tracker.name == "aamtrack 2D"
    success, landmarks, confidence = tracker.track(frames)
    assert success.all() and landmarks.shape == (10, 68, 2) and (confidence >= 0.5).all()
    assert np.linalg.norm(landmarks - truth, axis=-1).mean() < 1.5  # about a pixel, as in the tracker's tests
    blank = np.full_like(frames[0], 128)
    success, landmarks, confidence = tracker.fit_each([frames[0], blank])  # frame 0 is one Haar finds on its own
    assert list(success) == [True, False] and np.isnan(landmarks[1]).all() and confidence[1] == 0.0

    video = tmp_path / "synth.avi"
    synth.write_video(video, frames)
    np.savez(tmp_path / "synth_dlib68.npz", landmarks=truth)
    stills = tmp_path / "stills"
    stills.mkdir()
    for i in (0, 3):
        rb.cv2.imwrite(str(stills / f"face{i}.png"), frames[i])
        write_pts(stills / f"face{i}.pts", truth[i])
    out = tmp_path / "r.json"
    code = rb.main(["--model", str(model_path), "--video", str(video), "--stills", str(stills),
                    "--variants", "mirror,blank_grey", "--json", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "machine: " in printed and "| mirror | aamtrack 2D |" in printed and "| blank_grey |" in printed
    result = json.loads(out.read_text())
    video_rows = {r["variant"]: r for r in result["video"]["rows"]}
    assert set(video_rows) == {"clean", "mirror", "blank_grey"}  # clean always runs
    assert video_rows["clean"]["tracked"] == 1.0 and video_rows["clean"]["nme"] < 0.02  # ~1 px of 70
    # the smoothed landmarks (as aamtrack run writes them) are scored too: within 3 px of 70, the filter's lag on
    # the clip's motion included (measured 0.023)
    assert video_rows["clean"]["nme_smoothed"] < 0.04 and math.isfinite(video_rows["mirror"]["delta_smoothed"])
    assert video_rows["blank_grey"]["n_blank"] == rb.GAP_FRAMES and video_rows["blank_grey"]["n_face"] == 10
    frames_ = video_rows["blank_grey"]["per_frame"]  # each frame's record: the grey gap has no landmarks, no NME
    assert len(frames_["success"]) == len(frames_["nme"]) == len(frames_["confidence"]) == 10 + rb.GAP_FRAMES
    gap = [i for i, e in enumerate(frames_["nme"]) if e is None or math.isnan(e)]
    assert len(gap) == rb.GAP_FRAMES and not any(frames_["success"][i] for i in gap)
    assert {r["variant"] for r in result["stills"]["rows"]} == {"clean", "mirror"}
    assert result["stills"]["n_images"] == 2


def test_script_bad_input(tmp_path, capsys):
    code = rb.main(["--model", str(tmp_path / "missing.npz"), "--video", "none", "--stills", "none"])
    err = capsys.readouterr().err.strip()
    assert code == 1 and err.startswith("robustness: ") and len(err.splitlines()) == 1
    with pytest.raises(SystemExit):
        rb.main(["--variants", "clean,sepia"])
    assert "unknown variant(s) sepia" in capsys.readouterr().err
