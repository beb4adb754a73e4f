"""``aamtrack transfer``: bad inputs give one line on stderr, a non-zero exit and no output; an end-to-end run."""

import numpy as np
import pytest
from conftest import SEED
from synthetic import bumpy_surface, smooth_warp

from aamtrack.cli import main
from aamtrack.io.obj import read_obj, write_obj

LANDMARKS = np.linspace(0, 399, 68).round().astype(np.int64)  # 68 spread vertices of a 20 x 20 surface


def _source_npz(path, n_frames=3, **extra):
    neutral = bumpy_surface(20)
    frames = np.stack([smooth_warp(neutral, a) for a in np.linspace(0, 1, n_frames)])
    np.savez(path, frames=frames, landmark68=LANDMARKS, **extra)
    return frames


def _target_obj(path):
    verts = 2.0 * bumpy_surface(20)
    quads = np.array([[i * 20 + j, i * 20 + j + 1, (i + 1) * 20 + j + 1, (i + 1) * 20 + j]
                      for i in range(19) for j in range(19)])
    write_obj(path, verts, quads, LANDMARKS)
    return verts


def _csv(path, rows):
    head = ["frame", "success"] + [f"{a}_{i}" for a in "XYZ" for i in range(68)]
    lines = [",".join(head)] + [",".join(str(v) for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")


def _run(capsys, *argv):
    code = main(["transfer", *map(str, argv)])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


def test_end_to_end_npz_source_obj_target(tmp_path, capsys):
    frames = _source_npz(tmp_path / "src.npz", n_frames=4)
    verts = _target_obj(tmp_path / "tgt.obj")
    out = tmp_path / "out.npz"
    code, _ = _run(capsys, tmp_path / "src.npz", tmp_path / "tgt.obj", "--out", out, "--obj-dir", tmp_path / "objs")
    assert code == 0
    with np.load(out) as data:
        anim = data["frames"]
    assert anim.shape == (4, 400, 3) and anim.dtype == np.float32
    assert np.abs(anim[0] - verts).max() < 1e-5  # frame 0 is the target (float32 rounding)
    truth = 2.0 * frames  # the target is the source face at twice the size, same vertex order
    assert np.linalg.norm(anim - truth, axis=2).mean() < 0.1 * np.linalg.norm(truth - truth[0], axis=2).mean()
    objs = sorted((tmp_path / "objs").glob("*.obj"))
    assert len(objs) == 4 and read_obj(objs[-1]).faces.shape == (361, 4)
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary files left


def test_csv_source_holds_last_good_frame(tmp_path, capsys):
    rng = np.random.default_rng(SEED)
    base = 0.1 * bumpy_surface(20)[LANDMARKS]
    moved = base + 0.01 * rng.standard_normal(base.shape)
    flat = lambda p: list(p[:, 0]) + list(p[:, 1]) + list(p[:, 2])  # noqa: E731
    _csv(tmp_path / "t.csv", [[0, 0] + ["nan"] * 204, [1, 1] + flat(base), [2, 1] + flat(moved), [3, 0] + [0] * 204])
    _target_obj(tmp_path / "tgt.obj")
    code, _ = _run(capsys, tmp_path / "t.csv", tmp_path / "tgt.obj", "--out", tmp_path / "o.npz")
    assert code == 0
    with np.load(tmp_path / "o.npz") as data:
        anim = data["frames"]
    assert anim.shape == (3, 400, 3)  # the row before the first success is dropped
    assert np.array_equal(anim[2], anim[1])  # a failed row repeats the last good frame


def _bad_inputs(tmp):
    """(name, argv) pairs of bad inputs; each writes what it needs into tmp."""
    _source_npz(tmp / "src.npz")
    _target_obj(tmp / "tgt.obj")
    np.savez(tmp / "nolm.npz", frames=np.zeros((3, 100, 3)))
    np.savez(tmp / "badlm.npz", frames=np.zeros((3, 100, 3)), landmark68=np.arange(10))
    np.savez(tmp / "empty.npz", frames=np.zeros((0, 100, 3)), landmark68=np.arange(68))
    np.savez(tmp / "oob.npz", frames=np.zeros((2, 50, 3)), landmark68=np.arange(68))
    np.savez(tmp / "vert2d.npz", vertices=np.zeros((10, 2)))
    (tmp / "junk.obj").write_text("v 1 2 x\n")
    (tmp / "noverts.obj").write_text("# nothing\n")
    (tmp / "junk.npz").write_bytes(b"not a zip")
    _csv(tmp / "fail.csv", [[0, 0] + [0] * 204])
    (tmp / "cols.csv").write_text("frame,success,X_0\n0,1,0\n")
    verts = 2.0 * bumpy_surface(20)
    np.savez(tmp / "faces_oob.npz", vertices=verts, faces=np.array([[0, 1, 400]]), landmark68=LANDMARKS)
    np.savez(tmp / "faces_2.npz", vertices=verts, faces=np.array([[0, 1, -1]]), landmark68=LANDMARKS)
    np.savez(tmp / "flat.npz", vertices=verts * [1, 1, 0], landmark68=LANDMARKS)  # degenerate: a plane
    np.savez(tmp / "dup.npz", vertices=verts, landmark68=np.r_[LANDMARKS[:67], LANDMARKS[3]])
    np.savez(tmp / "huge.npz", vertices=verts * 1e300, landmark68=LANDMARKS)
    np.savez(tmp / "tiny.npz", vertices=verts * 1e-300, landmark68=LANDMARKS)
    np.savez(tmp / "ict_nolm.npz", neutral=verts, quads=np.zeros((0, 4), np.int64))
    (tmp / "trunc.npz").write_bytes((tmp / "src.npz").read_bytes()[:2000])
    (tmp / "f0.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    src, tgt = tmp / "src.npz", tmp / "tgt.obj"
    return {
        "target face out of range": [src, tmp / "faces_oob.npz"],
        "target face of 2 corners": [src, tmp / "faces_2.npz"],
        "degenerate target": [src, tmp / "flat.npz"],
        "duplicate landmarks": [src, tmp / "dup.npz"],
        "huge coordinates": [src, tmp / "huge.npz"],
        "tiny coordinates": [src, tmp / "tiny.npz"],
        "ICT layout without landmarks": [src, tmp / "ict_nolm.npz"],
        "truncated npz": [tmp / "trunc.npz", tgt],
        "obj face index 0": [src, tmp / "f0.obj"],
        "missing source": [tmp / "absent.npz", tgt],
        "unreadable npz": [tmp / "junk.npz", tgt],
        "no landmarks": [tmp / "nolm.npz", tgt],
        "wrong landmark count": [tmp / "badlm.npz", tgt],
        "landmark out of range": [tmp / "oob.npz", tgt],
        "empty sequence": [tmp / "empty.npz", tgt],
        "no successful row": [tmp / "fail.csv", tgt],
        "missing columns": [tmp / "cols.csv", tgt],
        "malformed obj": [src, tmp / "junk.obj"],
        "obj without vertices": [src, tmp / "noverts.obj"],
        "target vertices not 3D": [src, tmp / "vert2d.npz"],
        "missing target": [src, tmp / "absent.obj"],
        "obj without landmarks": [src, tmp / "tgt.obj", "--target-landmarks", tmp / "absent.txt"],
    }


BAD_CASES = [
    "target face out of range", "target face of 2 corners", "degenerate target", "duplicate landmarks",
    "huge coordinates", "tiny coordinates", "ICT layout without landmarks", "truncated npz", "obj face index 0",
    "missing source", "unreadable npz", "no landmarks", "wrong landmark count", "landmark out of range",
    "empty sequence", "no successful row", "missing columns", "malformed obj", "obj without vertices",
    "target vertices not 3D", "missing target", "obj without landmarks",
]


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_input(tmp_path, capsys, case):
    argv = _bad_inputs(tmp_path)[case]
    out = tmp_path / "out.npz"
    code, err = _run(capsys, *argv[:2], "--out", out, "--obj-dir", tmp_path / "objs", *argv[2:])
    assert code == 1
    assert len(err) == 1 and err[0].startswith("aamtrack transfer: error: "), err
    assert not out.exists() and not list(tmp_path.glob(".out.npz*"))  # nothing written
    assert not (tmp_path / "objs").exists()


def test_ict_layout_target_compressed_output(tmp_path, capsys):
    import zipfile

    _source_npz(tmp_path / "src.npz", n_frames=3)
    verts = 2.0 * bumpy_surface(20)
    quads = np.array([[i * 20 + j, i * 20 + j + 1, (i + 1) * 20 + j + 1, (i + 1) * 20 + j]
                      for i in range(19) for j in range(19)])
    np.savez(tmp_path / "ict.npz", neutral=verts.astype(np.float32), quads=quads, landmark68_vertex_idx=LANDMARKS,
             expression_names=np.array(["jawOpen"]))  # the shared ICT FaceKit file's keys
    out = tmp_path / "anim.npz"
    code, err = _run(capsys, tmp_path / "src.npz", tmp_path / "ict.npz", "--out", out)
    assert code == 0 and not any("registering" in e for e in err)
    with zipfile.ZipFile(out) as z:
        assert all(i.compress_type == zipfile.ZIP_DEFLATED for i in z.infolist())  # np.savez_compressed
    with np.load(out) as data:
        assert data["frames"].shape == (3, 400, 3) and np.array_equal(data["faces"], quads)
        assert np.array_equal(data["landmark68"], LANDMARKS)


def test_missing_mesh_keys_are_named(tmp_path, capsys):
    _source_npz(tmp_path / "src.npz")
    np.savez(tmp_path / "other.npz", verts=np.zeros((5, 3)))
    code, err = _run(capsys, tmp_path / "src.npz", tmp_path / "other.npz", "--out", tmp_path / "o.npz")
    assert code == 1 and "`vertices`" in err[0] and "`neutral`" in err[0] and "verts" in err[0]


def test_obj_roundtrip(tmp_path):
    verts = bumpy_surface(9)
    faces = np.array([[0, 1, 10, -1], [1, 2, 11, 10]])
    write_obj(tmp_path / "m.obj", verts, faces, np.arange(68)[::-1])
    mesh = read_obj(tmp_path / "m.obj")
    assert np.abs(mesh.vertices - verts).max() < 1e-5  # 6 significant digits
    assert np.array_equal(mesh.faces, faces) and np.array_equal(mesh.landmark68, np.arange(68)[::-1])
