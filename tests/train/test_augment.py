"""Training's augmentation: mirrored images with renumbered points, blurred copies that keep their parents'
points, and the bookkeeping that keeps an image and its copies together."""

import cv2
import numpy as np

from aamtrack.mesh.landmarks import affine_points, mirror_points
from aamtrack.metrics import PIXEL_ORIGIN
from aamtrack.train.pipeline import TrainConfig, _augment, train_model
from conftest import SEED, SYNTH_COUPLES
import synth


def test_mirror_and_blurred_copies():
    images, points = synth.random_faces(6, np.random.default_rng(SEED), size=(160, 160))
    gray, pts, parent = _augment(images, points, True, 0.5, rng=np.random.default_rng(SEED))
    assert len(gray) == len(pts) == len(parent) == 12 + 6  # originals, mirrors, half of those blurred
    assert np.array_equal(parent[:12], np.arange(12)) and set(parent[12:]) <= set(range(12))
    assert np.allclose(pts[6:12], mirror_points(points, 160, origin=0.0))  # renumbered (iBUG left/right); OpenCV's pixels
    assert np.array_equal(gray[6], cv2.flip(gray[0], 1))
    for i in range(12, 18):
        j = parent[i]
        assert np.array_equal(pts[i], pts[j])  # a blurred copy keeps its parent's points
        assert gray[i].std() < gray[j].std()  # and is smoother
        assert abs(float(gray[i].mean()) - float(gray[j].mean())) < 1.0  # same image, blurred
    _, _, none = _augment(images, points, False, 0.0)
    assert np.array_equal(none, np.arange(6))


def test_mirrored_points_stay_on_what_they_mark():
    """A point marks a blob in the package's 1-based pixels (300-W's, PIXEL_ORIGIN): after cv2.flip the mirrored
    point (renumbered) marks the same blob. The former x -> w - 1 - x put every mirrored label 2 px to the left."""
    w, h = 120, 90
    p = np.array([37.3, 51.6])  # 1-based: the blob is centred at OpenCV pixel (36.3, 50.6)
    yy, xx = np.mgrid[0:h, 0:w] + PIXEL_ORIGIN
    blob = np.exp(-((xx - p[0]) ** 2 + (yy - p[1]) ** 2) / (2 * 2.0 ** 2))
    flipped = cv2.flip(blob, 1)
    centre = np.array([(flipped * xx).sum(), (flipped * yy).sum()]) / flipped.sum()
    points = np.zeros((68, 2))
    points[36] = p  # the subject's right outer eye corner: iBUG 45 once mirrored
    moved = mirror_points(points, w)
    assert np.abs(moved[45] - centre).max() < 1e-6  # px
    assert moved[45, 0] == w + 1 - p[0]


def test_affine_points_follow_warp_affine():
    """Points moved by affine_points mark the same blob after cv2.warpAffine (rotation, scale and shift)."""
    w, h = 160, 120
    p = np.array([70.4, 48.2])
    yy, xx = np.mgrid[0:h, 0:w] + PIXEL_ORIGIN
    blob = np.exp(-((xx - p[0]) ** 2 + (yy - p[1]) ** 2) / (2 * 3.0 ** 2))
    A = cv2.getRotationMatrix2D((60.0, 50.0), 25.0, 0.8)
    A[:, 2] += (7.5, -3.25)
    out = cv2.warpAffine(blob, A, (w, h), flags=cv2.INTER_LINEAR)
    centre = np.array([(out * xx).sum(), (out * yy).sum()]) / out.sum()
    assert np.abs(affine_points(p, A) - centre).max() < 0.02  # px (bilinear resampling of a 3 px blob)


def test_training_with_blurred_copies_keeps_the_shape_model(synth_data):
    """The blurred copies only add regression data: the shape model and the appearance come from the sharp set."""
    images, points = synth_data
    images, points = images[:12], points[:12]
    cfg = TrainConfig(couples=SYNTH_COUPLES, pose_only_couples=2, validator_images=60)
    plain, _ = train_model(images, points, "2d", config=cfg)
    blurred, _ = train_model(images, points, "2d", config=TrainConfig(**{**cfg.__dict__, "blur_share": 0.5}))
    assert np.allclose(plain.shape.mean, blurred.shape.mean)
    assert np.allclose(plain.textures[-1].mean, blurred.textures[-1].mean)
    a, b = plain.couples[-1].cascade, blurred.couples[-1].cascade
    assert a.shape != b.shape or not np.allclose(a, b)  # the cascade did learn from the extra starts


def test_landmark_cascade_learns_from_blurred_copies_too(synth_data):
    """``landmark_blur_share`` adds blurred copies to the landmark cascade's data only: the search is the same,
    the cascade differs and still moves its training starts toward the labels."""
    images, points = synth_data
    images, points = images[:12], points[:12]
    cfg = TrainConfig(couples=SYNTH_COUPLES, pose_only_couples=2, validator_images=60, landmark_starts=6)
    plain, _ = train_model(images, points, "2d", config=cfg)
    blurred, _ = train_model(images, points, "2d", config=TrainConfig(**{**cfg.__dict__,
                                                                          "landmark_blur_share": 0.5}))
    assert np.array_equal(plain.couples[-1].cascade, blurred.couples[-1].cascade)  # the search is untouched
    assert not np.allclose(plain.landmark_cascade.regressors, blurred.landmark_cascade.regressors)
    stages = blurred.config["landmark_stages"]
    assert stages[-1]["train_nme_mean"] < stages[0]["train_nme_mean"]  # later stages keep lowering the error


def test_landmark_cascade_learns_from_occluded_copies_too():
    """``landmark_occlude_share`` adds occluded copies (``train.validator.occluded_copy``) to the first landmark
    cascade's data only, for the 3D model: the search is the same, the cascade differs and still moves its
    training starts toward the labels."""
    import synth3d

    candide = synth3d.synthetic_candide()
    images, points, _, _ = synth3d.posed_faces(candide, 16, np.random.default_rng(SEED))
    cfg = TrainConfig(couples=SYNTH_COUPLES, map_refine_rounds=1, n_corrective=4, validator_images=60,
                      landmark_starts=6, landmark_occlude_share=0.0)
    plain, _ = train_model(images, points, "3d", candide=candide, config=cfg)
    occluded, _ = train_model(images, points, "3d", candide=candide,
                              config=TrainConfig(**{**cfg.__dict__, "landmark_occlude_share": 0.5}))
    assert np.array_equal(plain.couples[-1].cascade, occluded.couples[-1].cascade)  # the search is untouched
    assert not np.allclose(plain.landmark_cascade.regressors, occluded.landmark_cascade.regressors)
    stages = occluded.config["landmark_stages"]
    assert stages[-1]["train_nme_mean"] < stages[0]["train_nme_mean"]  # later stages keep lowering the error
