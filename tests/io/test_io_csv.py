"""Tracking CSV: one row per FrameResult, fixed column order, empty fields for frames without a face, read back
equal to what was written (up to the printed decimals), nothing left behind when the run fails."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import SEED
from iohelpers import make_results

from aamtrack.errors import InputError
from aamtrack.io import TrackingCsvWriter, csv_columns, read_tracking_csv
from aamtrack.result import FrameResult

ANIM = ["AU_jaw_drop", "AU_lip_stretcher", "AU_brow_lowerer"]
SHAPE = ["shape_0", "shape_1"]


def _write(path, results, **kw):
    with TrackingCsvWriter(path, anim_names=ANIM, shape_names=SHAPE, **kw) as writer:
        for r in results:
            writer.write(r)
    return writer


def test_column_order():
    cols = csv_columns(anim_names=ANIM, shape_names=SHAPE)
    assert cols[:12] == ["frame", "timestamp", "success", "dropped", "status", "confidence",
                         "pose_Rx", "pose_Ry", "pose_Rz", "pose_Tx", "pose_Ty", "pose_scale"]
    assert cols[12:14] == ["x_0", "x_1"] and cols[79:81] == ["x_67", "y_0"] and cols[147] == "y_67"
    assert cols[148:] == ANIM + SHAPE
    cols3 = csv_columns(anim_names=ANIM, shape_names=SHAPE, with_3d=True)
    assert cols3[148] == "X_0" and cols3[216] == "Y_0" and cols3[284] == "Z_0" and cols3[351] == "Z_67"
    assert len(cols3) == 12 + 5 * 68 + 5
    with pytest.raises(ValueError, match="duplicate"):
        csv_columns(anim_names=["a", "frame"], shape_names=["a"])


@pytest.mark.parametrize("with_3d", [False, True])
def test_round_trip(tmp_path, with_3d):
    results = make_results(19, np.random.default_rng(SEED), with_3d=with_3d)
    path = tmp_path / "track.csv"
    writer = _write(path, results, with_3d=with_3d)
    assert writer.n_rows == 19 and list(tmp_path.iterdir()) == [path]

    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == csv_columns(anim_names=ANIM, shape_names=SHAPE, with_3d=with_3d)
    assert len(rows) == 1 + len(results)  # exactly one row per FrameResult
    for row, r in zip(rows[1:], results, strict=True):
        if not r.success:  # success 0, then nothing but empty fields after the confidence
            assert row[2] == "0" and row[6:] == [""] * (len(row) - 6)

    data = read_tracking_csv(path)
    assert list(data) == rows[0]
    ok = np.array([r.success for r in results])
    np.testing.assert_array_equal(data["frame"], np.arange(19))
    assert data["frame"].dtype == np.int64
    np.testing.assert_array_equal(data["success"], ok.astype(int))
    np.testing.assert_array_equal(data["dropped"], [int(r.status == "dropped") for r in results])
    assert list(data["status"]) == [r.status for r in results]
    np.testing.assert_allclose(data["timestamp"], [r.timestamp for r in results], atol=5e-5)
    np.testing.assert_allclose(data["confidence"], [r.confidence for r in results], atol=5e-5)

    good = [r for r in results if r.success]
    x = np.stack([data[f"x_{i}"] for i in range(68)], axis=1)
    y = np.stack([data[f"y_{i}"] for i in range(68)], axis=1)
    assert np.isnan(x[~ok]).all() and np.isnan(y[~ok]).all()
    np.testing.assert_allclose(x[ok], [r.landmarks[:, 0] for r in good], atol=5e-4)  # %.3f pixels
    np.testing.assert_allclose(y[ok], [r.landmarks[:, 1] for r in good], atol=5e-4)
    rot = np.stack([data[c] for c in ("pose_Rx", "pose_Ry", "pose_Rz")], axis=1)
    np.testing.assert_allclose(rot[ok], [r.rotation for r in good], atol=5e-6)  # %.5f radians
    np.testing.assert_allclose(data["pose_Tx"][ok], [r.translation[0] for r in good], atol=5e-4)
    np.testing.assert_allclose(data["pose_scale"][ok], [r.scale for r in good], rtol=5e-6)  # %.6g
    anim = np.stack([data[n] for n in ANIM], axis=1)
    np.testing.assert_allclose(anim[ok], [r.anim_params for r in good], atol=5e-6)
    assert np.isnan(anim[~ok]).all()
    shape = np.stack([data[n] for n in SHAPE], axis=1)
    np.testing.assert_allclose(shape[ok], [r.shape_params for r in good], atol=5e-6)
    if with_3d:
        for k, axis in enumerate("XYZ"):
            col = np.stack([data[f"{axis}_{i}"] for i in range(68)], axis=1)
            np.testing.assert_allclose(col[ok], [r.landmarks3d[:, k] for r in good], atol=5e-6)
            assert np.isnan(col[~ok]).all()


def test_nan_values_are_empty_fields(tmp_path):
    rng = np.random.default_rng(SEED)
    landmarks = rng.uniform(0, 100, size=(68, 2))
    landmarks[5] = np.nan
    result = FrameResult(frame=0, timestamp=0.0, status="tracked", confidence=0.9, landmarks=landmarks,
                         rotation=np.array([0.0, 0.0, 0.1]), translation=np.array([10.0, 20.0]), scale=np.nan)
    with TrackingCsvWriter(tmp_path / "t.csv") as writer:
        writer.write(result)
    data = read_tracking_csv(tmp_path / "t.csv")
    assert np.isnan(data["x_5"][0]) and np.isnan(data["y_5"][0]) and np.isnan(data["pose_scale"][0])
    assert data["x_4"][0] == pytest.approx(landmarks[4, 0], abs=5e-4)


def test_exception_leaves_nothing(tmp_path):
    results = make_results(5, np.random.default_rng(SEED))
    with pytest.raises(RuntimeError, match="tracker crashed"):
        with TrackingCsvWriter(tmp_path / "t.csv", anim_names=ANIM, shape_names=SHAPE) as writer:
            for r in results:
                writer.write(r)
            raise RuntimeError("tracker crashed")
    assert not list(tmp_path.iterdir())


def test_exception_keeps_existing_file(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("previous run\n")
    with pytest.raises(ValueError, match="anim_params"):  # parameter count does not match the names
        with TrackingCsvWriter(path, anim_names=["only_one"]) as writer:
            writer.write(make_results(1, np.random.default_rng(SEED))[0])
    assert path.read_text() == "previous run\n" and list(tmp_path.iterdir()) == [path]


def test_write_after_close(tmp_path):
    writer = TrackingCsvWriter(tmp_path / "t.csv")
    writer.close()
    writer.close()
    with pytest.raises(ValueError, match="closed"):
        writer.write(FrameResult(frame=0, timestamp=0.0, status="lost"))
    assert read_tracking_csv(tmp_path / "t.csv")["frame"].shape == (0,)  # header only


def test_reads_openface_style(tmp_path):
    path = tmp_path / "openface.csv"
    path.write_text("frame, face_id, timestamp, confidence, success, AU01_r\n"
                    "1, 0, 0.000, 0.98, 1, 0.52\n"
                    "2, 0, 0.033, 0.00, 0, \n")
    data = read_tracking_csv(path)
    assert list(data) == ["frame", "face_id", "timestamp", "confidence", "success", "AU01_r"]
    np.testing.assert_array_equal(data["frame"], [1, 2])
    assert data["AU01_r"][0] == 0.52 and np.isnan(data["AU01_r"][1])


def test_read_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_tracking_csv(tmp_path / "missing.csv")
    (tmp_path / "ragged.csv").write_text("frame,x_0\n0,1.0\n1\n")
    with pytest.raises(InputError, match="row 3: 1 fields, header has 2"):
        read_tracking_csv(tmp_path / "ragged.csv")
    (tmp_path / "text.csv").write_text("frame,x_0\n0,abc\n")
    with pytest.raises(InputError, match="column 'x_0': not a number"):
        read_tracking_csv(tmp_path / "text.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(InputError, match="empty"):
        read_tracking_csv(tmp_path / "empty.csv")


def _slow_line(writer, result) -> str:
    """The row as the field-by-field path (the csv module) writes it: the reference for the fast path."""
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(writer._row(result))
    return buf.getvalue()


@pytest.mark.parametrize("with_3d", [False, True])
def test_fast_rows_are_the_same_text_as_field_by_field(tmp_path, with_3d):
    rng = np.random.default_rng(SEED)
    results = make_results(40, rng, with_3d=with_3d)
    # values that exercise the formats: tiny, huge, negative zero, many digits
    r = results[1]
    r.landmarks[0] = (-0.0, 1e-9)
    r.landmarks[1] = (123456.78949, -0.0005)
    results[2] = FrameResult(**{**r.__dict__, "scale": 1.23456789e-7, "frame": 2})
    with TrackingCsvWriter(tmp_path / "a.csv", anim_names=ANIM, shape_names=SHAPE, with_3d=with_3d) as w:
        n_fast = 0
        for res in results:
            fast = w._fast_line(res)
            if res.success:
                assert fast == _slow_line(w, res)
                n_fast += 1
            else:
                assert fast is None  # frames without a face take the general path
        assert n_fast == sum(r.success for r in results) > 10
        w.abort()


def test_nan_rows_fall_back_to_empty_fields_and_write_many_matches_write(tmp_path):
    results = make_results(24, np.random.default_rng(SEED), with_3d=True)
    results[1].landmarks[5, 0] = np.nan  # the general path writes it as an empty field
    one = _write(tmp_path / "one.csv", results, with_3d=True).path
    with TrackingCsvWriter(tmp_path / "many.csv", anim_names=ANIM, shape_names=SHAPE, with_3d=True) as w:
        w.write_many(results[:10])
        w.write_many(results[10:])
    assert w.n_rows == 24
    assert (tmp_path / "many.csv").read_bytes() == one.read_bytes()
    assert read_tracking_csv(one)["x_5"][1] != read_tracking_csv(one)["x_5"][1]  # NaN read back
