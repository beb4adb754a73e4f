"""The ICT FaceKit sequence generator (needs ../shared/data; skips with a reason where absent)."""

import numpy as np
import pytest
from conftest import SEED, shared_path

from aamtrack.errors import InputError
from aamtrack.refine.sequences import apply_weights, load_face_model, make_sequence

pytestmark = pytest.mark.shared_data


def test_sequence_shape_smoothness_and_neutral_start():
    model = load_face_model(shared_path("ict_facekit", "ict_face_light_head11248.npz"))
    seq = make_sequence(model, n_frames=101, seed=SEED)
    assert seq.frames.shape == (101, 11248, 3) and seq.frames.dtype == np.float32
    assert np.array_equal(seq.weights[0], np.zeros(len(model.expression_names)))  # F^0 is neutral
    assert 0.0 <= seq.weights.min() and seq.weights.max() <= 1.0
    names = model.expression_names
    for name in ("jawOpen", "mouthSmile_L", "eyeBlink_L"):  # talking, smiling, blinking all happen
        assert seq.weights[:, names.index(name)].max() > 0.2, name
    step = np.abs(np.diff(seq.weights, axis=0)).max()
    assert step < 0.5  # smooth in time: no weight jumps by half its range between frames
    again = apply_weights(model, seq.identity, seq.weights)
    assert np.abs(again - seq.frames).max() < 1e-5  # same ground truth from the weights (float32)


def test_missing_keys_raise_input_error(tmp_path):
    np.savez(tmp_path / "bad.npz", neutral=np.zeros((3, 3)))
    with pytest.raises(InputError, match="bad.npz"):
        load_face_model(tmp_path / "bad.npz")


@pytest.mark.parametrize("content, problem", [(None, "a bare array, not an .npz archive"),
                                              (b"plain text", "not an .npz archive"), (b"", "empty file")])
def test_a_file_that_is_no_archive_is_named_as_such(tmp_path, content, problem):
    path = tmp_path / "face.npz"
    if content is None:
        np.save(tmp_path / "face.npy", np.zeros((3, 3)))
        (tmp_path / "face.npy").rename(path)
    else:
        path.write_bytes(content)
    with pytest.raises(InputError, match=rf"face.npz: cannot read face model \({problem}\)$"):
        load_face_model(path)
