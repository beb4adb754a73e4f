"""benchmarks/video_pose.py's reading of a head's turns from 3D points, on point clouds turned by known angles."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from conftest import SEED  # noqa: E402
from video_pose import compare, point_rotations, rotation_angles  # noqa: E402

from aamtrack.mesh.shape_model import rotation_matrix  # noqa: E402


def test_rotation_angles_invert_the_models_rotation():
    rng = np.random.default_rng(SEED)
    for _ in range(50):
        angles = rng.uniform([-1.0, -1.4, -3.0], [1.0, 1.4, 3.0])
        assert np.abs(rotation_angles(rotation_matrix(*angles)) - angles).max() < 1e-9


def test_point_rotations_recover_known_turns_up_to_a_common_zero():
    """A random cloud turned, scaled and moved by known amounts per frame: the turns read from the frames about
    their mean match the true ones (the points' rotations are of their mean shape, in another frame than the
    truth's: ``relative_angles`` takes that away exactly)."""
    rng = np.random.default_rng(SEED)
    cloud = rng.normal(size=(40, 3)) * [60.0, 80.0, 30.0]
    truth = np.c_[rng.uniform(-0.3, 0.3, 30) - 0.4, rng.uniform(-0.5, 0.5, 30), rng.uniform(-0.2, 0.2, 30)]
    frames = np.stack([rng.uniform(0.8, 1.2) * cloud @ rotation_matrix(*a).T + rng.uniform(-50, 50, 3)
                       for a in truth])
    frames[7] = np.nan  # a frame without points
    read = point_rotations(frames)
    assert np.isnan(read[7]).all() and np.isfinite(np.delete(read, 7, 0)).all()
    c = compare(read, np.stack([rotation_matrix(*a) for a in truth]))
    assert c["frames"] == 29
    assert max(c["pitch_rms"], c["yaw_rms"], c["roll_rms"]) < 1e-6  # degrees
    assert min(c["pitch_corr"], c["yaw_corr"], c["roll_corr"]) > 0.999999
