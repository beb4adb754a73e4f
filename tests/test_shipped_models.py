"""The shipped models load and track the bundled sample clip (nothing outside the repository needed)."""

from pathlib import Path

import numpy as np
import pytest

from aamtrack.io.frames import open_frames
from aamtrack.model import load_model
from aamtrack.models import default_model_path
from aamtrack.track.tracker import Tracker, TrackerConfig

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "cap12_first12s.mp4"


def _sample_images(n: int) -> list:
    """The sample clip's first n frames (BGR images)."""
    with open_frames(SAMPLE) as frames:
        return [f.image for f, _ in zip(frames, range(n), strict=False)]


def _track(tracker: Tracker, images) -> list:
    """The tracker's results for the images as a 25 fps video."""
    from aamtrack.track.replay import ReplayFrame

    return list(tracker.track(ReplayFrame(i, i / 25.0, im) for i, im in enumerate(images)))


def _errors_with_and_without_the_view(model, images, reference) -> dict:
    """{True: mean NME, False: mean NME} of the tracks of the images with the landmark cascade's adaptive view
    (``Searcher.adaptive_view``: contrast gain, noise smoothing) on and off, against the reference points, every
    frame asserted tracked."""
    from aamtrack.metrics import nme

    errors = {}
    for view in (True, False):
        tracker = Tracker(model)
        tracker.searcher.adaptive_view = view
        results = _track(tracker, images)
        assert all(r.success for r in results)
        errors[view] = np.mean([float(nme(r.landmarks, p)) for r, p in zip(results, reference)])
    return errors


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


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_low_rank_landmark_cascade_stays_near_the_full_one(kind):
    """The landmark cascade applies its regressors at rank ``LandmarkCascade.rank`` (an approximation: the file
    keeps them whole). On the sample's faces, from the tracked points moved by 2 px of noise, its points stay
    within 0.01 outer eye-corner distances (mean over the 68) of the full-rank cascade's: 0.005 at rank 80 when
    written, 0.013 at rank 32 (3D, this test's starts); and the approximation is not the identity (rank below
    136)."""
    from dataclasses import replace

    from aamtrack.imaging import to_gray32

    model = load_model(default_model_path(kind))
    lc = model.landmark_cascade
    full = replace(lc, rank=0)
    assert 0 < lc.rank < 136
    with open_frames(SAMPLE) as source:
        frames = list(source)
    tracked = [(f.image, r) for f, r in zip(frames, Tracker(model).track(frames), strict=True) if f.index % 30 == 0]
    rng = np.random.default_rng(11)
    gaps, moved = [], []
    for image, res in tracked:
        grey = to_gray32(image)
        pts = res.landmarks - 1.0  # the package's 1-based pixels -> OpenCV's, which the cascade reads
        start = pts + rng.normal(0, 2.0, pts.shape)
        eye = np.linalg.norm(pts[45] - pts[36])
        want = full.apply(grey, 1.0, start)
        got = lc.apply(grey, 1.0, start)
        gaps.append(np.linalg.norm(got - want, axis=1).mean() / eye)
        moved.append(np.linalg.norm(want - start, axis=1).mean() / eye)
    assert np.median(gaps) < 0.01  # eye distances: the approximation's own error
    assert max(gaps) > 0  # the ranks differ
    assert np.median(moved) > 2 * np.median(gaps)  # the cascade's move is larger than what the rank changes


