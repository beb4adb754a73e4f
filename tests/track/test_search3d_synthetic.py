"""The 3D default path without ../shared: a 3D model trained on the synthetic Candide-like face (``synth3d``)
searches from displaced starts and tracks a written video of a turning head, against the renders' true
landmarks and pose."""

import numpy as np
import pytest

from aamtrack.imaging import to_gray32
from aamtrack.io.frames import open_frames
from aamtrack.metrics import PIXEL_ORIGIN
from aamtrack.search import Searcher
from aamtrack.track.tracker import Tracker
from aamtrack.train.shape_fit import fit_landmarks
from conftest import SEED
import synth
import synth3d


def test_3d_search_recovers_displaced_starts(synth_model3d):
    model, candide = synth_model3d
    sm = model.shape
    searcher = Searcher(model)
    rng = np.random.default_rng(SEED + 3)
    images, points, _, _ = synth3d.posed_faces(candide, 8, rng)  # faces not seen in training
    points = points - PIXEL_ORIGIN  # labels are 1-based; the search works in OpenCV's pixels
    before, after, floor = [], [], []
    for img, pts in zip(images, points):
        truth = fit_landmarks(sm, pts)  # the model's own best description (its mean person differs)
        p0 = np.r_[truth.q, truth.shape_params]
        width = np.ptp(pts[:, 0])
        p0[4:6] += 0.05 * width * np.array([np.cos(2.0), np.sin(2.0)])
        p0[1] += 0.1  # yaw, radians
        p0[2] += np.radians(5.0)
        p0[3] *= 1.04
        res = searcher.fit(searcher.levels(to_gray32(img)), p0)
        before.append(np.linalg.norm(sm.landmarks(p0[:sm.n_q], p0[sm.n_q:]) - pts, axis=1).mean())
        after.append(np.linalg.norm(res.landmarks - pts, axis=1).mean())
        floor.append(truth.rms_px)
    print(f"3D search, mean px error: start {np.mean(before):.2f}, after {np.mean(after):.2f}, "
          f"model floor (RMS) {np.mean(floor):.2f}")
    assert np.mean(before) > 5.0  # the start is really off
    assert np.mean(after) < 1.0  # back to about a pixel (faces 130 px wide)


@pytest.fixture(scope="module")
def turning_video(tmp_path_factory, synth_model3d):
    """40 frames of the synthetic 3D face turning (yaw +-0.3 rad) and moving, its true landmarks and yaw."""
    _, candide = synth_model3d
    sm = synth3d.shape_model(candide)
    frames, truth, yaws = [], [], []
    for i in range(40):
        t = 2 * np.pi * i / 40
        q = np.zeros(sm.n_q)
        q[:6] = 0.05 * np.sin(2 * t), 0.3 * np.sin(t), 0.03 * np.cos(t), 120.0, 160 + 8 * np.sin(t), 120.0
        pts = sm.landmarks(q)
        g = synth.render(synth.face_layout(), pts, (320, 240))
        frames.append(np.dstack([g, g, g]))
        truth.append(pts)
        yaws.append(q[1])
    path = tmp_path_factory.mktemp("v3d") / "turning.avi"
    synth.write_video(path, frames)
    return path, np.array(truth), np.array(yaws)


def test_3d_tracker_follows_a_turning_head(turning_video, synth_model3d):
    model, _ = synth_model3d
    path, truth, yaws = turning_video
    with open_frames(path) as src:
        results = list(Tracker(model).track(src))
    assert [r.frame for r in results] == list(range(40)) and all(r.success for r in results)
    err = np.array([np.linalg.norm(r.landmarks - t, axis=1).mean() for r, t in zip(results, truth)])
    yaw = np.array([r.rotation[1] for r in results])
    print(f"3D tracker: mean landmark error {err.mean():.2f} px (worst {err.max():.2f}); yaw error median "
          f"{np.degrees(np.median(np.abs(yaw - yaws))):.1f} deg")
    assert err.mean() < 1.5 and err.max() < 3.0  # about a pixel on a 120-px face, MJPG-compressed
    assert np.corrcoef(yaw, yaws)[0, 1] > 0.9  # the head's turn is read as yaw, with its sign
