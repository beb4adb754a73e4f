"""Training's augmentation: mirrored images with renumbered points, blurred copies that keep their parents'
points, and the bookkeeping that keeps an image and its copies together."""

import cv2
import numpy as np

from aamtrack.mesh.landmarks import mirror_points
from aamtrack.train.pipeline import TrainConfig, _augment, train_model
from conftest import SEED, SYNTH_COUPLES
import synth


def test_mirror_and_blurred_copies():
    images, points = synth.random_faces(6, np.random.default_rng(SEED), size=(160, 160))
    gray, pts, parent = _augment(images, points, True, 0.5, rng=np.random.default_rng(SEED))
    assert len(gray) == len(pts) == len(parent) == 12 + 6  # originals, mirrors, half of those blurred
    assert np.array_equal(parent[:12], np.arange(12)) and set(parent[12:]) <= set(range(12))
    assert np.allclose(pts[6:12], mirror_points(points, 160))  # mirrors renumbered (iBUG left/right)
    assert np.array_equal(gray[6], cv2.flip(gray[0], 1))
    for i in range(12, 18):
        j = parent[i]
        assert np.array_equal(pts[i], pts[j])  # a blurred copy keeps its parent's points
        assert gray[i].std() < gray[j].std()  # and is smoother
        assert abs(float(gray[i].mean()) - float(gray[j].mean())) < 1.0  # same image, blurred
    _, _, none = _augment(images, points, False, 0.0)
    assert np.array_equal(none, np.arange(6))


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
