import json

import cv2
import numpy as np
import pytest

from aamtrack.errors import ModelFileError
from aamtrack.model import FORMAT_VERSION, load_model, save_model
from conftest import SEED


def test_round_trip(tmp_path, synth_model):
    path = tmp_path / "m.npz"
    save_model(synth_model, path)
    m = load_model(path)
    assert m.kind == "2d" and m.shape.coef_names == synth_model.shape.coef_names
    for a, b in zip(m.couples, synth_model.couples):
        assert a.face_px == b.face_px and np.array_equal(a.cascade, b.cascade) and np.array_equal(a.free, b.free)
    for a, b in zip(m.textures, synth_model.textures):
        assert np.array_equal(a.mean, b.mean) and np.array_equal(a.frame.pix_bary, b.frame.pix_bary)
    assert np.array_equal(m.shape.landmark_map, synth_model.shape.landmark_map)
    assert m.features == synth_model.features and m.validator.names == synth_model.validator.names
    assert np.array_equal(m.validator.weights, synth_model.validator.weights)
    assert np.array_equal(m.detector_box_points, synth_model.detector_box_points)
    lv, lv0 = m.landmark_validator, synth_model.landmark_validator
    assert lv0 is not None and lv0.descriptor_weights is not None  # the synthetic model has one: it is tested
    assert lv.bias == lv0.bias and np.array_equal(lv.descriptor_weights, lv0.descriptor_weights)
    assert np.array_equal(lv.weights, lv0.weights) and np.array_equal(lv.scale, lv0.scale)
    sc, sc0 = m.soft_cascade, synth_model.soft_cascade
    assert sc0 is not None and 0 <= synth_model.soft_above <= 1  # the synthetic model has one too
    assert m.soft_above == synth_model.soft_above and np.array_equal(sc.regressors, sc0.regressors)
    assert np.array_equal(sc.biases, sc0.biases) and np.array_equal(sc.shape_regressors, sc0.shape_regressors)
    assert sc.basis is m.landmark_cascade.basis and sc.ref is m.landmark_cascade.ref  # stored once, shared
    assert synth_model.landmark_cascade.repeats == 2 and m.landmark_cascade.repeats == sc.repeats == 2
    assert len(synth_model.soft_couples) == len(synth_model.couples)  # the synthetic model has soft couples too
    for a, b in zip(m.soft_couples, synth_model.soft_couples, strict=True):
        assert a.face_px == b.face_px and np.array_equal(a.free, b.free)
        assert np.array_equal(a.cascade, b.cascade) and np.array_equal(a.cascade_bias, b.cascade_bias)
    dv, dv0 = m.dim_validator, synth_model.dim_validator
    assert dv0 is not None and synth_model.dim_below > 0  # the synthetic model has one too
    assert m.dim_below == synth_model.dim_below and dv.bias == dv0.bias
    assert np.array_equal(dv.weights, dv0.weights) and np.array_equal(dv.descriptor_weights, dv0.descriptor_weights)
    sv, sv0 = m.soft_validator, synth_model.soft_validator
    assert sv0 is not None  # the synthetic model has a validator for soft faces too
    assert sv.bias == sv0.bias and np.array_equal(sv.weights, sv0.weights)
    assert np.array_equal(sv.descriptor_weights, sv0.descriptor_weights)
    sp, sp0 = m.shape_prior, synth_model.shape_prior
    assert sp0 is not None and sp.residual_variance == sp0.residual_variance  # learned by default: it is tested
    assert np.array_equal(sp.mean, sp0.mean) and np.array_equal(sp.modes, sp0.modes)
    assert np.array_equal(sp.variances, sp0.variances)
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]  # no temporary left behind


def test_round_trip_of_the_dim_faces_cascade(tmp_path, synth_model):
    """``Model.dim_cascade`` (the synthetic model learned one from dim copies of its faces) is stored as the soft
    one is: its own regressors (float16, as trained), the landmark cascade's reference shape and components
    shared, read back never repeated; a model without one reads back without one."""
    from dataclasses import replace

    dc = synth_model.dim_cascade
    assert dc is not None and dc.repeats == 0
    assert not np.array_equal(dc.regressors, synth_model.landmark_cascade.regressors)  # its own
    path = tmp_path / "m.npz"
    save_model(synth_model, path)
    m = load_model(path)
    assert np.array_equal(m.dim_cascade.regressors, dc.regressors) and np.array_equal(m.dim_cascade.biases, dc.biases)
    assert np.array_equal(m.dim_cascade.shape_regressors, dc.shape_regressors)
    assert m.dim_cascade.repeats == 0 and m.landmark_cascade.repeats == 2
    assert m.dim_cascade.basis is m.landmark_cascade.basis and m.dim_cascade.ref is m.landmark_cascade.ref
    save_model(replace(synth_model, dim_cascade=None), path)
    assert load_model(path).dim_cascade is None  # none stored, none read


