"""What a user of ``aamtrack run`` sees beyond the CSV: -v events with loss reasons, the report, smoothing on
by default, the first-run compile message; on a synthetic video whose face leaves and comes back."""

import json
import logging
import sys
import threading

import numpy as np
import pytest

import synth
from notices import stderr_lines
from aamtrack.cli import main
from aamtrack.commands import run as run_cmd
from aamtrack.io.csvout import read_tracking_csv

AWAY = range(8, 14)


@pytest.fixture(scope="module")
def away_video(tmp_path_factory):
    frames, truth = synth.moving_face_frames(24, away=AWAY)
    path = tmp_path_factory.mktemp("vid") / "away.avi"
    synth.write_video(path, frames)
    return path, truth


def test_verbose_report_and_smoothing(tmp_path, away_video, model_file, capsys, caplog):
    pytest.importorskip("matplotlib")
    path, truth = away_video
    out = tmp_path / "out"
    with caplog.at_level(logging.INFO):
        assert main(["-v", "run", str(path), "--model", str(model_file), "--out-dir", str(out), "--report"]) == 0
    events = [r.getMessage() for r in caplog.records if r.name == "aamtrack.track"]
    assert events[0].startswith("frame 0: face detected")
    # the face leaves at frame 8: the search from frame 7 fits the background badly; then Haar finds nothing, or
    # finds background in a turned copy of the frame whose fit the validator rejects: every frame stays lost
    assert any(e.startswith("frame 8: lost: low confidence") for e in events), events
    # the face is back at frame 14: found there, or a frame or two later and tracked back to it (``backfill``)
    assert any(("face re-detected after" in e or "tracking again after" in e) and "frames lost" in e
               for e in events), events
    cols = read_tracking_csv(out / "away.csv")
    back = int(np.flatnonzero((cols["success"] == 1) & (cols["frame"] > 8))[0])
    assert (cols["status"][8:back] == "lost").all() and back == AWAY.stop  # no "face" while it is away
    found = int(np.flatnonzero((cols["status"] == "detected") & (cols["frame"] > 8))[0])
    summary = json.loads((out / "away.json").read_text())
    assert summary["frames_tracked_back"] == found - back
    assert summary["smoothing"]["filter"] == "one_euro"  # on by default, looking ahead
    assert summary["smoothing"]["look_ahead_frames"] == 8 and summary["smoothing"]["follow_jumps"] is True
    assert summary["outputs"]["report"] == str(out / "report.html")
    text = (out / "report.html").read_text()
    assert f"frames 8&ndash;{back - 1}" in text and "low confidence" in text
    assert "report.html" in capsys.readouterr().out


def test_report_without_matplotlib_writes_nothing(tmp_path, away_video, model_file, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    out = tmp_path / "out"
    assert main(["run", str(away_video[0]), "--model", str(model_file), "--out-dir", str(out), "--report"]) == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and "pip install 'aamtrack[plot]'" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("option", ["--smooth-beta", "--smooth-look-ahead"])
def test_bad_smoothing_parameters(tmp_path, away_video, model_file, capsys, option):
    assert main(["run", str(away_video[0]), "--model", str(model_file), "--out-dir", str(tmp_path / "o"),
                 option, "-1"]) == 1
    err = stderr_lines(capsys)
    assert len(err) == 1 and option in err[0] and "-1" in err[0]
    assert not (tmp_path / "o").exists()


def test_compile_message_only_when_the_warm_up_is_slow(monkeypatch):
    said = []
    notified = threading.Event()

    def notify(text):
        said.append(text)
        notified.set()

    def slow_warmup(tracker):  # a warm-up that outlasts the threshold: it ends once the message is out
        assert notified.wait(timeout=30)
        return 6.0

    monkeypatch.setattr(run_cmd, "warmup", slow_warmup)
    assert run_cmd._warm_up(None, notify, after=0.0) == 6.0
    assert said == ["compiling kernels (first run only) ...", "kernels ready in 6.0 s (cached for later runs)"]
    said.clear()
    monkeypatch.setattr(run_cmd, "warmup", lambda tracker: 0.01)  # a cache load: quiet
    assert run_cmd._warm_up(None, notify, after=5.0) == 0.01
    assert said == []


def test_summary_counts_lost_frames_by_reason(tmp_path, away_video, model_file):
    """The run's summary says why frames were lost (``frames_lost_by_reason``, the reasons' numbers as "#"): every
    lost frame counted once, under the reasons the events log gives."""
    out = tmp_path / "out"
    assert main(["run", str(away_video[0]), "--model", str(model_file), "--out-dir", str(out)]) == 0
    summary = json.loads((out / "away.json").read_text())
    by = summary["frames_lost_by_reason"]
    assert summary["frames_lost"] >= len(AWAY) - 1 and sum(by.values()) == summary["frames_lost"]
    assert set(by) <= {"no face detected", "low confidence # < #"}, by  # the kinds this video's losses have
    assert "low confidence # < #" in by  # frame 8: the search from frame 7 fits the background badly