def test_pose_of_an_unchanging_face_stays_put():
    """Three frames of the sample, each shown 60 times over: the 3D pose reported must not walk, nor step when
    the person's shape estimate is held at frame ``sigma_frames``. While the shape units are being estimated
    each tracked search starts them at the median of the estimates so far (``sigma_restart``); started from the
    previous frame's fit instead, pose and shape walked together along what the 2D points cannot tell apart
    (pitch range over frames 20-59 of these frames: 4.3 / 3.6 / 4.3 degrees when written, 0.3 / 1.5 / 1.1 with
    the restart). With the search's shape units free until the median was held, the pose then stepped once at
    the hold: 1.7 / 2.1 / 2.7 degrees of pitch with the models of 2026-11-29; holding them at the running median
    (``sigma_running``) leaves 0.00 there and a range of 0.003-0.027 degrees over frames 10-59 (measured
    2026-11-29), the first few frames settling by up to a degree."""
    from aamtrack.track.replay import ReplayFrame

    model = load_model(default_model_path("3d"))
    held = Tracker(model).config.sigma_frames
    images = _sample_images(201)
    for k in (0, 150, 200):
        results = list(Tracker(model).track(ReplayFrame(i, i / 25.0, images[k]) for i in range(held + 10)))
        assert all(r.success for r in results)
        angles = np.degrees(np.array([r.rotation for r in results]))
        assert np.ptp(angles[10:], axis=0).max() < 0.2  # degrees: no walk, and no step at the hold (frame 50)
        assert np.abs(angles[held + 1] - angles[held - 1]).max() < 0.05  # degrees: the hold itself changes nothing


def test_reported_pose_comes_from_the_points_without_the_jaw():
    """``TrackerConfig.pose_from_points``: the pose a 3D result reports is fitted to the final points less the
    jaw's, so a search whose pose is off and a jaw line read elsewhere (a turned face's silhouette) leave it on
    the truth: synthetic points, exact but for the jaw moved 6 px sideways, the search's pose 3 and 4 degrees
    off. A fit to all 68 points is pulled off by the jaw."""
    from dataclasses import replace

    from aamtrack.mesh.landmark_fit import LandmarkFitter
    from aamtrack.result import FitResult
    from aamtrack.track.tracker import TrackerConfig

    model = load_model(default_model_path("3d"))
    sm = model.shape
    tracker = Tracker(model)
    q = np.zeros(sm.n_q)
    q[:6] = [0.1, 0.45, -0.05, 160.0 / sm.frontal_width(), 320.0, 240.0]  # a face 160 px wide
    q[6:] = 0.3 * sm.bounds()[1][6:]  # some expression, within the coefficients' bounds
    sigma = 0.5 * np.asarray(sm.shape_sd)
    points = sm.landmarks(q, sigma)
    points[:17, 0] += 6.0  # px
    start = np.r_[q, sigma]
    start[0] += np.radians(3.0)
    start[1] -= np.radians(4.0)
    res = FitResult(p=start, landmarks=points, vertices=np.zeros((sm.n_vertices, 2)), residual=0.0)

    def error_deg(p):
        return np.degrees(np.abs(p[:3] - q[:3])).max()

    assert error_deg(tracker.reported_pose(res)) < 0.1  # degrees
    assert error_deg(LandmarkFitter(sm).refit(start, points, 2)) > 1.0
    off = Tracker(model, config=replace(TrackerConfig(), pose_from_points=False))
    assert np.array_equal(off.reported_pose(res), start[:sm.n_q])


N_BLURRED = 40  # helen_test photos (about 20 s)


@pytest.mark.shared_data
def test_a_blurred_still_is_looked_at_again_sharpened():
    """``TrackerConfig.sharpen_soft``: helen_test photos blurred by 0.09 outer eye distances (held out; the soft
    face's fits are the soft cascade's), fitted as ``aamtrack fit`` fits them: more of them within NME 0.08 with
    the sharpened second look than without it, and a sharp photo never looked at twice (its result the same
    bits)."""
    import cv2
    from dataclasses import replace

    from aamtrack.io.dataset import find_pairs
    from aamtrack.io.pts import read_pts
    from aamtrack.metrics import nme
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import TrackerConfig
    from conftest import shared_path

    model = load_model(default_model_path("3d"))
    with_look, without = Tracker(model), Tracker(model, config=replace(TrackerConfig(), sharpen_soft=0.0))
    pairs = find_pairs(shared_path("300w", "helen_test"))[:N_BLURRED]
    good = {True: 0, False: 0}
    for k, (img_path, pts_path) in enumerate(pairs):
        image, truth = cv2.imread(str(img_path)), read_pts(pts_path)
        eye = float(np.linalg.norm(truth[45] - truth[36]))
        blurred = cv2.GaussianBlur(image, (0, 0), 0.09 * eye)
        for tracker, key in ((with_look, True), (without, False)):
            res = tracker.fit_still(ReplayFrame(k, 0.0, blurred))
            good[key] += bool(res.success) and float(nme(res.landmarks, truth)) <= 0.08
        if k == 0:
            a, b = with_look.fit_still(ReplayFrame(0, 0.0, image)), without.fit_still(ReplayFrame(0, 0.0, image))
            assert np.array_equal(a.landmarks, b.landmarks)  # a sharp photo: one look, the same fit
    print(f"blurred helen_test, within NME 0.08: {good[True]} of {len(pairs)} with the second look, "
          f"{good[False]} without")
    assert good[True] >= good[False] + 2