def test_soft_faces_take_the_soft_cascade(synth_model, synth_data):
    """``Model.cascade_for``: a face above the threshold takes the soft cascade, below it the sharp one (the
    threshold moved about the face's own sharpness, so both sides are seen on one image)."""
    from dataclasses import replace

    from aamtrack.landmark_cascade import sharpness

    images, points = synth_data
    gray = cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY).astype(np.float32) if images[0].ndim == 3 else \
        images[0].astype(np.float32)
    s = sharpness(gray, 1.0, points[0])
    assert 0 < s < 1
    assert replace(synth_model, soft_above=s - 0.01).cascade_for(gray, 1.0, points[0]) is synth_model.soft_cascade
    assert replace(synth_model, soft_above=s + 0.01).cascade_for(gray, 1.0, points[0]) is \
        synth_model.landmark_cascade
    assert replace(synth_model, soft_cascade=None, soft_above=0.0).cascade_for(gray, 1.0, points[0]) is \
        synth_model.landmark_cascade


def test_soft_faces_take_the_soft_couples(synth_model, synth_data):
    """``Model.couples_for``: a search starting on a face above the soft landmark cascade's threshold takes the
    soft couples, below it the sharp ones; a model without soft couples always takes its couples."""
    from dataclasses import replace

    from aamtrack.landmark_cascade import sharpness

    images, points = synth_data
    gray = cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY).astype(np.float32) if images[0].ndim == 3 else \
        images[0].astype(np.float32)
    s = sharpness(gray, 1.0, points[0])
    m = synth_model
    assert m.soft_couples and m.soft_couples is not m.couples
    assert replace(m, soft_above=s - 0.01).couples_for(gray, 1.0, points[0]) is m.soft_couples
    assert replace(m, soft_above=s + 0.01).couples_for(gray, 1.0, points[0]) is m.couples
    assert replace(m, soft_couples=(), soft_above=0.0).couples_for(gray, 1.0, points[0]) is m.couples


def test_dim_noisy_faces_take_the_dim_validator(synth_model, synth_data):
    """``Model.validator_for``: a face whose signal-to-noise is below the threshold takes the validator for dim
    faces, above it the landmark validator (the threshold moved about the face's own value); a model without one
    always takes the landmark validator. A fit of the soft landmark cascade (``soft``) takes the validator for soft
    faces unless it is dim."""
    from dataclasses import replace

    from aamtrack.landmark_cascade import signal_to_noise

    images, points = synth_data
    gray = cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY).astype(np.float32) if images[0].ndim == 3 else \
        images[0].astype(np.float32)
    s = signal_to_noise(gray, 1.0, points[0])
    assert s > 0
    m = synth_model
    assert replace(m, dim_below=s + 0.01).validator_for(gray, 1.0, points[0]) is m.dim_validator
    assert replace(m, dim_below=s - 0.01).validator_for(gray, 1.0, points[0]) is m.landmark_validator
    assert replace(m, dim_validator=None, dim_below=1e3).validator_for(gray, 1.0, points[0]) is m.landmark_validator
    # a fit of the soft landmark cascade takes the validator for soft faces, unless the face is dim
    assert replace(m, dim_below=s - 0.01).validator_for(gray, 1.0, points[0], soft=True) is m.soft_validator
    assert replace(m, dim_below=s + 0.01).validator_for(gray, 1.0, points[0], soft=True) is m.dim_validator
    assert replace(m, soft_validator=None, dim_below=s - 0.01).validator_for(gray, 1.0, points[0], soft=True) is \
        m.landmark_validator


