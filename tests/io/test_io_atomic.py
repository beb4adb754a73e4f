"""Atomic writes and the JSON summary: complete files or nothing, an existing file untouched on failure."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import SEED

from aamtrack.io import atomic_write, save_npz, to_jsonable, write_summary_json


class Boom(RuntimeError):
    pass


def test_text_and_binary(tmp_path):
    with atomic_write(tmp_path / "a.txt") as f:
        f.write("hello\n")
    with atomic_write(tmp_path / "b.bin", "wb", fsync=True) as f:
        f.write(b"\x00\x01")
    assert (tmp_path / "a.txt").read_text() == "hello\n"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bin"]


def test_failure_leaves_existing_file_untouched(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old content\n")
    with pytest.raises(Boom):
        with atomic_write(path) as f:
            f.write("half of the new")
            raise Boom
    assert path.read_text() == "old content\n"
    assert list(tmp_path.iterdir()) == [path]  # temporary file removed


def test_failure_leaves_nothing_new(tmp_path):
    with pytest.raises(Boom):
        with atomic_write(tmp_path / "new.txt", "wb") as f:
            f.write(b"partial")
            raise Boom
    assert not list(tmp_path.iterdir())


def test_replacing_keeps_the_file_mode(tmp_path):
    path = tmp_path / "script.sh"
    path.write_text("old")
    path.chmod(0o751)
    with atomic_write(path) as f:
        f.write("new")
    assert path.read_text() == "new" and (path.stat().st_mode & 0o777) == 0o751


def test_bad_mode(tmp_path):
    with pytest.raises(ValueError, match="mode"):
        with atomic_write(tmp_path / "x", "a"):
            pass


def test_save_npz_exact_name(tmp_path):
    rng = np.random.default_rng(SEED)
    arrays = {"mean": rng.normal(size=(5, 2)), "path": np.arange(3), "format_version": np.int64(1)}
    save_npz(tmp_path / "model.bin", **arrays)  # no ".npz" appended; an array may be called "path"
    with np.load(tmp_path / "model.bin", allow_pickle=False) as data:
        assert sorted(data.files) == sorted(arrays)
        for key, value in arrays.items():
            np.testing.assert_array_equal(data[key], value)


def test_summary_json_converts_numpy(tmp_path):
    data = {
        "n_frames": np.int64(12),
        "fps": np.float32(29.97),
        "ok": np.bool_(True),
        "rate": np.array([0.5, np.nan, 1.0]),
        "counts": {"tracked": np.int32(10), 3: "int key"},
        "sizes": (320, 240),
        "model": Path("models/a.npz"),
        "inf": float("inf"),
    }
    path = tmp_path / "summary.json"
    write_summary_json(path, data)
    text = path.read_text()
    assert text.startswith('{\n  "n_frames": 12,') and text.endswith("}\n")
    back = json.loads(text)
    assert back["fps"] == pytest.approx(29.97, rel=1e-6)
    assert back["ok"] is True and back["rate"] == [0.5, None, 1.0] and back["inf"] is None
    assert back["counts"] == {"tracked": 10, "3": "int key"}
    assert back["sizes"] == [320, 240] and back["model"] == "models/a.npz"


def test_summary_json_unknown_type_writes_nothing(tmp_path):
    with pytest.raises(TypeError, match="object"):
        write_summary_json(tmp_path / "s.json", {"x": object()})
    assert not list(tmp_path.iterdir())
    assert to_jsonable([np.uint8(3), {np.str_("k"): np.float64(1.5)}]) == [3, {"k": 1.5}]
