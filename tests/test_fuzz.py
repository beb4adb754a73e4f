"""Bounded, seeded fuzzing of ``aamtrack run`` with damaged short videos: every case exits 0 (one CSV row per
frame the container holds, a summary) or 1 with one line, never a traceback or a signal, never a stray file.
(Damaged model files plug into tests/fuzz.py the same way.)"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEED
from fuzz import check_clean_run, damage

import synth
from aamtrack.io.csvout import read_tracking_csv
from aamtrack.model import save_model

N_VIDEO_CASES = 48
N_FRAMES = 6


@pytest.fixture(scope="module")
def clean_videos(tmp_path_factory):
    frames, _ = synth.moving_face_frames(N_FRAMES, size=(160, 120), scale=70.0, amplitude=4.0)
    folder = tmp_path_factory.mktemp("clean")
    paths = {"avi": folder / "clip.avi", "mp4": folder / "clip.mp4"}
    synth.write_video(paths["avi"], frames, fourcc="MJPG")
    synth.write_video(paths["mp4"], frames, fourcc="mp4v")
    return paths


@pytest.fixture(scope="module")
def model_path(tmp_path_factory, synth_model):
    path = tmp_path_factory.mktemp("model") / "synth2d.npz"
    save_model(synth_model, path)
    return path


@pytest.mark.parametrize("case", range(N_VIDEO_CASES))
def test_damaged_video(case, tmp_path, capsys, clean_videos, model_path):
    rng = np.random.default_rng([SEED, case])
    ext = ("avi", "mp4")[case % 2]
    src = tmp_path / f"damaged.{ext}"
    what = f"case {case}: {ext}, " + damage(clean_videos[ext], src, rng)
    out = tmp_path / "out"
    code = check_clean_run(["run", str(src), "--model", str(model_path), "--out-dir", str(out)], capsys,
                           workdir=tmp_path, allowed_new={"out", "out/damaged.csv", "out/damaged.json"}, what=what)
    if code == 0:
        cols = read_tracking_csv(out / "damaged.csv")
        n = len(cols["frame"])
        assert cols["frame"].tolist() == list(range(n)), what  # consecutive rows from frame 0
        assert n == N_FRAMES, what  # a row per frame the container holds (its header survives these cases)
        assert np.all(np.diff(cols["timestamp"]) > 0), what