def test_a_dim_face_s_still_fit_takes_the_dim_cascade(synth_model, synth_data):
    """``Searcher.refine_landmarks``: a still's fit (``still``) of a face dim by the model's measure takes
    ``Model.dim_cascade`` (made here to move no point: zero regressors), a tracked frame's fit of the same face and
    a still's fit of a face that is not dim take the landmark cascade, which moves the points; the threshold
    ``dim_below`` moved about the face's own signal-to-noise so both sides are seen on one image."""
    from dataclasses import replace

    from aamtrack.imaging import Levels
    from aamtrack.landmark_cascade import signal_to_noise
    from aamtrack.search import Searcher

    images, points = synth_data
    gray = cv2.cvtColor(images[0], cv2.COLOR_BGR2GRAY).astype(np.float32) if images[0].ndim == 3 else \
        images[0].astype(np.float32)
    lc = synth_model.landmark_cascade
    inert = replace(lc, regressors=np.zeros_like(lc.regressors), biases=np.zeros_like(lc.biases),
                    shape_regressors=np.zeros_like(lc.shape_regressors), repeats=0)
    searcher = Searcher(synth_model)
    res = searcher.fit(Levels(gray, synth_model.features), _start(synth_model, points[0]), landmarks=False)
    r = searcher.factors(res.p)[-1]
    s = signal_to_noise(Levels(gray, synth_model.features).resampled(r), r, res.landmarks)
    dim, clear = (Searcher(replace(synth_model, dim_cascade=inert, soft_cascade=None, dim_below=b))
                  for b in (s + 0.01, s - 0.01))
    levels = Levels(gray, synth_model.features)
    assert np.array_equal(dim.refine_landmarks(levels, res, r, still=True).landmarks, res.landmarks)
    moved = np.abs(dim.refine_landmarks(levels, res, r).landmarks - res.landmarks).max()
    assert moved > 0.01  # a tracked frame's fit: the landmark cascade
    assert np.abs(clear.refine_landmarks(levels, res, r, still=True).landmarks - res.landmarks).max() > 0.01


def _start(model, pts):
    """A search vector of the rough pose fitted to 68 points, coefficients 0."""
    from aamtrack.mesh.shape_model import initial_pose

    return np.r_[initial_pose(model.shape, pts - 1.0, None), np.zeros(model.shape.n_shape)]


def _rewrite_meta(path, out, **changes):
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta.update(changes)
    data["meta"] = np.array(json.dumps(meta))
    np.savez_compressed(out, **data)


def test_unknown_version_is_rejected(tmp_path, synth_model):
    save_model(synth_model, tmp_path / "m.npz")
    _rewrite_meta(tmp_path / "m.npz", tmp_path / "future.npz", format_version=FORMAT_VERSION + 1)
    with pytest.raises(ModelFileError, match=f"format version {FORMAT_VERSION + 1} is not supported"):
        load_model(tmp_path / "future.npz")


@pytest.mark.parametrize("content,message", [
    (b"not a zip at all", r"bad.npz: not an aamtrack model \(not an .npz archive\)$"),
    (b"", "bad.npz: empty file, not an aamtrack model$"),
    (None, "no such model file")])
def test_corrupt_or_missing(tmp_path, content, message):
    """(A file that is not a zip archive at all is said to be so, not what numpy makes of it: it would try it
    as a pickle and say how to load pickles.)"""
    p = tmp_path / "bad.npz"
    if content is not None:
        p.write_bytes(content)
    with pytest.raises(ModelFileError, match=message):
        load_model(p)


def test_bare_array_file(tmp_path):
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(ModelFileError, match=r"not an aamtrack model \(a bare array, not an .npz archive\)$"):
        load_model(tmp_path / "array.npy")


def test_npz_without_meta(tmp_path):
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(ModelFileError, match="no 'meta'"):
        load_model(tmp_path / "other.npz")


