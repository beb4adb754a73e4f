"""Atomic writes and the JSON summary: complete files or nothing, an existing file untouched on failure."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import SEED

from aamtrack.errors import OutputError
from aamtrack.io import atomic_write, save_npz, to_jsonable, write_summary_json
from aamtrack.io.atomic import OutputSet, check_replaceable


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


# --- OutputSet: the outputs of one run, committed together -------------------------------------------------


def _listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def test_output_set_commits_all_together(tmp_path):
    out = tmp_path / "a" / "b"
    with OutputSet(out) as outputs:
        outputs.prepare()
        csv_tmp = outputs.file("x.csv")
        pts_tmp = outputs.folder_output("x_pts")
        csv_tmp.write_text("rows\n")
        (pts_tmp / "f1.pts").write_text("p\n")
        assert not (out / "x.csv").exists()  # nothing under a final name before the commit
        outputs.commit()
    assert _listing(out) == ["x.csv", "x_pts", "x_pts/f1.pts"]


def test_output_set_failure_leaves_nothing_and_removes_created_folders(tmp_path):
    out = tmp_path / "a" / "b"
    with pytest.raises(Boom):
        with OutputSet(out) as outputs:
            outputs.prepare()
            outputs.file("x.csv").write_text("half")
            (outputs.folder_output("x_pts") / "f.pts").write_text("p")
            raise Boom
    assert _listing(tmp_path) == []


def test_output_set_rename_failure_restores_previous_outputs(tmp_path, monkeypatch):
    (tmp_path / "x.csv").write_text("old csv")
    (tmp_path / "x.json").write_text("old json")
    outputs = OutputSet(tmp_path).prepare()
    outputs.file("x.csv").write_text("new csv")
    outputs.file("x.json").write_text("new json")
    real_replace, calls = os.replace, []

    def replace(src, dst):  # renames: old x.csv aside, new x.csv in, old x.json aside, new x.json in: fails
        calls.append(dst)
        if len(calls) == 4:
            raise OSError(5, "Input/output error")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OutputError, match="Input/output error"):
        outputs.commit()
    monkeypatch.undo()
    assert (tmp_path / "x.csv").read_text() == "old csv" and (tmp_path / "x.json").read_text() == "old json"
    assert _listing(tmp_path) == ["x.csv", "x.json"]


def test_outputs_only_replace_regular_files(tmp_path):
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "target").write_text("t")
    os.symlink(tmp_path / "target", tmp_path / "link")
    for name, what in (("pipe", "device or special file"), ("link", "symbolic link")):
        with pytest.raises(OutputError, match=what):
            check_replaceable(tmp_path / name)
        with pytest.raises(OutputError, match=what):
            with atomic_write(tmp_path / name) as f:
                f.write("x")
    if os.path.exists("/dev/null"):
        with pytest.raises(OutputError, match="device"):
            write_summary_json("/dev/null", {"a": 1})
    assert (tmp_path / "target").read_text() == "t" and _listing(tmp_path) == ["link", "pipe", "target"]


def test_folder_output_refuses_a_folder_with_more_than_files(tmp_path):
    (tmp_path / "x_pts" / "sub").mkdir(parents=True)
    with pytest.raises(OutputError, match="holds more than files"):
        OutputSet(tmp_path).folder_output("x_pts")
