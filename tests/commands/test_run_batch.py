"""``aamtrack run`` on many inputs: a folder of videos with a corrupt member, --jobs, skip / --overwrite, names
that would collide, and the pipelined run's failures (a decoder failing mid-video) leaving nothing behind."""

from __future__ import annotations

import sys

import pytest
from faults import files_below

import synth
from notices import stderr_lines
from aamtrack.cli import main
from aamtrack.commands.batch import BATCH_COLUMNS, DASK_HINT, read_batch_csv
from aamtrack.commands.run import track_file
from aamtrack.errors import InputError
from aamtrack.io import frames as frames_mod
from aamtrack.io.csvout import read_tracking_csv

N = 8


def make_folder(root, n_videos: int = 3):
    folder = root / "videos"
    folder.mkdir()
    for k in range(n_videos):
        frames, _ = synth.moving_face_frames(N, amplitude=4.0 + k)
        synth.write_video(folder / f"clip{k}.avi", frames)
    (folder / "broken.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    (folder / "notes.txt").write_text("not a video, not an input\n")
    return folder


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return make_folder(tmp_path_factory.mktemp("batch"))


def run(*args) -> int:
    return main(["run", *map(str, args)])


def rows_by_name(out) -> dict:
    rows = read_batch_csv(out / "batch.csv")
    return {r["input"].rsplit("/", 1)[-1]: r for r in rows}


def test_folder_with_a_corrupt_video_jobs_2(tmp_path, folder, model_file, capsys):
    out = tmp_path / "out"
    assert run(folder, "--model", model_file, "--out-dir", out, "--jobs", 2) == 1  # one input failed
    err = stderr_lines(capsys)
    assert len(err) == 1 and err[0].startswith("aamtrack run: error:") and "broken.mp4" in err[0], err
    assert "not a readable video" in err[0]
    with open(out / "batch.csv", encoding="utf-8") as f:
        assert f.readline().strip() == ",".join(BATCH_COLUMNS)
    rows = rows_by_name(out)
    assert sorted(rows) == ["broken.mp4", "clip0.avi", "clip1.avi", "clip2.avi"]
    assert rows["broken.mp4"]["status"] == "failed" and "not a readable video" in rows["broken.mp4"]["error"]
    for k in range(3):
        r = rows[f"clip{k}.avi"]
        assert r["status"] == "done" and r["error"] == "" and int(r["frames"]) == N
        assert int(r["tracked"]) + int(r["lost"]) <= N and float(r["fps"]) > 0
        assert len(read_tracking_csv(out / f"clip{k}" / f"clip{k}.csv")["frame"]) == N
    assert [f for f in files_below(out) if (out / f).is_file()] == ["batch.csv", "clip0/clip0.csv", "clip0/clip0.json", "clip1/clip1.csv",
                                "clip1/clip1.json", "clip2/clip2.csv", "clip2/clip2.json"]  # nothing for broken

    # --jobs 1 (in this process) writes the same bytes
    one = tmp_path / "one"
    assert run(folder, "--model", model_file, "--out-dir", one, "--jobs", 1) == 1
    for k in range(3):
        assert (one / f"clip{k}" / f"clip{k}.csv").read_bytes() == (out / f"clip{k}" / f"clip{k}.csv").read_bytes()


def test_rerun_skips_finished_inputs_unless_overwrite_or_other_options(tmp_path, folder, model_file, capsys):
    out = tmp_path / "out"
    args = (folder, "--model", model_file, "--out-dir", out, "--jobs", 1)
    assert run(*args) == 1
    stamp = (out / "clip0" / "clip0.csv").stat().st_mtime_ns
    assert run(*args) == 1  # the corrupt one still fails
    rows = rows_by_name(out)
    assert [rows[f"clip{k}.avi"]["status"] for k in range(3)] == ["skipped"] * 3
    assert int(rows["clip0.avi"]["frames"]) == N  # from the finished run's summary
    assert rows["broken.mp4"]["status"] == "failed"
    assert (out / "clip0" / "clip0.csv").stat().st_mtime_ns == stamp  # not rewritten
    assert "0 done, 3 skipped, 1 failed" in capsys.readouterr().out

    assert run(*args, "--overwrite") == 1
    assert [rows_by_name(out)[f"clip{k}.avi"]["status"] for k in range(3)] == ["done"] * 3
    assert run(*args, "--no-smooth") == 1  # other options: not the same result, so redone
    assert [rows_by_name(out)[f"clip{k}.avi"]["status"] for k in range(3)] == ["done"] * 3


def test_a_member_without_a_face_fails_and_again_on_a_rerun(tmp_path, model_file, capsys):
    import numpy as np

    folder = tmp_path / "videos"
    folder.mkdir()
    frames, _ = synth.moving_face_frames(4)
    synth.write_video(folder / "face.avi", frames)
    synth.write_video(folder / "wall.avi", [np.full((120, 160, 3), 90, np.uint8) for _ in range(4)])
    out = tmp_path / "out"
    for attempt in ("first", "re-run"):
        assert run(folder, "--model", model_file, "--out-dir", out, "--jobs", 1) == 1, attempt
        err = stderr_lines(capsys)
        assert len(err) == 1 and err[0].startswith("aamtrack run: error:"), (attempt, err)
        assert err[0].endswith("wall.avi: no face found in any of its 4 frames"), err
        rows = rows_by_name(out)
        assert rows["wall.avi"]["status"] == "failed" and "no face found" in rows["wall.avi"]["error"]
        assert rows["face.avi"]["status"] == ("done" if attempt == "first" else "skipped")
        assert not (out / "wall").exists()  # nothing written for it


FORK_WHILE_BUSY = """
import sys, threading
from pathlib import Path
import cv2
import numpy as np
from aamtrack.commands.batch import run_batch, run_options
clips, model, out = sys.argv[1].split(","), Path(sys.argv[2]), Path(sys.argv[3])
opts = run_options(model_path=model, overlay=False, pts=False, report=False, replay=False, fps=None, smooth=None)
big = np.random.default_rng(0).random((1500, 1500), np.float32)
stop = threading.Event()
def spin():  # OpenCV's thread pool at work in another thread whenever the batch forks its workers
    while not stop.is_set():
        cv2.GaussianBlur(big, (0, 0), 3.0)
t = threading.Thread(target=spin)
t.start()
try:
    for i in range(3):
        rows = run_batch(clips, out_dir=out / str(i), model_path=model, options=opts, jobs=2, progress=False)
        print(i, [r["status"] for r in rows], flush=True)
finally:
    stop.set()
    t.join()
"""


def test_workers_forked_while_opencv_threads_are_busy_do_not_hang(tmp_path, folder, model_file):
    """OpenCV's thread pool does not survive a fork: before the batch kept OpenCV to one thread while forking, a
    worker forked with the pool at work hung for ever in its first OpenCV call (this script, every time); with
    that alone it still hung now and then (once in CI: a lock held by the spinning thread at the fork), so with
    other threads alive the workers now come from a fork server."""
    import os
    import signal
    import subprocess

    clips = ",".join(str(folder / f"clip{k}.avi") for k in range(3))
    proc = subprocess.Popen([sys.executable, "-c", FORK_WHILE_BUSY, clips, str(model_file), str(tmp_path)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=240)  # a hang fails this test, not the whole run
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the script and its hung workers
        proc.communicate()
        pytest.fail("a batch with --jobs 2 hung while OpenCV's threads were busy")
    assert proc.returncode == 0, err[-2000:]
    assert out.splitlines() == [f"{i} ['done', 'done', 'done']" for i in range(3)], out


START_METHODS = """
import threading
from aamtrack.commands.batch import _pool_context
alone = _pool_context().get_start_method()
done = threading.Event()
t = threading.Thread(target=done.wait)
t.start()
busy = _pool_context().get_start_method()
done.set()
t.join()
print(alone, busy)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="fork and the fork server are Linux's start methods")
def test_workers_are_forked_only_from_a_process_with_no_other_thread():
    """Forking keeps a worker's start to milliseconds (the parent's modules and tracker come with it), but copies
    only the forking thread: a lock another thread holds at that moment stays held in the worker for ever."""
    import subprocess

    out = subprocess.run([sys.executable, "-c", START_METHODS], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["fork", "forkserver"]


def test_inputs_sharing_a_stem_get_their_own_folders(tmp_path, model_file):
    frames, _ = synth.moving_face_frames(4)
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        synth.write_video(tmp_path / sub / "clip.avi", frames)
    out = tmp_path / "out"
    assert run(tmp_path / "a" / "clip.avi", tmp_path / "b" / "clip.avi", "--model", model_file,
               "--out-dir", out, "--jobs", 1) == 0
    names = sorted(p.name for p in out.iterdir() if p.is_dir())
    assert len(names) == 2 and all(n.startswith("clip_") for n in names) and names[0] != names[1]
    assert [r["status"] for r in read_batch_csv(out / "batch.csv")] == ["done", "done"]


def test_several_inputs_need_an_out_dir(tmp_path, folder, model_file, capsys):
    assert run(folder / "clip0.avi", folder / "clip1.avi", "--model", model_file) == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and "need --out-dir" in err[0]


def test_scheduler_without_dask_says_how_to_install(tmp_path, folder, model_file, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)  # as if not installed: import fails
    assert run(folder, "--model", model_file, "--out-dir", tmp_path / "o", "--scheduler", "tcp://127.0.0.1:1") == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and DASK_HINT in err[0]
    assert not (tmp_path / "o").exists()


def test_pipelined_and_single_thread_runs_write_the_same_rows(tmp_path, folder, model_file):
    a = track_file(str(folder / "clip1.avi"), model_path=model_file, out_dir=tmp_path / "a", progress=False)
    b = track_file(str(folder / "clip1.avi"), model_path=model_file, out_dir=tmp_path / "b", progress=False,
                   pipelined=False)
    assert a["pipelined"] and not b["pipelined"]
    assert (tmp_path / "a" / "clip1.csv").read_bytes() == (tmp_path / "b" / "clip1.csv").read_bytes()


def test_decoder_failing_mid_video_leaves_nothing(tmp_path, folder, model_file, capsys, monkeypatch):
    real_read = frames_mod.VideoFrames._read

    def read_then_fail(self, cap, first):
        for k, f in enumerate(real_read(self, cap, first)):
            if k == 5:
                raise InputError(f"{self.name}: decoder failed at frame 5")
            yield f

    monkeypatch.setattr(frames_mod.VideoFrames, "_read", read_then_fail)
    out = tmp_path / "out"
    assert run(folder / "clip0.avi", "--model", model_file, "--out-dir", out, "--video", "--pts") == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and err[0].endswith("decoder failed at frame 5"), err
    assert not out.exists()


def test_grey_frames_give_the_same_rows_as_colour(tmp_path, folder, model_file):
    # without --video / --report the decoding thread hands the tracker grey frames; with --video, colour ones
    track_file(str(folder / "clip2.avi"), model_path=model_file, out_dir=tmp_path / "g", progress=False)
    track_file(str(folder / "clip2.avi"), model_path=model_file, out_dir=tmp_path / "c", progress=False,
               overlay=True)
    assert (tmp_path / "g" / "clip2.csv").read_bytes() == (tmp_path / "c" / "clip2.csv").read_bytes()


@pytest.mark.parametrize("args,needle", [
    (["--jobs", "0"], "--jobs 0"),
    (["--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"], "exclude each other"),
])
def test_bad_batch_options_are_one_line(tmp_path, folder, model_file, capsys, args, needle):
    assert run(folder, "--model", model_file, "--out-dir", tmp_path / "o", *args) == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and needle in err[0], err
    assert not (tmp_path / "o").exists()


def test_stop_signal_in_a_batch_keeps_finished_inputs_and_leaves_no_half(tmp_path, folder, model_file, capsys,
                                                                         monkeypatch):
    import os
    import signal

    from aamtrack.io.csvout import TrackingCsvWriter

    real_write = TrackingCsvWriter.write

    def write_then_signal(self, result):
        real_write(self, result)
        if ".clip1." in self.path.name and self.n_rows == 3:  # (the temporary name of clip1.csv)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(TrackingCsvWriter, "write", write_then_signal)
    out = tmp_path / "out"
    assert run(folder, "--model", model_file, "--out-dir", out, "--jobs", 1) == 128 + signal.SIGTERM
    assert capsys.readouterr().err.strip().endswith("stopped by SIGTERM")
    files = [f for f in files_below(out) if (out / f).is_file()]
    assert files == ["clip0/clip0.csv", "clip0/clip0.json"]  # inputs are in name order: broken, clip0, clip1
    assert len(read_tracking_csv(out / "clip0" / "clip0.csv")["frame"]) == N
