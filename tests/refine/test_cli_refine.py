"""``aamtrack refine``: scans in an .npz or a folder, outputs, and bad inputs (one line, exit 1, nothing written)."""

import numpy as np
import pytest
from conftest import SEED
from synthetic import bumpy_surface, smooth_warp

from aamtrack.cli import main
from aamtrack.io.obj import read_obj, write_obj

LANDMARKS = np.linspace(0, 399, 68).round().astype(np.int64)  # 68 spread vertices of a 20 x 20 surface
QUADS = np.array([[i * 20 + j, i * 20 + j + 1, (i + 1) * 20 + j + 1, (i + 1) * 20 + j]
                  for i in range(19) for j in range(19)])


def _sequence(n_frames=4):
    neutral = bumpy_surface(20)
    return np.stack([smooth_warp(neutral, a) for a in np.linspace(0, 1, n_frames)])


def _scans_npz(path, frames, rng, **extra):
    points = np.stack([rng.permutation(f) for f in frames])  # point order changes from frame to frame
    arrays = dict(points=points, landmarks=frames[:, LANDMARKS])
    arrays.update(extra)
    np.savez(path, **arrays)


def _csv(path, landmarks):
    head = ["frame"] + [f"{a}_{i}" for a in "XYZ" for i in range(68)]
    rows = [[t] + list(lm[:, 0]) + list(lm[:, 1]) + list(lm[:, 2]) for t, lm in enumerate(landmarks)]
    path.write_text("\n".join(",".join(map(str, r)) for r in [head] + rows) + "\n")


def _run(capsys, *argv):
    code = main(["refine", *map(str, argv)])
    err = capsys.readouterr().err.strip().splitlines()
    return code, [e for e in err if "error" in e or not e.strip().startswith(("round", "writing"))]


def test_npz_scans_end_to_end(tmp_path, capsys):
    rng = np.random.default_rng(SEED)
    frames = _sequence()
    write_obj(tmp_path / "tpl.obj", frames[0], QUADS, LANDMARKS)
    _scans_npz(tmp_path / "scans.npz", frames, rng)
    out = tmp_path / "out.npz"
    code, _ = _run(capsys, tmp_path / "tpl.obj", tmp_path / "scans.npz", "--out", out, "--obj-dir", tmp_path / "o")
    assert code == 0
    with np.load(out, allow_pickle=False) as data:
        tracked, keys, kpos = data["frames"], data["key_index"], data["key_positions"]
        assert np.array_equal(data["faces"], QUADS)
    assert tracked.shape == (4, 400, 3) and tracked.dtype == np.float32
    assert np.abs(tracked[0] - frames[0]).max() < 1e-6  # frame 0 is the template
    assert np.array_equal(keys[:68], LANDMARKS) and kpos.shape == (4, len(keys), 3)
    err = np.linalg.norm(tracked - frames, axis=2).mean()
    motion = np.linalg.norm(frames - frames[0], axis=2).mean()
    assert err < 0.2 * motion  # the template follows the scans (the 68 landmarks alone already give most of it)
    objs = sorted((tmp_path / "o").glob("*.obj"))
    assert len(objs) == 4 and read_obj(objs[2]).faces.shape == (361, 4)
    assert np.abs(read_obj(objs[3]).vertices - tracked[3]).max() < 1e-4
    assert not list(tmp_path.rglob(".*tmp*"))  # no temporary files left


def test_folder_of_scans_with_landmark_csv(tmp_path, capsys):
    rng = np.random.default_rng(SEED + 1)
    frames = _sequence(3)
    np.savez(tmp_path / "tpl.npz", vertices=frames[0], landmark68=LANDMARKS)
    scans = tmp_path / "scans"
    scans.mkdir()
    for t, f in enumerate(frames):  # different sizes per frame; .obj and ASCII .ply; natural name order
        pts = rng.permutation(f)[: 400 - 30 * t]
        if t == 1:
            body = "\n".join(f"{x} {y} {z}" for x, y, z in pts)
            (scans / f"scan{t}.ply").write_text(f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty float x\n"
                                                f"property float y\nproperty float z\nend_header\n{body}\n")
        else:
            write_obj(scans / f"scan{t}.obj", pts)
    _csv(scans / "landmarks.csv", frames[:, LANDMARKS])
    out = tmp_path / "out.npz"
    code, _ = _run(capsys, tmp_path / "tpl.npz", scans, "--out", out)
    assert code == 0
    with np.load(out) as data:
        tracked = data["frames"]
    assert tracked.shape == (3, 400, 3)
    assert np.linalg.norm(tracked - frames, axis=2).mean() < 0.2 * np.linalg.norm(frames - frames[0], axis=2).mean()


def test_binary_ply_points(tmp_path):
    from aamtrack.io.obj import read_point_cloud

    pts = np.random.default_rng(SEED).standard_normal((50, 3)).astype(np.float32)
    rec = np.zeros(50, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1")])
    rec["x"], rec["y"], rec["z"] = pts.T
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 50\nproperty float x\nproperty float y\n"
            "property float z\nproperty uchar red\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n")
    (tmp_path / "p.ply").write_bytes(head.encode() + rec.tobytes())
    assert np.array_equal(read_point_cloud(tmp_path / "p.ply"), pts.astype(np.float64))