def test_truncated_file(tmp_path, synth_model):
    save_model(synth_model, tmp_path / "m.npz")
    data = (tmp_path / "m.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelFileError):
        load_model(tmp_path / "cut.npz")


def _rewrite(path, out, arrays=None, **meta_changes):
    """Copy a model file with some arrays replaced and some metadata changed."""
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta.update(meta_changes)
    data["meta"] = np.array(json.dumps(meta))
    data.update(arrays or {})
    np.savez_compressed(out, **data)


@pytest.fixture
def model_path(tmp_path, synth_model):
    path = tmp_path / "m.npz"
    save_model(synth_model, path)
    return path


def _damaged(synth_model):
    """(name, arrays to replace, metadata changes, message) of malformed models that must not load."""
    c0 = synth_model.couples[0]
    t0 = synth_model.textures[0]
    lc = synth_model.landmark_cascade
    lc_meta = {"halves": list(lc.halves), "cells": lc.spec.cells, "cell": lc.spec.cell, "bins": lc.spec.bins,
               "floor": lc.spec.floor}
    return [
        ("negative free", {"couple0/free": -c0.free - 1}, {}, "indices outside"),
        ("free beyond p", {"couple0/free": c0.free + 100}, {}, "indices outside"),
        ("nan cascade", {"couple0/cascade": np.full_like(c0.cascade, np.nan)}, {}, "non-finite"),
        ("inverted bounds", {"shape/coef_lo": synth_model.shape.coef_hi + 1}, {}, "bounds inverted"),
        ("texture index", {"tex0/pix_vid": t0.frame.pix_vid + 10_000}, {}, "indices outside"),
        ("mean length", {"tex0/mean": t0.mean[:-3]}, {}, "has shape"),
        ("float version", {}, {"format_version": FORMAT_VERSION + 0.5}, "not an integer"),
        ("text version", {}, {"format_version": str(FORMAT_VERSION)}, "not an integer"),
        ("kind says 3d", {}, {"kind": "3d"}, "without shape units"),
        ("unknown kind", {}, {"kind": "4d"}, "unknown model kind"),
        ("negative feature", {}, {"features": {"kind": "gradient", "lcn_sigma": 8.0, "soft": -1.0, "eps": 1.0, "blur": 1.0}},
         "feature settings"),
        ("unknown feature", {}, {"features": {"kind": "sift", "lcn_sigma": 8.0, "soft": 1.0, "eps": 1.0, "blur": 1.0}},
         "feature kind"),
        ("texture of another couple", {}, {"couples": [{"face_px": 32.0, "texture": 7}]}, "names texture"),
        ("no couples", {}, {"couples": []}, "no couples"),
        ("missing array", {"couple0/cascade_bias": None}, {}, "missing"),
        ("descriptor weights length", {"landmark_validator/descriptor_weights":
                                       synth_model.landmark_validator.descriptor_weights[:-1]}, {}, "has shape"),
        ("landmark cascade without repeats", {}, {"landmark_cascade": lc_meta}, "unreadable landmark cascade"),
        ("negative repeats", {}, {"landmark_cascade": {**lc_meta, "repeats": -1}}, "landmark cascade settings out"),
        ("fractional repeats", {}, {"landmark_cascade": {**lc_meta, "repeats": 1.5}}, "landmark cascade settings out"),
        ("landmark validator without cascade", {}, {"landmark_cascade": None}, "without a landmark cascade"),
        ("unreadable landmark validator", {}, {"landmark_validator": {"names": 3}}, "unreadable landmark_validator"),
        ("soft cascade threshold", {}, {"soft_landmarks": {"above": 2.0}}, "outside 0..1"),
        ("unreadable soft cascade", {}, {"soft_landmarks": {"below": 0.5}}, "unreadable soft landmark cascade"),
        ("soft cascade without cascade", {}, {"landmark_cascade": None, "landmark_validator": None},
         "soft landmark cascade without a landmark cascade"),
        ("soft regressors of another size", {"soft_landmarks/biases": np.zeros((1, 136))}, {}, "has shape"),
        ("dim validator threshold", {}, {"dim_validator": {"names": list(synth_model.dim_validator.names),
                                                           "bias": 0.0, "below": -1.0}}, "outside 0..1000"),
        ("unreadable dim validator", {}, {"dim_validator": {"names": ["a"], "bias": 0.0}}, "unreadable dim_validator"),
        ("dim validator without landmark validator", {}, {"landmark_validator": None},
         "dim faces without a landmark validator"),
        ("dim descriptor weights length", {"dim_validator/descriptor_weights":
                                           synth_model.dim_validator.descriptor_weights[:-1]}, {}, "has shape"),
        ("soft couples of another count", {}, {"soft_couples": [{"face_px": 32.0, "texture": 0}]},
         "soft couples do not match"),
        ("soft couple of another size", {}, {"soft_couples": [{"face_px": 2.0 * c.face_px, "texture": c.texture}
                                                              for c in synth_model.couples]}, "differs from couple 0"),
        ("soft couple nan cascade", {"soft_couple0/cascade": np.full_like(c0.cascade, np.nan)}, {}, "non-finite"),
        ("soft couples without a gate", {}, {"soft_landmarks": None}, "without a soft landmark cascade's"),
        ("soft validator without a soft cascade", {}, {"soft_landmarks": None, "soft_couples": []},
         "soft faces without a landmark validator"),
        ("soft validator descriptor weights length", {"soft_validator/descriptor_weights":
                                                      synth_model.soft_validator.descriptor_weights[:-1]}, {},
         "has shape"),
        ("dim cascade without its arrays", {"dim_landmarks/biases": None}, {}, "missing"),
        ("dim cascade without a dim validator", {}, {"dim_validator": None},
         "dim faces without a landmark cascade and a validator"),
        ("shape prior without its modes", {"shape_prior/modes": None}, {}, "missing"),
        ("shape prior modes of another count", {"shape_prior/modes": synth_model.shape_prior.modes[:-1]}, {},
         "has shape"),
        ("negative shape prior variance", {"shape_prior/variances": -synth_model.shape_prior.variances}, {},
         "variances are not positive"),
        ("unreadable shape prior", {}, {"shape_prior": {"residual_variance": "small"}}, "unreadable shape_prior"),
        ("validator of other statistics", {"validator/weights": np.zeros(5), "validator/mean": np.zeros(5),
                                           "validator/scale": np.ones(5)},
         {"validator": {"names": ["a", "b", "c", "d", "e"], "bias": 0.0}}, "this version computes"),
    ]


@pytest.mark.parametrize("case", range(39))
def test_malformed_models_give_one_clear_error(tmp_path, model_path, synth_model, case):
    name, arrays, meta, message = _damaged(synth_model)[case]
    bad = tmp_path / "bad.npz"
    with np.load(model_path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    for k, v in arrays.items():
        if v is None:
            del data[k]
        else:
            data[k] = v
    m = json.loads(str(data["meta"]))
    m.update(meta)
    data["meta"] = np.array(json.dumps(m))
    np.savez_compressed(bad, **data)
    with pytest.raises(ModelFileError, match=message):
        load_model(bad)


def test_crafted_header_is_refused_before_allocation(tmp_path, model_path):
    """An entry whose .npy header claims a huge array (the data is not there) is refused, not allocated."""
    import zipfile

    bad = tmp_path / "huge.npz"
    with zipfile.ZipFile(model_path) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "couple0/cascade.npy":
                header = b"{'descr': '<f4', 'fortran_order': False, 'shape': (100000, 100000, 20), }"
                header += b" " * (63 - (len(header) + 10) % 64) + b"\n"
                data = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + b"\0" * 64
            zout.writestr(item, data)
    with pytest.raises(ModelFileError, match="claims"):
        load_model(bad)


def test_fuzzed_model_files_load_cleanly_or_fail_with_a_model_error(tmp_path, model_path, synth_data):
    """A seeded few hundred damaged copies (bytes flipped, entries cut): each either loads and runs a search
    without error, or raises ModelFileError; never another exception (and never a crash in compiled code)."""
    from aamtrack.imaging import to_gray32
    from aamtrack.search import Searcher

    rng = np.random.default_rng(SEED)
    raw = model_path.read_bytes()
    levels_image = to_gray32(synth_data[0][0])
    loaded = failed = 0
    for k in range(300):
        data = bytearray(raw)
        n = int(rng.integers(1, 8))
        for pos in rng.integers(0, len(data), n):
            data[pos] = int(rng.integers(0, 256))
        if k % 10 == 0:
            data = data[: int(rng.integers(10, len(data)))]
        bad = tmp_path / f"fuzz{k}.npz"
        bad.write_bytes(bytes(data))
        try:
            model = load_model(bad)
        except ModelFileError:
            failed += 1
            continue
        loaded += 1
        searcher = Searcher(model)
        p0 = np.r_[0.0, 0.0, 0.0, 100.0, 110.0, 110.0, np.zeros(model.n_params - 6)]
        res = searcher.fit(searcher.levels(levels_image), p0)
        assert res.p.shape == (model.n_params,)
    assert failed > 100  # most damage is caught (zip CRCs, headers, checks)
    print(f"fuzz: {loaded} loaded and searched, {failed} refused with one clear error")


def test_zip_feature_python_cannot_read_is_one_clear_error(tmp_path, model_path):
    """A model file whose zip entries claim a feature ``zipfile`` does not implement (flag bit 5, compressed
    patched data: seen by the fuzz test) is a ModelFileError, not a NotImplementedError traceback."""
    data = bytearray(model_path.read_bytes())
    at = data.find(b"PK\x01\x02")  # the first central directory entry; its flags are 8 bytes in
    assert at > 0
    data[at + 8] |= 0x20
    bad = tmp_path / "patched.npz"
    bad.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match="not a readable aamtrack model"):
        load_model(bad)
