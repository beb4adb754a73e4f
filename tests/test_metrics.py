"""Tests for aamtrack.metrics on small hand-made arrays whose answers are worked out in the comments."""

import numpy as np
import pytest

from aamtrack.metrics import (
    CED_THRESHOLDS,
    IBUG_REGIONS,
    MEDIAPIPE_SUBSET,
    MEDIAPIPE_TO_IBUG,
    PIXEL_ORIGIN,
    ced,
    from_dlib,
    from_normalised,
    jitter,
    mediapipe_to_ibug,
    nme,
    nme_by_region,
    nme_subset,
    still_frames,
)
from conftest import SEED, shared_path


def _face68(eye_gap: float = 10.0) -> np.ndarray:
    """A (68, 2) shape: random points, with the outer eye corners 36 and 45 exactly ``eye_gap`` px apart."""
    rng = np.random.default_rng(SEED)
    shape = rng.uniform(0.0, 50.0, size=(68, 2))
    shape[36] = (20.0, 30.0)
    shape[45] = (20.0 + eye_gap, 30.0)
    return shape


def test_nme_shift_by_one_pixel():
    ref = _face68(10.0)
    pred = ref + (1.0, 0.0)  # every point 1 px off -> mean error 1 px; eye gap 10 px -> NME 1/10
    assert nme(pred, ref) == pytest.approx(0.1)


def test_nme_diagonal_shift_and_batch():
    ref = np.stack([_face68(10.0), _face68(20.0)])  # (2, 68, 2)
    pred = ref + (3.0, 4.0)  # 3-4-5 triangle: every point 5 px off
    # frame 0: 5 / 10 = 0.5; frame 1: 5 / 20 = 0.25
    np.testing.assert_allclose(nme(pred, ref), [0.5, 0.25])


def test_nme_one_point_off():
    ref = _face68(10.0)
    pred = ref.copy()
    pred[0] += (0.0, 6.8)  # one point 6.8 px off, 67 exact -> mean 6.8 / 68 = 0.1 px -> NME 0.1 / 10 = 0.01
    assert nme(pred, ref) == pytest.approx(0.01)


def test_nme_is_normalised_by_the_reference_not_the_prediction():
    ref = _face68(10.0)
    pred = ref.copy()
    pred[45] += (10.0, 0.0)  # pred's eye gap is 20 px but ref's 10 px is used: 10 / 68 / 10
    assert nme(pred, ref) == pytest.approx(1.0 / 68.0)


def test_nme_explicit_normaliser_on_few_points():
    ref = np.array([[0.0, 0.0], [4.0, 0.0], [2.0, 3.0]])  # points 0 and 1 are 4 px apart
    pred = ref + (0.0, 2.0)  # 2 px each -> 2 / 4 = 0.5
    assert nme(pred, ref, left=0, right=1) == pytest.approx(0.5)


def test_nme_nan_where_pred_nan():
    ref = np.stack([_face68(10.0)] * 3)
    pred = ref + (1.0, 0.0)
    pred[1] = np.nan  # nothing found in frame 1
    pred[2, 7, 0] = np.nan  # one NaN coordinate also fails the frame
    errors = nme(pred, ref)
    assert errors[0] == pytest.approx(0.1)
    assert np.isnan(errors[1]) and np.isnan(errors[2])


def test_nme_shape_mismatch_raises():
    with pytest.raises(ValueError, match="shape"):
        nme(np.zeros((68, 2)), np.zeros((67, 2)))


def test_ced_hand_list():
    errors = [0.01, 0.02, 0.02, 0.05, np.nan]  # 5 items, one failed
    # <= 0.0: none -> 0/5; <= 0.02: 0.01, 0.02, 0.02 -> 3/5; <= 0.04: same 3/5; <= 0.1: 4/5 (NaN never counts)
    np.testing.assert_allclose(ced(errors, [0.0, 0.02, 0.04, 0.1]), [0.0, 0.6, 0.6, 0.8])


def test_ced_default_thresholds():
    assert CED_THRESHOLDS.shape == (31,)
    assert CED_THRESHOLDS[0] == 0.0 and CED_THRESHOLDS[-1] == pytest.approx(0.15)
    np.testing.assert_allclose(np.diff(CED_THRESHOLDS), 0.005)
    share = ced([0.0, 0.2])  # 0.0 is within every threshold; 0.2 is beyond 0.15 -> 1/2 everywhere
    np.testing.assert_allclose(share, 0.5)


def test_ced_empty_is_nan():
    assert np.isnan(ced([], [0.1])).all()