DIM_RECOVERED = (46, 237, 252)  # helen_test photos whose dim copy only the smoothed look fits (below)


def test_a_refused_dim_still_is_looked_at_again_smoothed():
    """``TrackerConfig.smooth_dim``: helen_test photos made small, dark and noisy as the robustness suite's
    dim_small makes them (``benchmarks/robustness.py``; the noise drawn per photo, seeded by its index), fitted as
    ``aamtrack fit`` fits them. Of the 330 so made, the look changed three results, each from not fitted to within
    NME 0.08 (46, 237, 252), and one from not fitted to 0.082 (/tmp harness, 2026-12-01): those three are fitted
    within 0.08 with it and not without. A clear photo is never looked at twice (its result the same bits)."""
    import sys
    from dataclasses import replace

    import cv2

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from robustness import dim_small

    from aamtrack.io.dataset import find_pairs
    from aamtrack.io.pts import read_pts
    from aamtrack.metrics import nme
    from aamtrack.track.replay import ReplayFrame
    from conftest import shared_path

    model = load_model(default_model_path("3d"))
    with_look, without = Tracker(model), Tracker(model, config=replace(TrackerConfig(), smooth_dim=0.0))
    assert with_look.config.smooth_dim > 0
    pairs = find_pairs(shared_path("300w", "helen_test"))
    for k in DIM_RECOVERED:
        image, truth = cv2.imread(str(pairs[k][0])), read_pts(pairs[k][1])
        eye = float(np.linalg.norm(truth[45] - truth[36]))
        dim, moved = dim_small(image, truth.astype(float), eye_px=eye, rng=np.random.default_rng(k))
        got, before = with_look.fit_still(ReplayFrame(k, 0.0, dim)), without.fit_still(ReplayFrame(k, 0.0, dim))
        assert not before.success, (k, before.confidence)
        assert got.success and float(nme(got.landmarks, moved)) <= 0.08, (k, got.reason)
    image = cv2.imread(str(pairs[0][0]))
    a, b = with_look.fit_still(ReplayFrame(0, 0.0, image)), without.fit_still(ReplayFrame(0, 0.0, image))
    assert np.array_equal(a.landmarks, b.landmarks)  # a clear photo: one look, the same fit


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_shipped_shape_prior_is_the_one_training_learns_from_helen_train(kind):
    """The shipped models' shape prior (added to the 2D model of 2026-11-28, not retrained; learned by the 3D
    model's training of 2026-11-29) is what ``train_model`` learns: ``learn_shape_prior`` of helen_train's
    labels and their mirrors, in OpenCV's pixels as training holds
    them."""
    from conftest import shared_path

    from aamtrack.io.dataset import find_pairs, load_pair
    from aamtrack.mesh.landmarks import mirror_points
    from aamtrack.metrics import PIXEL_ORIGIN
    from aamtrack.train.shape_prior import learn_shape_prior

    folder = shared_path("300w", "helen_train")
    pts, mirrored = [], []
    for image_path, pts_path in find_pairs(folder):
        image, p = load_pair(image_path, pts_path)
        pts.append(p - PIXEL_ORIGIN)
        mirrored.append(mirror_points(p - PIXEL_ORIGIN, image.shape[1], origin=0.0))
    prior = learn_shape_prior(np.array(pts + mirrored))
    shipped = load_model(default_model_path(kind)).shape_prior
    assert shipped.n_modes == prior.n_modes
    assert np.allclose(shipped.mean, prior.mean, atol=1e-12)
    assert np.allclose(np.abs(shipped.modes @ prior.modes.T), np.eye(prior.n_modes), atol=1e-6)  # (signs: SVD's)
    assert np.allclose(shipped.variances, prior.variances, rtol=1e-9)


