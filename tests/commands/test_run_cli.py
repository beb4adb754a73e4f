"""``aamtrack run`` end to end on synthetic videos, and every bad-input case."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from notices import stderr_lines
from aamtrack.cli import main
from aamtrack.io.csvout import read_tracking_csv
import synth


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    frames, truth = synth.moving_face_frames(20)
    path = tmp_path_factory.mktemp("vid") / "clip.avi"
    synth.write_video(path, frames)
    return path, truth


def _frames_in(path) -> int:
    """Frames OpenCV decodes from the video at ``path``."""
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    return n


def _err_line(capsys, *needles):
    err = stderr_lines(capsys)
    assert len(err) == 1 and err[0].startswith("aamtrack run: error:"), err
    for n in needles:
        assert n in err[0]


def test_run_end_to_end(tmp_path, video, model_file, capsys):
    path, truth = video
    out = tmp_path / "out"
    assert main(["run", str(path), "--model", str(model_file), "--out-dir", str(out), "--video", "--pts",
                 "--no-smooth"]) == 0  # the tracker's own accuracy: smoothing trails the moving face a little
    cols = read_tracking_csv(out / "clip.csv")
    assert cols["frame"].tolist() == list(range(20))  # exactly one row per frame
    assert (cols["success"] == 1).all()
    pred = np.stack([np.column_stack([cols[f"x_{i}"], cols[f"y_{i}"]]) for i in range(68)], axis=1)
    assert np.linalg.norm(pred - truth, axis=2).mean() < 1.0  # within a pixel of the truth
    assert np.allclose(cols["timestamp"], np.arange(20) / 25.0, atol=1e-4)
    summary = json.loads((out / "clip.json").read_text())
    assert summary["frames_read"] == 20 and summary["frames_tracked"] == 20 and summary["frames_lost"] == 0
    assert _frames_in(summary["outputs"]["video"]) == 20  # overlay: one frame per input frame
    assert len(list((out / "clip_pts").glob("*.pts"))) == 20
    printed = capsys.readouterr().out
    assert "20 frames: 20 tracked" in printed
    for name in ("clip.csv", "clip.json", Path(summary["outputs"]["video"]).name, "clip_pts/ (20 files)"):
        assert name in printed  # the final line names every output
    assert summary["smoothing"] is None


def test_fast_video_writes_the_overlay_in_mp4v(tmp_path, video, model_file, capsys):
    """``--fast-video``: the overlay in mp4v (.mp4), one frame per input frame, without ``--video``."""
    out = tmp_path / "out"
    assert main(["run", str(video[0]), "--model", str(model_file), "--out-dir", str(out), "--fast-video"]) == 0
    summary = json.loads((out / "clip.json").read_text())
    assert summary["outputs"]["video"] == str(out / "clip_overlay.mp4")
    cap = cv2.VideoCapture(summary["outputs"]["video"])
    assert int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").upper() in (b"MP4V", b"FMP4")
    assert _frames_in(summary["outputs"]["video"]) == 20
    assert sorted(p.name for p in out.iterdir()) == ["clip.csv", "clip.json", "clip_overlay.mp4"]
    assert "clip_overlay.mp4" in capsys.readouterr().out


def test_default_output_folder_is_next_to_the_input(tmp_path, video, model_file):
    src = tmp_path / "here.avi"
    src.write_bytes(video[0].read_bytes())
    assert main(["run", str(src), "--model", str(model_file)]) == 0
    assert (tmp_path / "here_aamtrack" / "here.csv").is_file()


def test_video_without_a_face(tmp_path, model_file, capsys):
    """A video in which no face is found is bad input: one line, exit 1, nothing written."""
    frames = [np.full((120, 160, 3), 90, np.uint8) for _ in range(6)]
    synth.write_video(tmp_path / "empty_room.avi", frames)
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "empty_room.avi"), "--model", str(model_file), "--out-dir", str(out)]) == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and err[0].startswith("aamtrack run: error:"), err
    assert err[0].endswith("empty_room.avi: no face found in any of its 6 frames"), err
    assert not out.exists()


def test_realtime_drops_frames_of_a_fast_source(tmp_path, model_file):
    frames, _ = synth.moving_face_frames(12)
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"f{i}.png"), f)
    out = tmp_path / "out"
    # at 10,000 fps a new frame arrives every 0.1 ms: the tracker cannot keep up
    assert main(["run", str(folder), "--model", str(model_file), "--out-dir", str(out), "--realtime",
                 "--fps", "10000"]) == 0
    cols = read_tracking_csv(out / "frames.csv")
    assert cols["frame"].tolist() == list(range(12))
    assert cols["dropped"].sum() > 0 and (cols["success"][cols["dropped"] == 1] == 0).all()
    summary = json.loads((out / "frames.json").read_text())
    assert summary["frames_dropped"] == int(cols["dropped"].sum())
    assert summary["smoothing"]["look_ahead_frames"] == 0  # a live clock has no frames ahead: forwards only


@pytest.mark.parametrize("make,needle", [
    (lambda p: None, "clip.mp4"),
    (lambda p: p.write_text("this is not a video"), "clip.mp4"),
    (lambda p: p.write_bytes(b""), "clip.mp4"),
])
def test_bad_video_files(tmp_path, model_file, capsys, make, needle):
    src = tmp_path / "clip.mp4"
    make(src)
    out = tmp_path / "out"
    assert main(["run", str(src), "--model", str(model_file), "--out-dir", str(out)]) == 1
    _err_line(capsys, needle)
    assert not out.exists()  # nothing written


def test_zero_frame_video(tmp_path, model_file, capsys):
    vw = cv2.VideoWriter(str(tmp_path / "zero.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 25, (64, 48))
    vw.release()
    out = tmp_path / "out"
    assert main(["run", str(tmp_path / "zero.avi"), "--model", str(model_file), "--out-dir", str(out)]) == 1
    _err_line(capsys, "zero.avi")
    assert not out.exists()


def test_unknown_model_version(tmp_path, video, model_file, capsys):
    with np.load(model_file, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta["format_version"] = 99
    data["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(tmp_path / "future.npz", **data)
    out = tmp_path / "out"
    assert main(["run", str(video[0]), "--model", str(tmp_path / "future.npz"), "--out-dir", str(out)]) == 1
    _err_line(capsys, "future.npz", "version 99")
    assert not out.exists()


def test_unreadable_frame_in_a_folder(tmp_path, model_file):
    frames, _ = synth.moving_face_frames(8)
    folder = tmp_path / "seq"
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"frame{i:02d}.png"), f)
    (folder / "frame03.png").write_bytes(b"corrupt")
    out = tmp_path / "out"
    assert main(["run", str(folder), "--model", str(model_file), "--out-dir", str(out)]) == 0
    cols = read_tracking_csv(out / "seq.csv")
    assert len(cols["frame"]) == 8 and cols["success"][3] == 0
    assert cols["success"].sum() == 7  # tracking goes on after the unreadable frame