def _track_still_then_moving() -> np.ndarray:
    """10 frames of a 2-point track: frames 0-5 wobble by +-0.5 px in x, frames 6-9 move 3 px per frame."""
    base = np.array([[0.0, 0.0], [10.0, 0.0]])  # "eye corners" 10 px apart
    track = np.stack([base] * 10)
    track[1:6:2, :, 0] += 0.5  # frames 1, 3, 5 at +0.5: each of the pairs (0,1)..(4,5) moves every point 0.5 px
    track[6:, :, 0] += 3.0 * np.arange(1, 5)[:, None]  # frames 6-9: 3, 6, 9, 12 px
    return track


def test_jitter_on_constructed_track():
    track = _track_still_then_moving()
    still = np.zeros(10, bool)
    still[:6] = True  # pairs (0,1)..(4,5) are still: each 0.5 px -> jitter 0.5
    assert jitter(track, still) == pytest.approx(0.5)
    # all frames: pairs (0,1)..(4,5) 0.5 px each; (5,6): 3 - 0.5 = 2.5 px; (6,7)..(8,9): 3 px each
    # -> (5 * 0.5 + 2.5 + 3 * 3) / 9 = 14 / 9
    assert jitter(track, np.ones(10, bool)) == pytest.approx(14.0 / 9.0)


def test_jitter_skips_lost_frames_and_empty_mask():
    track = _track_still_then_moving()
    track[2] = np.nan  # pairs (1,2) and (2,3) drop out; (0,1), (3,4), (4,5) remain, 0.5 px each
    still = np.zeros(10, bool)
    still[:6] = True
    assert jitter(track, still) == pytest.approx(0.5)
    assert np.isnan(jitter(track, np.zeros(10, bool)))


def test_still_frames_on_constructed_track():
    track = _track_still_then_moving()
    # relative motion per frame (eye gap 10 px): frames 1-5: 0.5/10 = 0.05; frame 6: 2.5/10; frames 7-9: 0.3
    still = still_frames(track, thresh=0.1, min_len=3, left=0, right=1)
    np.testing.assert_array_equal(still, [0, 1, 1, 1, 1, 1, 0, 0, 0, 0])  # frame 0 has no predecessor
    # a tighter threshold marks nothing still
    assert not still_frames(track, thresh=0.04, min_len=1, left=0, right=1).any()


def test_still_frames_drops_short_runs():
    base = np.array([[0.0, 0.0], [10.0, 0.0]])
    steps = np.array([0, 0, 5, 0, 0, 5, 0, 0, 0, 0], float)  # big jumps into frames 2 and 5
    track = base + np.cumsum(steps)[:, None, None] * np.array([1.0, 0.0])
    # motion < 0.1 * 10 px at frames 1, 3, 4, 6, 7, 8, 9 -> runs [1], [3, 4], [6..9]; min_len 3 keeps only [6..9]
    still = still_frames(track, thresh=0.1, min_len=3, left=0, right=1)
    np.testing.assert_array_equal(still, [0, 0, 0, 0, 0, 0, 1, 1, 1, 1])


def test_mediapipe_map_indices():
    assert MEDIAPIPE_TO_IBUG[36] == 33 and MEDIAPIPE_TO_IBUG[45] == 263  # outer eye corners
    assert MEDIAPIPE_TO_IBUG[39] == 133 and MEDIAPIPE_TO_IBUG[42] == 362  # inner eye corners
    assert MEDIAPIPE_TO_IBUG[48] == 61 and MEDIAPIPE_TO_IBUG[54] == 291  # mouth corners
    assert len(set(MEDIAPIPE_TO_IBUG.values())) == len(MEDIAPIPE_TO_IBUG)
    assert all(0 <= i < 68 for i in MEDIAPIPE_TO_IBUG) and all(0 <= j < 468 for j in MEDIAPIPE_TO_IBUG.values())


def test_mediapipe_to_ibug_picks_the_mapped_points():
    points468 = np.zeros((2, 468, 3))
    points468[..., 0] = np.arange(468)  # x = MediaPipe index, so the picked x values are the indices
    points468[1, :, 0] += 1000.0
    sub = mediapipe_to_ibug(points468, [36, 45])
    assert sub.shape == (2, 2, 2)
    np.testing.assert_array_equal(sub[0, :, 0], [33, 263])
    np.testing.assert_array_equal(sub[1, :, 0], [1033, 1263])
    assert mediapipe_to_ibug(points468).shape == (2, len(MEDIAPIPE_SUBSET), 2)
    with pytest.raises(ValueError, match="no MediaPipe counterpart"):
        mediapipe_to_ibug(points468, [17])