def test_a_hand_over_the_mouth_leaves_the_points_where_the_face_is():
    """The sample clip with a skin-coloured ellipse over the mouth and chin on frames 100-199, placed from the clean
    track's points: few of those frames are reported tracked with points more than 0.10 eye distances from the
    clean track's, with the shape test (``TrackerConfig.max_shape_score``, ``shape_recheck_above``) and without
    it, none with an implausible shape, and the frames after the hand are tracked. With the landmark cascade of
    2026-11-28 (no occluded training copies) the hand pulled 20 frames' points off without the shape test and 1
    with it; with the occlusion-trained cascade (``TrainConfig.landmark_occlude_share``) 0 and 0 when written."""
    import sys
    from dataclasses import replace

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from occlusion import SKIN, occluder_mask

    from aamtrack.metrics import PIXEL_ORIGIN, nme

    model = load_model(default_model_path("3d"))
    images = _sample_images(230)
    on = Tracker(model)
    clean = _track(on, images)
    assert all(r.success for r in clean)  # the premise: the clean clip is tracked throughout
    covered = range(100, 200)
    occluded = [im.copy() for im in images]
    for i in covered:
        occluded[i][occluder_mask("mouth", clean[i].landmarks, occluded[i].shape)] = SKIN
    wrong = {}
    off = Tracker(model, config=replace(on.config, max_shape_score=0.0, shape_recheck_above=0.0))
    for name, tracker in (("on", on), ("off", off)):
        results = _track(tracker, occluded)
        wrong[name] = sum(r.success and float(nme(r.landmarks, clean[i].landmarks)) > 0.10
                          for i, r in zip(covered, results[100:200], strict=True))
        if name == "on":
            scores = [model.shape_prior.score(r.landmarks - PIXEL_ORIGIN) for r in results[100:200] if r.success]
            assert max(scores) <= on.config.max_shape_score
            assert all(r.success for r in results[210:])  # the track is back once the hand is gone
    print("frames off the clean track by more than 0.10:", wrong)
    assert wrong["on"] <= 3 and wrong["off"] <= 3  # of 100 covered frames


