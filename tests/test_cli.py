"""The command line itself: usage errors are one line too, and no command is one line."""

import pytest

from aamtrack.cli import main


@pytest.mark.parametrize("argv,needle", [
    (["run"], "the following arguments are required: input"),
    (["run", "clip.mp4", "--fps", "abc"], "invalid float value: 'abc'"),
    (["run", "clip.mp4", "--kind", "4d"], "invalid choice: '4d'"),
    (["bench", "clip.mp4", "--frames", "x"], "invalid int value"),
    (["bogus"], "invalid choice: 'bogus'"),
])
def test_usage_errors_are_one_line(capsys, argv, needle):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ": error: " in err[0] and needle in err[0], err


def test_no_command(capsys):
    assert main(["-v"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no command given" in err[0], err


@pytest.mark.parametrize("exc,needle", [(MemoryError(), "out of memory"),
                                        (OSError(5, "Input/output error", "clip.mp4"), "clip.mp4: Input/output error")])
def test_unexpected_resource_errors_are_one_line(capsys, monkeypatch, exc, needle):
    def fail(*a, **kw):
        raise exc

    monkeypatch.setattr("aamtrack.commands.run.track_file", fail)
    assert main(["run", "clip.mp4"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("aamtrack run: error:") and needle in err[0], err
