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
    assert m.config["seed"] == 0  # the default, the shipped models'


def test_seed_is_recorded_and_changes_the_draws(tmp_path, dataset, capsys):
    out = tmp_path / "m7.npz"
    code = main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out), "--couples", "32:16,64:24",
                 "--seed", "7"])
    assert code == 0
    m7 = load_model(out)
    assert m7.config["seed"] == 7
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(tmp_path / "m0.npz"),
                 "--couples", "32:16,64:24"]) == 0
    m0 = load_model(tmp_path / "m0.npz")
    # the shape model does not depend on the draws; the learned updates do
    np.testing.assert_array_equal(m7.shape.mean, m0.shape.mean)
    assert not np.array_equal(m7.couples[-1].cascade, m0.couples[-1].cascade)


@pytest.mark.parametrize("seed", ["-1", "x"])
def test_bad_seed(tmp_path, dataset, capsys, seed):
    with pytest.raises(SystemExit) as exc:
        main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(tmp_path / "m.npz"), "--seed", seed])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--seed" in err and "whole number" in err


def test_workers_give_the_same_model(tmp_path, dataset, capsys):
    """``--workers`` sets the threads of the per-image work and nothing else (``tests/train/test_workers.py``
    checks every array of a 3D model with all its validators)."""
    for n in ("1", "2"):
        assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(tmp_path / f"m{n}.npz"),
                     "--couples", "32:16,64:24", "--workers", n]) == 0
    m1, m2 = load_model(tmp_path / "m1.npz"), load_model(tmp_path / "m2.npz")
    np.testing.assert_array_equal(m1.couples[-1].cascade, m2.couples[-1].cascade)
    np.testing.assert_array_equal(m1.landmark_cascade.regressors, m2.landmark_cascade.regressors)


@pytest.mark.parametrize("workers", ["0", "-2", "x"])
def test_bad_workers(tmp_path, dataset, capsys, workers):
    with pytest.raises(SystemExit) as exc:
        main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(tmp_path / "m.npz"),
              "--workers", workers])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--workers" in err and "number of threads" in err
    assert not (tmp_path / "m.npz").exists()


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


@pytest.mark.parametrize("couples", ["32:64", "4096:4096", "abc", "64:32,", "0:0"])
def test_bad_couples(tmp_path, dataset, capsys, couples):
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out), "--couples", couples]) == 1
    _one_line_error(capsys, "--couples")


def test_3d_without_candide_mesh(tmp_path, dataset, capsys, monkeypatch):
    monkeypatch.setattr("aamtrack.commands.train.default_candide_path", lambda: None)
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "3d", "--out", str(out)]) == 1
    _one_line_error(capsys, "--candide")
    assert not out.exists()


def test_pts_of_another_image_size(tmp_path, dataset, capsys):
    from aamtrack.io.pts import read_pts

    pts = read_pts(dataset / "face06.pts")
    write_pts(dataset / "face06.pts", pts * 3.0)  # the markup of the same face in a 3x larger copy
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "face06.pts", "outside the 220x220 image")
    assert not out.exists()


def test_tiny_image(tmp_path, dataset, capsys):
    cv2.imwrite(str(dataset / "face02.png"), np.zeros((1, 1), np.uint8))
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "face02.png", "1x1 px, too small")
    assert not out.exists()


@pytest.mark.parametrize("points", [np.full((68, 2), 50.0),  # all on one point
                                    np.column_stack([np.linspace(20, 200, 68), np.full(68, 100.0)])])  # a line
def test_degenerate_points(tmp_path, dataset, capsys, points):
    write_pts(dataset / "face07.pts", points)
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "face07.pts", "degenerate landmarks")
    assert not out.exists()


def test_numerical_failure_in_training_is_one_line(tmp_path, dataset, capsys, monkeypatch):
    def svd_fails(*a, **kw):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr("aamtrack.commands.train.train_model", svd_fails)
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "SVD did not converge", "training failed")
    assert not out.exists()


def test_report_in_a_missing_folder_fails_before_training(tmp_path, dataset, capsys, monkeypatch):
    monkeypatch.setattr("aamtrack.commands.train.train_model", lambda *a, **kw: pytest.fail("trained"))
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out),
                 "--report", str(tmp_path / "nope" / "fit.csv")]) == 1
    _one_line_error(capsys, "nope", "does not exist")
    assert not out.exists()


def test_report_failing_after_the_model_leaves_no_model(tmp_path, dataset, capsys, monkeypatch):
    from faults import disk_full, files_below

    (tmp_path / "models").mkdir()
    (tmp_path / "reports").mkdir()
    out = tmp_path / "models" / "m.npz"
    out.write_bytes(b"the previous model")
    disk_full(monkeypatch, tmp_path / "reports", 0)  # the report's disk is full, the model's is not
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out), "--couples", "32:16",
                 "--report", str(tmp_path / "reports" / "fit.csv")]) == 1
    _one_line_error(capsys, "fit.csv", "no space left")
    assert out.read_bytes() == b"the previous model"  # untouched, and no new model beside it
    assert files_below(tmp_path / "models") == ["m.npz"] and files_below(tmp_path / "reports") == []


def test_too_little_disk_space_fails_before_training(tmp_path, dataset, capsys, monkeypatch):
    import shutil
    from collections import namedtuple

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(10**9, 10**9 - 300_000, 300_000))
    monkeypatch.setattr("aamtrack.commands.train.train_model", lambda *a, **kw: pytest.fail("trained"))
    out = tmp_path / "m.npz"
    assert main(["train", "--data", str(dataset), "--kind", "2d", "--out", str(out)]) == 1
    _one_line_error(capsys, "0.3 MB free", "may need up to")
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