def test_nme_by_region_hand_example_and_the_regions_make_up_the_whole():
    ref = _face68(eye_gap=10.0)
    pred = ref.copy()
    pred[8] += (0.0, 3.4)  # the chin 3.4 px off: jaw NME 3.4 / 17 / 10 = 0.02, every other region 0
    pred[[48, 54]] += (1.0, 0.0)  # both mouth corners 1 px: mouth 2 / 20 / 10 = 0.01
    got = nme_by_region(pred, ref)
    assert set(got) == {"jaw", "brows", "nose", "eyes", "mouth"}
    assert got["jaw"] == pytest.approx(0.02) and got["mouth"] == pytest.approx(0.01)
    assert got["brows"] == got["nose"] == got["eyes"] == 0.0
    assert sorted(i for r in IBUG_REGIONS.values() for i in r) == list(range(68))  # each point once
    rng = np.random.default_rng(SEED)
    batch_pred = ref + rng.normal(0, 2.0, (5, 68, 2))
    parts = nme_by_region(batch_pred, np.broadcast_to(ref, (5, 68, 2)))
    whole = sum(len(IBUG_REGIONS[k]) * v for k, v in parts.items()) / 68
    assert np.allclose(whole, nme(batch_pred, np.broadcast_to(ref, (5, 68, 2))))  # the regions make up the NME
    with pytest.raises(ValueError, match="shape"):
        nme_by_region(pred[:60], ref)


def test_nme_subset_hand_example():
    pred68 = np.full((68, 2), np.nan)  # points outside the subset may be NaN
    pred68[36] = (0.0, 0.0)
    pred68[45] = (20.0, 0.0)
    pred68[30] = (10.0, 10.0)
    ref = np.array([[0.0, 1.0], [10.0, 13.0], [20.0, 1.0]])  # iBUG 36, 30, 45; eye gap 20 px
    # errors 1, 3, 1 px -> mean 5/3 px -> NME (5/3) / 20 = 1/12
    assert nme_subset(pred68, ref, [36, 30, 45], (36, 45)) == pytest.approx(1.0 / 12.0)
    pred68[30] = np.nan
    assert np.isnan(nme_subset(pred68, ref, [36, 30, 45], (36, 45)))
    with pytest.raises(ValueError, match="norm_pair"):
        nme_subset(pred68, ref, [36, 30, 45], (39, 45))


@pytest.mark.shared_data
def test_mediapipe_map_lands_on_dlib_reference_cap12():
    dlib_ref = from_dlib(np.load(shared_path("videos", "cap12_edit_dlib68.npz"))["landmarks"])
    mp = np.load(shared_path("videos", "cap12_edit_mediapipe468.npz"))
    mp_px = from_normalised(mp["landmarks_norm"], mp["width"], mp["height"])
    sub = mediapipe_to_ibug(mp_px)
    eye_gap = np.linalg.norm(dlib_ref[:, 45] - dlib_ref[:, 36], axis=-1)  # about 65 px on cap12
    dist = np.linalg.norm(sub - dlib_ref[:, list(MEDIAPIPE_SUBSET)], axis=-1) / eye_gap[:, None]
    median = np.median(dist, axis=0)
    # every mapped point lies within 0.05 eye-gap (about 3 px) of the dlib point in the median frame
    assert (median < 0.05).all(), dict(zip(MEDIAPIPE_SUBSET, median.round(3)))
    # and the subset NME of the dlib track against MediaPipe is small (the two agree to about 0.02-0.03)
    assert np.mean(nme_subset(dlib_ref, sub)) < 0.04


def test_reference_conventions_land_on_the_package_pixels():
    """dlib's 0-based pixel indices and MediaPipe's normalised coordinates in the package's 1-based pixels: the
    top-left pixel's centre is PIXEL_ORIGIN in both, the bottom-right one's (w - 1 + PIXEL_ORIGIN, ...)."""
    w, h = 400, 300
    assert np.allclose(from_dlib([[0, 0], [w - 1, h - 1]]), [[PIXEL_ORIGIN, PIXEL_ORIGIN],
                                                           [w - 1 + PIXEL_ORIGIN, h - 1 + PIXEL_ORIGIN]])
    centres = np.array([[0.5 / w, 0.5 / h, 0.3], [(w - 0.5) / w, (h - 0.5) / h, -0.1]])  # (x, y, z), z dropped
    out = from_normalised(centres, w, h)
    assert out.shape == (2, 2)
    assert np.allclose(out, [[PIXEL_ORIGIN, PIXEL_ORIGIN], [w - 1 + PIXEL_ORIGIN, h - 1 + PIXEL_ORIGIN]])
    # the image's own edges lie half a pixel outside its outer pixels' centres
    assert np.allclose(from_normalised([[0.0, 1.0]], w, h), [[PIXEL_ORIGIN - 0.5, h - 1 + PIXEL_ORIGIN + 0.5]])
