"""iBUG .pts files: both layouts read, round trip through write_pts, and clear messages for bad files."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEED

from aamtrack.errors import InputError
from aamtrack.io import read_pts, write_pts, write_pts_per_frame
from aamtrack.result import FrameResult


@pytest.fixture
def points():
    return np.random.default_rng(SEED).uniform(0, 1000, size=(68, 2))


def test_round_trip_standard_form(tmp_path, points):
    path = tmp_path / "a.pts"
    write_pts(path, points)
    text = path.read_text()
    assert text.startswith("version: 1\nn_points:  68\n{\n") and text.endswith("}\n")
    np.testing.assert_allclose(read_pts(path), points, atol=5e-4)  # written with 3 decimals
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


def test_bare_lines(tmp_path, points):
    path = tmp_path / "bare.pts"
    path.write_text("".join(f"{float(x)!r} {float(y)!r}\n" for x, y in points) + "\n")
    result = read_pts(path)
    assert result.dtype == np.float64 and result.shape == (68, 2)
    np.testing.assert_array_equal(result, points)  # repr round-trips floats exactly


def test_crlf_and_extra_spaces(tmp_path, points):
    path = tmp_path / "win.pts"
    body = "".join(f"  {x:.6f}\t{y:.6f} \r\n" for x, y in points)
    path.write_bytes(f"version: 1\r\nn_points: 68\r\n{{\r\n{body}}}\r\n".encode())
    np.testing.assert_allclose(read_pts(path), points, atol=1e-6)


def test_any_count_when_n_points_is_none(tmp_path, points):
    write_pts(tmp_path / "five.pts", points[:5])
    assert read_pts(tmp_path / "five.pts", n_points=None).shape == (5, 2)


def _error(path, **kw) -> str:
    with pytest.raises(InputError) as info:
        read_pts(path, **kw)
    return str(info.value)


def test_wrong_count(tmp_path, points):
    write_pts(tmp_path / "a.pts", points[:67])
    assert _error(tmp_path / "a.pts") == f"{tmp_path / 'a.pts'}: 67 points, expected 68"
    (tmp_path / "b.pts").write_text("".join(f"{x} {y}\n" for x, y in points[:60]))
    assert _error(tmp_path / "b.pts").endswith("60 points, expected 68")


def test_header_count_disagrees_with_body(tmp_path, points):
    write_pts(tmp_path / "a.pts", points)
    path = tmp_path / "a.pts"
    path.write_text(path.read_text().replace("n_points:  68", "n_points:  70"))
    assert "n_points 70" in _error(path)


def test_garbage(tmp_path, points):
    path = tmp_path / "g.pts"
    lines = [f"{x} {y}" for x, y in points]
    lines[4] = "12.5 abc"
    path.write_text("\n".join(lines))
    message = _error(path)
    assert str(path) in message and "line 5" in message and "abc" in message
    path.write_text("\n".join(lines[:3] + ["1 2 3"] + lines[4:]))
    assert "line 4" in _error(path)
    path.write_text("version: 1\nn_points: 68\n{\n1 2\n")
    assert "missing closing" in _error(path)
    path.write_text("")
    assert "empty" in _error(path)
    path.write_text("\n".join(lines[:3] + ["nan 2"] + lines[4:]))
    assert "non-finite" in _error(path)


def test_missing_file_and_folder(tmp_path):
    assert _error(tmp_path / "faces" / "a.pts") == f"{tmp_path / 'faces' / 'a.pts'}: no such file"
    assert "folder" in _error(tmp_path)


def test_write_rejects_bad_points(tmp_path, points):
    with pytest.raises(ValueError, match="shape"):
        write_pts(tmp_path / "x.pts", points[:, :1])
    bad = points.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        write_pts(tmp_path / "x.pts", bad)
    assert not list(tmp_path.iterdir())


def test_pts_per_frame(tmp_path, points):
    out = tmp_path / "pts"
    tracked = FrameResult(frame=123, timestamp=4.1, status="tracked", landmarks=points)
    lost = FrameResult(frame=124, timestamp=4.13, status="lost")
    assert write_pts_per_frame(out, tracked) == out / "frame_000123.pts"
    assert write_pts_per_frame(out, lost) is None
    assert [p.name for p in out.iterdir()] == ["frame_000123.pts"]
    np.testing.assert_allclose(read_pts(out / "frame_000123.pts"), points, atol=5e-4)