def test_a_close_up_filling_the_frame_is_found_and_tracked():
    """The sample's first 40 frames zoomed in so the face's landmarks span the frame's height (brows at the top
    edge, chin at the bottom: Haar's box would reach past both). Before the close-up search
    (``detector.CLOSE_PAD``) no search found the face (cap12 zoomed so: 47% of its frames tracked, most of the
    rest 'no face detected'); now every frame is tracked from the first, and the points agree with the un-zoomed
    track's moved by the zoom."""
    import cv2

    from aamtrack.detector import HaarDetector
    from aamtrack.mesh.landmarks import affine_points
    from aamtrack.metrics import nme

    model = load_model(default_model_path("3d"))
    images = _sample_images(40)
    plain = _track(Tracker(model), images)
    assert all(r.success for r in plain)
    pts = np.array([r.landmarks for r in plain])
    H, W = images[0].shape[:2]
    centre, height = np.median(pts.mean(1), 0), np.median(np.ptp(pts[:, :, 1], axis=1))
    s = 1.0 * H / height  # the landmarks span the frame's height
    M = np.array([[s, 0.0, W / 2 - s * centre[0]], [0.0, s, H / 2 - s * centre[1]]])
    zoomed = [cv2.warpAffine(im, M, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
              for im in images]

    class Unpadded(HaarDetector):  # neither the close-up search nor the edge one (which looks for any size)
        def _searches(self, frame_width, thorough=True):
            return [t for t in super()._searches(frame_width, thorough) if not (t.close or t.edge)]

    grey = cv2.cvtColor(zoomed[0], cv2.COLOR_BGR2GRAY)
    assert Unpadded().find(grey) is None  # the premise: none of the searches in the frame itself finds this face
    results = _track(Tracker(model), zoomed)
    assert [r.status for r in results] == ["detected"] + ["tracked"] * (len(zoomed) - 1)
    errors = [float(nme(r.landmarks, affine_points(p, M))) for r, p in zip(results, pts)]  # (M: OpenCV's pixels)
    print("close-up against the un-zoomed track, NME mean / max:", np.mean(errors), np.max(errors))
    assert np.mean(errors) < 0.02 and np.max(errors) < 0.04  # the same face (measured 0.008 / 0.010)


def test_a_face_cut_by_the_frames_side_is_found_and_tracked():
    """The sample's first 30 frames moved left so about 15% of the face's width lies past the frame's edge (the
    face a third of the frame wide: not a close-up): before the edge search (``detector.Search.edge``) no frame
    was tracked ('no face detected'); now the face is found within a few frames and tracked on, its visible
    points where the uncut track's moved by the same shift (measured 26 of 30 frames, NME over the visible points
    0.017; 0.010 since the patches and texture past the edge count as missing, ``patches._blank_outside``)."""
    import cv2

    model = load_model(default_model_path("3d"))
    images = _sample_images(30)
    pts = np.array([r.landmarks for r in _track(Tracker(model), images)])
    dx = -(np.median(pts[:, :, 0].min(1)) + 0.15 * np.median(np.ptp(pts[:, :, 0], axis=1)))
    H, W = images[0].shape[:2]
    M = np.array([[1.0, 0.0, dx], [0.0, 1.0, 0.0]])
    cut = [cv2.warpAffine(im, M, (W, H), borderMode=cv2.BORDER_REPLICATE) for im in images]
    results = _track(Tracker(model), cut)
    moved = pts + [dx, 0.0]
    errors = []
    for r, p in zip(results, moved):
        if r.success:
            seen = p[:, 0] >= 0  # the points inside the frame
            errors.append(np.linalg.norm(r.landmarks[seen] - p[seen], axis=1).mean() / np.linalg.norm(p[45] - p[36]))
    print(f"cut face: {len(errors)} of {len(cut)} frames tracked, visible points' NME {np.mean(errors):.4f}")
    assert len(errors) >= 20 and all(r.success for r in results[10:])
    assert np.mean(errors) < 0.03 and np.max(errors) < 0.05


def test_a_face_sliding_half_out_of_the_frame_is_kept_on_what_the_frame_shows():
    """The sample's first 40 frames slid left until 40% of the face's width lies past the frame's edge and back (a
    speaker leaning out of shot): every frame stays tracked, the visible points where the unmoved track's moved
    with the frame. The search's texture pixels and the landmark cascade's patches outside the frame count as
    missing (``warp._fill_outside``, ``patches._blank_outside``) and half a face is kept (``min_inside`` 0.5);
    before, the frames past about 30% were lost ("landmarks inside the frame", then no face detected)."""
    import cv2

    model = load_model(default_model_path("3d"))
    images = _sample_images(40)
    pts = np.array([r.landmarks for r in _track(Tracker(model), images)])
    H, W = images[0].shape[:2]
    width = np.median(np.ptp(pts[:, :, 0], axis=1))
    out_share = 0.4 * np.sin(np.linspace(0, np.pi, len(images)))  # 0 -> 40% of the face's width past the edge -> 0
    cut, moved = [], []
    for im, p, share in zip(images, pts, out_share):
        dx = -(p[:, 0].min() + share * width)
        cut.append(cv2.warpAffine(im, np.array([[1.0, 0.0, dx], [0.0, 1.0, 0.0]]), (W, H),
                                  borderMode=cv2.BORDER_REPLICATE))
        moved.append(p + [dx, 0.0])
    results = _track(Tracker(model), cut)
    errors = []
    for r, p in zip(results, moved):
        seen = p[:, 0] >= 0  # the points inside the frame
        errors.append(np.linalg.norm(r.landmarks[seen] - p[seen], axis=1).mean() / np.linalg.norm(p[45] - p[36]))
    print(f"face half out: {sum(r.success for r in results)} of {len(cut)} frames tracked, visible points' NME "
          f"mean {np.nanmean(errors):.4f}, max {np.nanmax(errors):.4f}")
    assert all(r.success for r in results)
    assert np.mean(errors) < 0.03 and np.max(errors) < 0.06


def test_a_small_rolled_face_in_a_dim_frame_is_found_at_once_and_tracked():
    """The sample's first 30 frames shrunk to 0.55 (about 33 px between the outer eye corners), rolled by 25
    degrees, dim and noisy in a 960x540 frame (a far speaker, a tilted camera): the thorough searches turned at
    twice the detection width (``HaarDetector.find``) find it in the first frame, and it is tracked where the
    upright track's points moved with it (measured 30 of 30 frames, NME 0.0164 against the moved track; 15 of 30
    before those searches, the first detection at frame 15)."""
    import cv2

    from aamtrack.mesh.landmarks import affine_points
    from aamtrack.metrics import nme

    model = load_model(default_model_path("3d"))
    images = _sample_images(30)
    pts = np.array([r.landmarks for r in _track(Tracker(model), images)])
    H, W = images[0].shape[:2]
    M = cv2.getRotationMatrix2D((W / 2, H / 2), -25.0, 0.55)
    M[:, 2] += (120, 200)
    rng = np.random.default_rng(0)
    small = []
    for im in images:
        dim = cv2.warpAffine(im, M, (960, 540), borderValue=(20, 15, 25)).astype(np.float32) * np.float32(
            [0.30, 0.28, 0.42])
        small.append(np.clip(dim + rng.normal(0, 6, dim.shape).astype(np.float32), 0, 255).astype(np.uint8))
    results = _track(Tracker(model), small)
    # (M: OpenCV's pixels, the points the package's: ``affine_points`` moves them as the image moved)
    errors = [float(nme(r.landmarks, affine_points(p, M))) for r, p in zip(results, pts) if r.success]
    print(f"small rolled dim face: {len(errors)} of {len(small)} frames tracked, NME {np.mean(errors):.4f}")
    assert results[0].success and len(errors) >= 28
    assert np.mean(errors) < 0.04 and np.max(errors) < 0.06


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_a_dark_face_is_fitted_where_the_bright_one_is(kind):
    """The sample's first 40 frames at 0.3 of their brightness (a dim room, no noise added): the points stay
    where the bright frames' track has them with the landmark cascade's contrast gain
    (``landmark_cascade.descriptor_gain``, in ``descriptor_view``), and drift without it (3D measured 0.0018
    against 0.0129 mean NME: the jaw drew up)."""
    model = load_model(default_model_path(kind))
    images = _sample_images(40)
    bright = [r.landmarks for r in _track(Tracker(model), images)]
    dark = [np.round(0.3 * im).astype(np.uint8) for im in images]
    errors = _errors_with_and_without_the_view(model, dark, bright)
    print(f"{kind} dark frames against the bright track, mean NME: {errors[True]:.4f} with the gain, "
          f"{errors[False]:.4f} without")
    assert errors[True] < 0.006 and errors[True] < 0.5 * errors[False]


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_a_noisy_face_is_fitted_nearer_the_clean_one_when_smoothed(kind):
    """The sample's first 40 frames with sensor noise of 25 grey levels on each channel (the robustness suite's
    noise variant): against the clean frames' track the landmark cascade's points lie nearer with the noisy face
    read smoothed (``landmark_cascade.descriptor_view``) than read as it is (measured mean NME 3D 0.0135 against
    0.0174, 2D 0.0146 against 0.0183)."""
    model = load_model(default_model_path(kind))
    images = _sample_images(40)
    clean = [r.landmarks for r in _track(Tracker(model), images)]
    rng = np.random.default_rng(5)
    noisy = [np.clip(im + rng.normal(0.0, 25.0, im.shape), 0, 255).round().astype(np.uint8) for im in images]
    errors = _errors_with_and_without_the_view(model, noisy, clean)
    print(f"{kind} noisy frames against the clean track, mean NME: {errors[True]:.4f} smoothed, "
          f"{errors[False]:.4f} as they are")
    assert errors[True] < 0.018 and errors[True] < 0.9 * errors[False]


def _noise_still(index: int, seed: int, sizes, means, sds, blurs, *, colour_every: int, min_blur: float = 0.0):
    """The ``index``-th still of a /tmp set of Gaussian noise, drawn as the set was: for each still in turn a size
    (W, H) from ``sizes`` in turn, a mean, sd and blur uniform in ``means``, ``sds`` and ``blurs``, colour every
    ``colour_every``-th (else grey); blurred where the blur exceeds ``min_blur``. Every earlier still is drawn
    too (the draws are in order)."""
    import cv2

    rng = np.random.default_rng(seed)
    for k in range(index + 1):
        W, H = sizes[k % len(sizes)]
        mean, sd, blur = rng.uniform(*means), rng.uniform(*sds), rng.uniform(*blurs)
        noise = rng.normal(mean, sd, (H, W, 3) if k % colour_every == 0 else (H, W))
    if blur > min_blur:
        noise = cv2.GaussianBlur(noise, (0, 0), blur)
    return np.clip(noise, 0, 255).astype(np.uint8)


def test_a_still_of_blurred_noise_is_not_fitted():
    """Issue 9 asks that no noise frame is ever tracked. Blurred Gaussian noise (grey, 960x540, mean 87, sd 31,
    blurred by 1.7 px: texture rather than sensor noise) was fitted by ``aamtrack fit`` as a face: the smallest-face
    searches give a 26 px box, the dim faces' validator accepts its fit in the image and in its mirror (0.89 / 0.90)
    and the two agree (0.04 eye distances); texture correlation does not separate such fits (noise 0.19-0.42,
    helen_test's dim_small faces fitted within NME 0.08: 0.38 at the 5th percentile). The frame's variation is all
    at the noise's grain (``imaging.frame_structure`` 0.16 against the bar 0.25,
    ``TrackerConfig.dim_min_structure``): the dim fit is refused."""
    from aamtrack.track.replay import ReplayFrame

    image = _noise_still(9, 11, ((640, 480), (960, 540)), (30, 120), (10, 40), (0.6, 2.0), colour_every=4)
    result = Tracker(load_model(default_model_path("3d"))).fit_still(ReplayFrame(0, 0.0, image))
    assert not result.success, f"fitted at confidence {result.confidence:.2f}"
    assert "looks like noise" in result.reason, result.reason  # refused for the frame, at its high confidence


def test_a_dim_fit_of_noise_that_its_mirror_does_not_confirm_is_rejected():
    """``Tracker.fit_still``: a fit judged by the dim faces' validator stands only where the mirrored image's fit
    agrees with it. In this noise still Haar's smallest-face search finds a "face" 46 px wide and the dim
    validator accepts its fit (fitted when the mirror is not looked at), but the mirror's fit lies about 4 eye
    distances away: rejected, and the reason says why."""
    from aamtrack.track.replay import ReplayFrame

    image = _noise_still(90, 2042, ((640, 480), (960, 540), (1280, 720)), (15, 180), (3, 50), (0.0, 3.0),
                         colour_every=5, min_blur=0.3)  # the 2026-11-30 set of 150
    # (the frame's structure, ``TrackerConfig.dim_min_structure``, refuses it too: off, to see the mirror's part)
    tracker = Tracker(load_model(default_model_path("3d")), config=TrackerConfig(dim_min_structure=0.0))
    alone = tracker.fit_still(ReplayFrame(0, 0.0, image), mirror=False)
    assert alone.success, alone.reason  # the image's own fit is accepted: the mirror is what rejects it
    both = tracker.fit_still(ReplayFrame(0, 0.0, image))
    assert not both.success and both.reason.startswith("dim fit "), (both.confidence, both.reason)


def _blotchy_still(index: int, seed: int = 21) -> np.ndarray:
    """The ``index``-th still of a /tmp set of 120 non-face textures (2026-11-30, forty-fifth session), drawn as the
    set was; only its first kind, isotropic blotches, is made here (``index`` a multiple of 4): Gaussian noise
    blurred by 2-10 px, stretched to a spread of 4-45 grey levels about a mean of 30-170, grey, the frame 640x480,
    960x540, 1280x720 or 800x600 in turn. The set's other kinds (blotches blurred more along one axis, coloured
    blotches, two scales of blotches mixed) take draws too, so every still before it is drawn as the set drew it."""
    import cv2

    assert index % 4 == 0, "only the isotropic kind is kept here"
    rng = np.random.default_rng(seed)
    for k in range(index + 1):  # the noise of every still before it is drawn (blurred only for the one kept)
        W, H = [(640, 480), (960, 540), (1280, 720), (800, 600)][k % 4]
        kind = k % 4
        if kind == 0:
            im, blur = rng.normal(0, 1, (H, W)), rng.uniform(2, 10)
            if k == index:
                im = cv2.GaussianBlur(im, (0, 0), blur)
        elif kind == 1:
            rng.normal(0, 1, (H, W)), rng.uniform(1.5, 10), rng.uniform(1.5, 10)
        elif kind == 2:
            for _ in range(3):
                rng.normal(0, 1, (H, W)), rng.uniform(2, 8)
        else:
            rng.uniform(1, 3), rng.uniform(6, 20), rng.normal(0, 1, (H, W)), rng.normal(0, 1, (H, W))
        mean, spread = rng.uniform(30, 170), rng.uniform(4, 45)
    im = mean + im / im.std() * spread
    return np.clip(im, 0, 255).astype(np.uint8)


def test_a_still_of_blotchy_noise_is_not_fitted():
    """Issue 9 asks that no noise frame is ever tracked. Noise blurred into blotches (grey, 640x480) was fitted by
    ``aamtrack fit`` as a clear face (confidence 0.77): Haar finds "faces" in most such frames, and the landmark
    validator, which had seen flat and blurred uniform noise but no contrasty blotches, accepted the fit. Since it
    learned from fits at Haar's boxes on blotchy and cloudy noise (``TrainConfig.textured``,
    ``train.validator.textured_noise``; this set was not drawn by training) the fit is refused."""
    from aamtrack.track.replay import ReplayFrame

    image = _blotchy_still(0)
    result = Tracker(load_model(default_model_path("3d"))).fit_still(ReplayFrame(0, 0.0, image))
    assert not result.success, f"fitted at confidence {result.confidence:.2f}"


@pytest.mark.parametrize("index", [28, 44, 52, 60, 88, 112])
def test_a_still_of_blotches_taken_for_a_blurred_face_is_not_fitted(index):
    """Blotches look like a blurred face: in these stills (the same held-out set, grey, 640x480) the
    soft landmark cascade, the one for blurred faces, took Haar's "face", and the validator for soft faces
    accepted the fit (112 at confidence 0.78 until the forty-seventh session; the others, its model's 8 of 120,
    until the forty-eighth): it had learned from blurred faces and non-face images but not from textured noise
    (``TrainConfig.textured``), then from one photo in four's textured frame at a few of Haar's strongest boxes.
    Since both validators learn from every photo's frame at Haar's weakest hits too, the fit is refused by its
    confidence (the shipped 3D model fits none of the set's 120: benchmarks/README.md, "Textured noise")."""
    from aamtrack.track.replay import ReplayFrame

    image = _blotchy_still(index)
    result = Tracker(load_model(default_model_path("3d"))).fit_still(ReplayFrame(0, 0.0, image))
    assert not result.success, f"fitted at confidence {result.confidence:.2f}"
    assert result.reason.startswith("low confidence"), result.reason  # the validator refused it (Haar did give a box)
