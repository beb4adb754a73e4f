"""``aamtrack fit`` on a folder of synthetic stills: one row per image with a ``file`` column, .pts per fit, and
bad input as one line."""

import cv2
import numpy as np
import pytest

from aamtrack.cli import main
from aamtrack.io.csvout import read_tracking_csv
from aamtrack.io.pts import read_pts
from conftest import SEED
import synth


@pytest.fixture
def stills(tmp_path):
    folder = tmp_path / "stills"
    folder.mkdir()
    images, points = synth.random_faces(3, np.random.default_rng(SEED + 11), size=(220, 220), scale=130.0)
    for k, img in enumerate(images):
        cv2.imwrite(str(folder / f"face{k}.png"), img)
    cv2.imwrite(str(folder / "z_blank.png"), np.full((220, 220), 128, np.uint8))
    (folder / "z_broken.png").write_bytes(b"not a png")
    return folder, points


def test_fit_folder(tmp_path, stills, model_file, capsys):
    folder, points = stills
    out = tmp_path / "out"
    assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out), "--pts"]) == 0
    cols = read_tracking_csv(out / "stills.csv")
    assert list(cols)[0] == "file"
    assert cols["file"].tolist() == ["face0.png", "face1.png", "face2.png", "z_blank.png", "z_broken.png"]
    assert cols["success"].tolist() == [1, 1, 1, 0, 0]
    assert cols["status"][-1] == "unreadable"
    for k in range(3):
        fitted = np.column_stack([[cols[f"x_{i}"][k] for i in range(68)], [cols[f"y_{i}"][k] for i in range(68)]])
        assert np.linalg.norm(fitted - points[k], axis=1).mean() < 2.0  # within two pixels of the truth
        assert np.abs(read_pts(out / "stills_pts" / f"face{k}.pts") - fitted).max() < 1e-2
    assert sorted(p.name for p in (out / "stills_pts").iterdir()) == ["face0.pts", "face1.pts", "face2.pts"]
    assert "3 fitted" in capsys.readouterr().out


@pytest.mark.parametrize("make,needle", [(lambda d: d / "missing", "no such file"),
                                         (lambda d: d / "empty", "no image files"),
                                         (lambda d: d / "notes.txt", "notes.txt: not an image OpenCV can read")])
def test_fit_bad_input_is_one_line(tmp_path, model_file, capsys, make, needle):
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.txt").write_text("not a picture\n")
    out = tmp_path / "out"
    assert main(["fit", str(make(tmp_path)), "--model", str(model_file), "--out-dir", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aamtrack fit: error:") and needle in err[0], err
    assert not out.exists()


def test_fit_without_any_face_is_one_line_and_nothing_written(tmp_path, model_file, capsys):
    folder = tmp_path / "walls"
    folder.mkdir()
    for k in range(2):
        cv2.imwrite(str(folder / f"wall{k}.png"), np.full((160, 160), 100 + 40 * k, np.uint8))
    out = tmp_path / "out"
    assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aamtrack fit: error:"), err  # bad input: one line, exit 1
    assert err[0].endswith("walls: no face fitted in any of its 2 images (0 rejected, 2 without a face found, "
                           "0 unreadable)"), err
    assert not out.exists()  # nothing written


def test_fit_refuses_a_video(tmp_path, model_file, capsys):
    frames, _ = synth.moving_face_frames(3)
    video = tmp_path / "clip.avi"
    synth.write_video(video, frames)
    assert main(["fit", str(video), "--model", str(model_file), "--out-dir", str(tmp_path / "out")]) == 1
    assert "takes images" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_fit_no_mirror_fits_once(tmp_path, stills, model_file):
    """``--no-mirror`` fits each image once (the summary says which), about as well on these symmetric faces; by
    default the mirror is fitted too, and the two runs' points differ by that average only (under a pixel)."""
    import json

    folder, points = stills
    runs = {}
    for flag in ([], ["--no-mirror"]):
        out = tmp_path / ("once" if flag else "both")
        assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out), *flag]) == 0
        assert json.loads((out / "stills.json").read_text())["mirror"] is (not flag)
        cols = read_tracking_csv(out / "stills.csv")
        runs[bool(flag)] = np.stack([np.column_stack([[cols[f"x_{i}"][k] for i in range(68)],
                                                      [cols[f"y_{i}"][k] for i in range(68)]]) for k in range(3)])
    for k in range(3):
        assert np.linalg.norm(runs[True][k] - points[k], axis=1).mean() < 2.0  # within two pixels of the truth
        gap = np.linalg.norm(runs[True][k] - runs[False][k], axis=1)
        assert 0 < gap.max() < 1.0  # the mirrored fit's share moved them, a little


def test_fit_jobs_gives_the_same_outputs(tmp_path, stills, model_file):
    """``--jobs 2`` fits the images in two worker processes, each reading its own images: the CSV rows (in the
    images' order) and the .pts files are the same bytes as one image at a time in this process."""
    import json

    folder, _ = stills
    outs = {}
    for jobs in (1, 2):
        outs[jobs] = out = tmp_path / f"jobs{jobs}"
        assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out), "--pts",
                     "--jobs", str(jobs)]) == 0
        assert json.loads((out / "stills.json").read_text())["jobs"] == jobs
    assert (outs[1] / "stills.csv").read_bytes() == (outs[2] / "stills.csv").read_bytes()
    names = sorted(p.name for p in (outs[1] / "stills_pts").iterdir())
    assert names == sorted(p.name for p in (outs[2] / "stills_pts").iterdir()) and len(names) == 3
    for name in names:
        assert (outs[1] / "stills_pts" / name).read_bytes() == (outs[2] / "stills_pts" / name).read_bytes()


def test_fit_bad_jobs_is_one_line(tmp_path, stills, model_file, capsys):
    folder, _ = stills
    out = tmp_path / "out"
    assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out), "--jobs", "0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--jobs 0" in err[0], err
    assert not out.exists()


def test_fit_worker_that_dies_stops_the_run_with_one_line(tmp_path, stills, model_file, capsys, monkeypatch):
    """A worker process killed mid-run (here: it exits on the second image) stops ``aamtrack fit --jobs 2`` with
    one line and exit 1, and nothing is written."""
    import multiprocessing
    import os

    from aamtrack.commands import batch, fit

    folder, _ = stills
    real = fit._fit_image

    def dying(tracker, index, path, readable, mirror):
        if index == 1:
            os._exit(3)  # as a process killed by the system would end
        return real(tracker, index, path, readable, mirror)

    monkeypatch.setattr(fit, "_fit_image", dying)
    # forked workers run the patched function (the pool would start them from a fork server, which imports the
    # module afresh, when this process has other threads: a previous test's progress-bar monitor)
    monkeypatch.setattr(batch, "_pool_context", lambda: multiprocessing.get_context("fork"))
    out = tmp_path / "out"
    assert main(["fit", str(folder), "--model", str(model_file), "--out-dir", str(out), "--jobs", "2"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a worker process failed" in err[0], err
    assert not out.exists()
