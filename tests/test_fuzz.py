"""Bounded, seeded fuzzing of ``aamtrack run`` with damaged short videos: every case exits 0 (one CSV row per
frame the container holds, a summary) or 1 with one line, never a traceback or a signal, never a stray file,
and nothing from FFmpeg on stderr. (Damaged model files plug into tests/fuzz.py the same way.)"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEED
from fuzz import Case, check_outcome, damage, run_batch

import synth
from aamtrack.io.csvout import read_tracking_csv
from aamtrack.model import save_model

N_VIDEO_CASES = 48
N_FRAMES = 6


@pytest.fixture(scope="module")
def video_cases(tmp_path_factory, synth_model):
    """All damaged-video cases, run in one child process; name -> Case (with its outcome)."""
    root = tmp_path_factory.mktemp("fuzz")
    model = root / "synth2d.npz"
    save_model(synth_model, model)
    frames, _ = synth.moving_face_frames(N_FRAMES, size=(160, 120), scale=70.0, amplitude=4.0)
    clean = {"avi": root / "clean.avi", "mp4": root / "clean.mp4"}
    synth.write_video(clean["avi"], frames, fourcc="MJPG")
    synth.write_video(clean["mp4"], frames, fourcc="mp4v")
    cases = []
    for k in range(N_VIDEO_CASES):
        rng = np.random.default_rng([SEED, k])
        ext = ("avi", "mp4")[k % 2]
        work = root / f"case{k:02d}"
        work.mkdir()
        what = damage(clean[ext], work / f"damaged.{ext}", rng)
        cases.append(Case(f"case {k}: {ext}, {what}",
                          ["run", work / f"damaged.{ext}", "--model", model, "--out-dir", work / "out"], work,
                          allowed_new={"out", "out/damaged.csv", "out/damaged.json"}))
    native_stderr = run_batch(cases)
    return cases, native_stderr


@pytest.mark.parametrize("k", range(N_VIDEO_CASES))
def test_damaged_video(k, video_cases):
    case = video_cases[0][k]
    check_outcome(case)
    if case.code == 0:
        cols = read_tracking_csv(case.workdir / "out" / "damaged.csv")
        n = len(cols["frame"])
        assert cols["frame"].tolist() == list(range(n)), case.name  # consecutive rows from frame 0
        assert n == N_FRAMES, case.name  # a row per frame the container holds (its header survives these cases)
        assert np.all(np.diff(cols["timestamp"]) > 0), case.name


def test_outcomes_are_mixed_and_ffmpeg_is_silent(video_cases):
    cases, native_stderr = video_cases
    codes = [c.code for c in cases]
    assert codes.count(0) >= 10 and codes.count(1) >= 5  # the damage reaches both outcomes
    assert native_stderr.strip() == "", native_stderr[-2000:]  # FFmpeg's and OpenCV's own lines silenced
