"""Shared test fixtures: the location of ../shared/data and a skip marker for tests that need it."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tests/synth.py for every test folder

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SEED = 20261121


def shared_path(*parts: str) -> Path:
    """Path below ../shared/data; skips the calling test with a reason where it is absent."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs ../shared/data/{'/'.join(parts)} (absent here)")
    return path

SYNTH_COUPLES = ((32, 16), (64, 24), (128, 40))


@pytest.fixture(scope="session")
def synth_data():
    """24 rendered synthetic faces (images, (24, 68, 2) points) with known landmarks."""
    import numpy as np
    import synth

    return synth.random_faces(24, np.random.default_rng(SEED), size=(220, 220), scale=130.0)


@pytest.fixture(scope="session")
def synth_model(synth_data):
    """A 2D model trained on the synthetic faces (a few seconds)."""
    from aamtrack.train.pipeline import TrainConfig, train_model

    images, points = synth_data
    model, _ = train_model(images, points, "2d", config=TrainConfig(couples=SYNTH_COUPLES, pose_only_couples=2))
    return model


@pytest.fixture(scope="session")
def synth_model3d():
    """A 3D model (Candide-like synthetic mesh, ``synth3d``) trained on 30 posed synthetic faces, and the mesh."""
    import numpy as np
    import synth3d
    from aamtrack.train.pipeline import TrainConfig, train_model

    candide = synth3d.synthetic_candide()
    images, points, _, _ = synth3d.posed_faces(candide, 30, np.random.default_rng(SEED))
    model, _ = train_model(images, points, "3d", candide=candide,
                           config=TrainConfig(couples=SYNTH_COUPLES, map_refine_rounds=1, n_corrective=4))
    return model, candide


@pytest.fixture(scope="session")
def model_file(tmp_path_factory, synth_model):
    """The synthetic 2D model saved as a model file, for the command-line tests."""
    from aamtrack.model import save_model

    path = tmp_path_factory.mktemp("model") / "synth2d.npz"
    save_model(synth_model, path)
    return path
