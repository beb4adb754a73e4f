"""The Python API: README's example runs as printed, ``import aamtrack`` stays cheap, bad input raises at the
call."""

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import aamtrack
from aamtrack.errors import InputError

REPO = Path(__file__).resolve().parents[1]


def _readme_example() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Python API", 1)[1]
    lines = []
    for line in section.splitlines()[1:]:
        if line.startswith("    ") or (not line.strip() and lines):
            lines.append(line)
        elif lines:
            break
    return textwrap.dedent("\n".join(lines))


def test_readme_example_runs(monkeypatch, capsys):
    code = _readme_example()
    assert "aamtrack.track_video(" in code and "aamtrack.Tracker(" in code
    monkeypatch.chdir(REPO)  # the example's paths are relative to the repository root
    exec(compile(code, "README.md (Python API)", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("302 frames tracked; last nose tip at")  # every frame of the bundled sample
    assert out[1].startswith("tracked ")


def test_import_is_cheap():
    code = "import sys, aamtrack; print(sorted(m for m in ('numba', 'cv2', 'scipy', 'numpy') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_track_video_checks_its_input_at_the_call(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        aamtrack.track_video(tmp_path / "missing.mp4")


def test_track_video_smoothing_switch(tmp_path, synth_model):
    import synth

    frames, truth = synth.moving_face_frames(12)
    path = tmp_path / "clip.avi"
    synth.write_video(path, frames)
    raw = list(aamtrack.track_video(path, model=synth_model, smooth=False))
    smooth = list(aamtrack.track_video(path, model=synth_model))
    forwards = list(aamtrack.track_video(path, model=synth_model, smooth=aamtrack.SmoothConfig(look_ahead=0)))
    assert [r.status for r in raw] == [r.status for r in smooth] == [r.status for r in forwards] and raw[0].success
    assert np.array_equal(raw[0].landmarks, forwards[0].landmarks)  # forwards only, the detection passes through
    assert not np.array_equal(raw[-1].landmarks, forwards[-1].landmarks)  # later frames are filtered
    assert not np.array_equal(raw[0].landmarks, smooth[0].landmarks)  # by default the frames after it count too
    err = np.linalg.norm(np.stack([r.landmarks for r in raw]) - truth, axis=-1).mean()
    assert err < 1.0  # the raw stream is the tracker's own: within a pixel of the truth
    with pytest.raises(AttributeError):
        aamtrack.no_such_name  # noqa: B018
