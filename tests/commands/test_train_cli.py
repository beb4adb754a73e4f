"""``aamtrack train`` end to end on a tiny synthetic set, and every bad-input case."""

import cv2
import numpy as np
import pytest

from aamtrack.cli import main
from aamtrack.io.pts import write_pts
from aamtrack.model import load_model


@pytest.fixture
def dataset(tmp_path, synth_data):
    images, points = synth_data
    d = tmp_path / "data"
    d.mkdir()
    for i, (img, pts) in enumerate(zip(images[:12], points[:12], strict=True)):
        cv2.imwrite(str(d / f"face{i:02d}.png"), img)
        if i % 2:
            write_pts(d / f"face{i:02d}.pts", pts)
        else:  # the bare "x y" form is accepted too
            (d / f"face{i:02d}.pts").write_text("\n".join(f"{x} {y}" for x, y in pts))
    return d


def test_train_2d_writes_a_loadable_model(tmp_path, dataset, capsys):
    out = tmp_path / "m.npz"
    report = tmp_path / "fit.csv"
    code = main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out), "--couples", "32:16,64:24",
                 "--report", str(report)])
    assert code == 0
    m = load_model(out)
    assert m.kind == "2d" and [c.face_px for c in m.couples] == [32.0, 64.0]
    assert len(report.read_text().splitlines()) == 13  # header + one row per image
    assert "trained 2d model on 12 images" in capsys.readouterr().out


def _one_line_error(capsys, *needles):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aamtrack train: error:"), err
    for n in needles:
        assert n in err[0]


def test_missing_folder(tmp_path, capsys):
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(tmp_path / "nope"), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "nope", "no such folder")
    assert not out.exists()


def test_no_pairs(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "lonely.png").write_bytes(b"")
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(tmp_path / "empty"), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "no image with a .pts file")
    assert not out.exists()


def test_wrong_point_count(tmp_path, dataset, capsys):
    pts = (dataset / "face03.pts").read_text().splitlines()
    (dataset / "face03.pts").write_text("\n".join(l for l in pts if not l.startswith("1")) + "\n")
    bad = "\n".join(f"{x} {y}" for x, y in np.zeros((67, 2)))
    (dataset / "face05.pts").write_text(bad)
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "face0")
    assert not out.exists()


def test_unreadable_image(tmp_path, dataset, capsys):
    (dataset / "face04.png").write_bytes(b"\x89PNG broken")
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "face04.png", "cannot read image")
    assert not out.exists()


def test_bad_couples(tmp_path, dataset, capsys):
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out), "--couples", "32:64"]) == 1
    _one_line_error(capsys, "--couples")


def test_3d_without_candide_mesh(tmp_path, dataset, capsys, monkeypatch):
    monkeypatch.setattr("aamtrack.commands.train.default_candide_path", lambda: None)
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "3d", "--out", str(out)]) == 1
    _one_line_error(capsys, "--candide")
    assert not out.exists()


def test_without_out_writes_a_new_file_in_the_current_folder(tmp_path, dataset, capsys, monkeypatch):
    work = tmp_path / "work"
    (work / "models").mkdir(parents=True)
    shipped = work / "models" / "2d.npz"  # as in the repository root: the old default target
    shipped.write_bytes(b"shipped")
    (work / "aamtrack_2d.npz").write_bytes(b"an earlier model")
    monkeypatch.chdir(work)
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--couples", "32:16,64:24"]) == 0
    assert shipped.read_bytes() == b"shipped" and (work / "aamtrack_2d.npz").read_bytes() == b"an earlier model"
    assert load_model(work / "aamtrack_2d_2.npz").kind == "2d"  # numbered past the existing file
    assert "aamtrack_2d_2.npz" in capsys.readouterr().out
