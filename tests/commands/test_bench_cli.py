"""``aamtrack bench``: bad options are one line and exit 1, before any work."""

import pytest

from aamtrack.cli import main


@pytest.mark.parametrize("args,needle", [
    (["--frames", "-3"], "--frames -3"),
    (["--frames", "0"], "--frames 0"),
    (["--sizes", "100000x100000"], "--sizes"),
    (["--sizes", "640x480,8x8"], "--sizes"),
    (["--sizes", "640"], "--sizes"),
    (["--threads", "0"], "--threads"),
])
def test_bad_options(tmp_path, capsys, monkeypatch, args, needle):
    monkeypatch.setattr("aamtrack.commands.bench.run_bench", lambda *a, **kw: pytest.fail("benchmark started"))
    assert main(["bench", str(tmp_path / "clip.mp4"), *args]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aamtrack bench: error:") and needle in err[0], err


def test_json_into_a_missing_folder_fails_first(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("aamtrack.commands.bench.run_bench", lambda *a, **kw: pytest.fail("benchmark started"))
    assert main(["bench", str(tmp_path / "clip.mp4"), "--json", str(tmp_path / "no" / "b.json")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_bad_input_fails_before_the_warm_up(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("aamtrack.commands.bench.run_bench", lambda *a, **kw: pytest.fail("benchmark started"))
    (tmp_path / "clip.mp4").write_text("not a video")
    assert main(["bench", str(tmp_path / "clip.mp4")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "clip.mp4: not a readable video" in err[0], err


def test_bench_streams_and_reports_the_pipelined_fps(tmp_path, model_file, capsys):
    import json

    import synth

    frames, _ = synth.moving_face_frames(6)
    synth.write_video(tmp_path / "clip.avi", frames)
    out = tmp_path / "b.json"
    assert main(["bench", str(tmp_path / "clip.avi"), "--model", str(model_file), "--sizes", "320x240",
                 "--frames", "5", "--json", str(out)]) == 0
    (row,) = json.loads(out.read_text())["rows"]
    assert row["frames"] == 5 and row["ms"]["decode"]["n"] == 5 and row["ms"]["output"]["n"] == 5
    assert row["fps_pipelined"] > 0 and row["fps_end_to_end"] > 0
    assert "pipelined" in capsys.readouterr().out
