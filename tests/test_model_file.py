import json

import numpy as np
import pytest

from aamtrack.errors import ModelFileError
from aamtrack.model import FORMAT_VERSION, load_model, save_model


def test_round_trip(tmp_path, synth_model):
    path = tmp_path / "m.npz"
    save_model(synth_model, path)
    m = load_model(path)
    assert m.kind == "2d" and m.shape.coef_names == synth_model.shape.coef_names
    for a, b in zip(m.couples, synth_model.couples):
        assert a.face_px == b.face_px and np.array_equal(a.U, b.U) and np.array_equal(a.free, b.free)
    for a, b in zip(m.textures, synth_model.textures):
        assert np.array_equal(a.mean, b.mean) and np.array_equal(a.frame.pix_bary, b.frame.pix_bary)
    assert np.array_equal(m.shape.landmark_map, synth_model.shape.landmark_map)
    assert m.config["residual_good"] == synth_model.config["residual_good"]
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]  # no temporary left behind


def _rewrite_meta(path, out, **changes):
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta.update(changes)
    data["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(out, **data)


def test_unknown_version_is_rejected(tmp_path, synth_model):
    save_model(synth_model, tmp_path / "m.npz")
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "future.npz", format_version=FORMAT_VERSION + 1)
    with pytest.raises(ModelFileError, match=f"format version {FORMAT_VERSION + 1} is not supported"):
        load_model(tmp_path / "future.npz")


@pytest.mark.parametrize("content,message", [(b"not a zip at all", "not a readable aamtrack model"),
                                             (None, "no such model file")])
def test_corrupt_or_missing(tmp_path, content, message):
    p = tmp_path / "bad.npz"
    if content is not None:
        p.write_bytes(content)
    with pytest.raises(ModelFileError, match=message):
        load_model(p)


def test_npz_without_meta(tmp_path):
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ModelFileError, match="no 'meta'"):
        load_model(tmp_path / "other.npz")


def test_truncated_file(tmp_path, synth_model):
    save_model(synth_model, tmp_path / "m.npz")
    data = (tmp_path / "m.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError):
        load_model(tmp_path / "cut.npz")