def _bad_inputs(tmp):
    rng = np.random.default_rng(SEED + 2)
    frames = _sequence(3)
    write_obj(tmp / "tpl.obj", frames[0], QUADS, LANDMARKS)
    _scans_npz(tmp / "scans.npz", frames, rng)
    _scans_npz(tmp / "nan.npz", frames, rng)
    with np.load(tmp / "nan.npz") as d:
        pts = d["points"].copy()
    pts[1, 5, 2] = np.nan
    np.savez(tmp / "nan.npz", points=pts, landmarks=frames[:, LANDMARKS])
    np.savez(tmp / "nolm.npz", points=pts)
    np.savez(tmp / "shape.npz", points=frames, landmarks=frames[:2, LANDMARKS])
    np.savez(tmp / "lm67.npz", points=frames, landmarks=frames[:, LANDMARKS[:67]])
    np.savez(tmp / "one.npz", points=frames[:1], landmarks=frames[:1, LANDMARKS])
    (tmp / "trunc.npz").write_bytes((tmp / "scans.npz").read_bytes()[:3000])
    np.savez(tmp / "dup.npz", vertices=frames[0], landmark68=np.r_[LANDMARKS[:67], LANDMARKS[0]])
    np.savez(tmp / "huge.npz", vertices=frames[0] * 1e9, landmark68=LANDMARKS)
    np.savez(tmp / "tiny.npz", vertices=frames[0] * 1e-12, landmark68=LANDMARKS)
    np.savez(tmp / "nokeys.npz", something=np.zeros(3))
    np.savez(tmp / "flat.npz", vertices=frames[0] * [1, 1, 0], landmark68=LANDMARKS)
    folder = tmp / "folder"
    folder.mkdir()
    write_obj(folder / "a.obj", frames[0])
    write_obj(folder / "b.obj", frames[1])
    _csv(folder / "lm.csv", frames[:1, LANDMARKS])  # 1 row for 2 scans
    empty = tmp / "empty"
    empty.mkdir()
    np.save(tmp / "bare.npy", frames)  # a bare array, renamed as an archive: np.load hands back no archive
    (tmp / "bare.npy").rename(tmp / "bare.npz")
    (tmp / "text.npz").write_text("not an archive\n")  # np.load would call this pickled data
    (tmp / "empty.npz").write_bytes(b"")
    (tmp / "bad.ply").write_text("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nend_header\n1\n")
    tpl, scans = tmp / "tpl.obj", tmp / "scans.npz"
    return {
        "missing template": [tmp / "absent.obj", scans],
        "missing scans": [tpl, tmp / "absent.npz"],
        "nan in points": [tpl, tmp / "nan.npz"],
        "missing landmarks key": [tpl, tmp / "nolm.npz"],
        "frame count mismatch": [tpl, tmp / "shape.npz"],
        "67 landmarks": [tpl, tmp / "lm67.npz"],
        "one frame": [tpl, tmp / "one.npz"],
        "truncated npz": [tpl, tmp / "trunc.npz"],
        "duplicate landmarks": [tmp / "dup.npz", scans],
        "huge coordinates": [tmp / "huge.npz", scans],
        "tiny coordinates": [tmp / "tiny.npz", scans],
        "template without a mesh": [tmp / "nokeys.npz", scans],
        "flat template": [tmp / "flat.npz", scans],
        "csv rows vs scans": [tpl, folder],
        "empty folder": [tpl, empty],
        "bad ply": [tpl, tmp / "bad.ply"],
        "negative smoothing": [tpl, scans, "--smooth-frames", "-1"],
        "bare array as template": [tmp / "bare.npz", scans],
        "bare array as scans": [tpl, tmp / "bare.npz"],
        "text as scans": [tpl, tmp / "text.npz"],
        "empty template": [tmp / "empty.npz", scans],
    }


BAD = ["missing template", "missing scans", "nan in points", "missing landmarks key", "frame count mismatch",
       "67 landmarks", "one frame", "truncated npz", "duplicate landmarks", "huge coordinates", "tiny coordinates",
       "template without a mesh", "flat template", "csv rows vs scans", "empty folder", "bad ply", "negative smoothing",
       "bare array as template", "bare array as scans", "text as scans", "empty template"]


@pytest.mark.parametrize("case", BAD)
def test_bad_input(tmp_path, capsys, case):
    argv = _bad_inputs(tmp_path)[case]
    out = tmp_path / "out.npz"
    code = main(["refine", *map(str, argv), "--out", str(out), "--obj-dir", str(tmp_path / "objs")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and err[0].startswith("aamtrack refine: error: "), err
    assert not out.exists() and not (tmp_path / "objs").exists() and not list(tmp_path.glob(".out*"))


@pytest.mark.parametrize("case", ["obj-dir is a file", "obj-dir under a file", "out is a folder"])
def test_unusable_outputs_are_refused_before_tracking(tmp_path, capsys, monkeypatch, case):
    import aamtrack.refine.sampler as sampler

    def fail(*args, **kwargs):
        raise AssertionError("tracking ran although the output cannot be written")

    monkeypatch.setattr(sampler, "refine_key_points", fail)
    rng = np.random.default_rng(SEED + 3)
    frames = _sequence(3)
    write_obj(tmp_path / "tpl.obj", frames[0], QUADS, LANDMARKS)
    _scans_npz(tmp_path / "scans.npz", frames, rng)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "folder.npz").mkdir()
    out, obj_dir = tmp_path / "out.npz", None
    if case == "obj-dir is a file":
        obj_dir = tmp_path / "afile"
    elif case == "obj-dir under a file":
        obj_dir = tmp_path / "afile" / "objs"
    else:
        out = tmp_path / "folder.npz"
    argv = ["refine", str(tmp_path / "tpl.obj"), str(tmp_path / "scans.npz"), "--out", str(out)]
    code = main(argv + (["--obj-dir", str(obj_dir)] if obj_dir else []))
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and err[0].startswith("aamtrack refine: error: "), err
    assert not (tmp_path / "out.npz").exists() and (tmp_path / "afile").read_text() == "x"
    assert list((tmp_path / "folder.npz").iterdir()) == []
