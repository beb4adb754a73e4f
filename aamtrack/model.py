"""The trained model: shape model, feature kind, texture maps with their mean textures and appearance bases, per
couple (image resolution x texture resolution) a learned update cascade (or a Jacobian update matrix), the
detector's box geometry and the fit validator; saved as one versioned ``.npz``.

File layout (``np.savez_compressed``, read with ``allow_pickle=False``): ``meta`` is a JSON string with
``format_version``, the package version, the model kind, names, the feature settings and the training record;
arrays are ``shape/*``, ``tex{i}/*``, ``couple{j}/*``, ``detector/box_points``, ``validator/*`` and, with a
landmark cascade, ``landmarks/*`` and ``landmark_validator/*``. ``load_model``
checks every array's shape, dtype, finiteness and index range, so a damaged or crafted file is one clear error,
never a crash in compiled code.
"""

from __future__ import annotations

import json
import math
import tokenize
import zipfile
import zlib
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from . import __version__
from .errors import ModelFileError
from .imaging import FEATURE_KINDS, Features
from .io.atomic import atomic_write
from .io.obj import npz_problem
from .io.pts import N_LANDMARKS
from .landmark_cascade import DescriptorSpec, LandmarkCascade, quantise_rows, sharpness, signal_to_noise
from .mesh.shape_model import N_POSE, ShapeModel
from .mesh.shape_prior import ShapePrior
from .mesh.texture_map import TextureFrame

FORMAT_VERSION = 12  # 3: the landmark cascade (``landmark_cascade``); 4: the landmark validator; 5: it reads
# the cascade's last-stage descriptors (before the last update) instead of a pass of its own at the final points;
# 6: the landmark cascade's stages also read the points' shape (``landmarks/shape_regressors``); 7: a second
# landmark cascade for soft (blurred) faces (``soft_landmarks/*``, ``Model.soft_cascade``); 8: a second landmark
# validator for dim, noisy faces (``dim_validator/*``, ``Model.dim_validator``); 9: a second set of couples for soft
# faces (``soft_couple*/*``, ``Model.soft_couples``) and (optional) a landmark validator for soft faces
# (``soft_validator/*``, ``Model.soft_validator``); 10: the landmark cascade's last stage ``repeats`` (it runs that
# many more times: older files would read as none, and their validators were learned without); 11: a landmark
# cascade for stills' fits of dim faces (``dim_landmarks/*``, ``Model.dim_cascade``); 12: the labelled shapes' prior
# (``shape_prior/*``, ``Model.shape_prior``), which the tracker refuses implausible fits by
STAT_NAMES = ("rms_residual", "texture_correlation", "texture_energy", "pose_update")
"""The fit statistics a validator reads, in order (``aamtrack.search.Searcher.statistics`` computes them)."""
MAX_ENTRY_BYTES = 512 * 2 ** 20  # no array of a model is near this; a crafted header claiming more is refused


@dataclass(frozen=True)
class Texture:
    """One texture resolution: its map, mean texture (D,) float32 and appearance basis (D, m) float32, with
    D = channels * frame.n_pixels (channel-major)."""

    frame: TextureFrame
    mean: np.ndarray
    appearance: np.ndarray


@dataclass(frozen=True)
class Couple:
    """One couple: runs on the image resampled so the face is ``face_px`` wide, on texture ``texture``, and
    updates the search vector's entries ``free`` (n_free,) int64 (the pose, coefficients and, 3D, the shape
    units; the coarsest couple may search the pose only).

    Learned cascade: ``cascade`` (n_stages, n_free, D) float32 and ``cascade_bias`` (n_stages, n_free) float64,
    delta = R_s e + b_s per stage (``aamtrack.train.cascade``). Jacobian alternative (n_stages = 0):
    ``update_matrix`` (n_free, D) float32, U = -(G^T G + diag(prior))^-1 G^T, with ``prior_step``
    (n_free, n_free) and ``prior`` (n_free,) for the Gaussian prior (``aamtrack.train.update``).
    """

    face_px: float
    texture: int
    free: np.ndarray
    cascade: np.ndarray
    cascade_bias: np.ndarray
    update_matrix: np.ndarray
    prior_step: np.ndarray
    prior: np.ndarray

    @property
    def n_stages(self) -> int:
        return self.cascade.shape[0]

    @cached_property
    def quantised(self) -> tuple[np.ndarray, np.ndarray]:
        """The cascade's matrices as the compiled search reads them (``landmark_cascade.quantise_rows``: int16,
        transposed, per-row scales): half the bytes of the finest couple's 1.3 MB (3D), which a tracked frame
        reads from memory, and a product that vectorises across the rows."""
        return quantise_rows(self.cascade)


@dataclass(frozen=True)
class Validator:
    """Logistic fit validator: confidence = 1 / (1 + exp(-(w . (x - mean) / scale + d . z + bias))) over the fit
    statistics x named ``names`` (``STAT_NAMES``) and, for the landmark validator, the landmark
    cascade's last-stage descriptors z (``LandmarkCascade.run``) weighted by
    ``descriptor_weights`` d (float32, None for a statistics-only validator)."""

    names: tuple
    weights: np.ndarray
    mean: np.ndarray
    scale: np.ndarray
    bias: float
    descriptor_weights: np.ndarray | None = None

    def logit(self, x: np.ndarray, z: np.ndarray | None = None) -> float:
        """The log-odds behind the confidence (0 at confidence 0.5)."""
        s = float(np.dot(self.weights, (np.asarray(x, float) - self.mean) / self.scale) + self.bias)
        if self.descriptor_weights is not None:
            if z is None:
                raise ValueError("this validator reads the landmark descriptors too")
            s += float(np.dot(self.descriptor_weights, z))
        return s

    def __call__(self, x: np.ndarray, z: np.ndarray | None = None) -> float:
        return float(1.0 / (1.0 + np.exp(-np.clip(self.logit(x, z), -50.0, 50.0))))


@dataclass(frozen=True)
class Model:
    """A trained AAM. Couples are ordered coarse to fine (couple 0 is the coarsest).

    The search vector p is [pose (6), coefficients (n_coef), shape units (n_shape, 3D only)]: the 3D model
    searches the person's shape units sigma with the pose and animation units (``ShapeModel.person_view``);
    the tracker holds sigma once it has estimated it by pinning its bounds.
    """

    shape: ShapeModel
    features: Features
    textures: tuple
    couples: tuple
    detector_box_points: np.ndarray
    validator: Validator
    config: dict = field(default_factory=dict)
    landmark_cascade: LandmarkCascade | None = None
    landmark_validator: Validator | None = None  # the reported confidence, after the landmark cascade
    soft_cascade: LandmarkCascade | None = None  # the landmark cascade for faces softer than ``soft_above``
    soft_above: float = math.inf  # ``landmark_cascade.sharpness`` above which a face takes ``soft_cascade``
    dim_validator: Validator | None = None  # the landmark validator for faces whose signal-to-noise is below
    dim_below: float = 0.0  # this (``landmark_cascade.signal_to_noise``)
    soft_couples: tuple = ()  # the couples a search takes for a face softer than ``soft_above`` at its start (or none)
    soft_validator: Validator | None = None  # the landmark validator for fits the soft cascade gave (not dim ones)
    dim_cascade: LandmarkCascade | None = None  # the landmark cascade for a still's fit of a dim face (``dim``)
    shape_prior: ShapePrior | None = None  # the labelled 68-point shapes' distribution (``mesh.shape_prior``)

    @property
    def kind(self) -> str:
        return self.shape.kind

    def cascade_for(self, image: np.ndarray, scale: float, pts: np.ndarray) -> LandmarkCascade | None:
        """The landmark cascade for the face at pts (68, 2) (frame pixels) in ``image`` (the grey frame resampled
        by ``scale``): ``soft_cascade`` when the face looks softer than ``soft_above`` (``sharpness``), else
        ``landmark_cascade``. The soft one shares the other's reference shape and descriptor components, so the
        landmark validator reads either one's last-stage descriptors."""
        if self.soft_cascade is not None and sharpness(image, scale, pts) > self.soft_above:
            return self.soft_cascade
        return self.landmark_cascade

    def couples_for(self, image: np.ndarray, scale: float, pts: np.ndarray) -> tuple:
        """The couples a search from the points pts (68, 2) (frame pixels; its start's) takes, read as
        ``cascade_for`` reads a fit: ``soft_couples`` when the face looks softer than ``soft_above``, else
        ``couples``. The sharp couples' updates, learned on sharp photos, lead a blurred face's search astray from
        its coarsest couple on; the soft ones took cap12 blurred by 0.06 eye distances from NME 0.0367 to 0.0318
        (``TrainConfig.soft_search_share``)."""
        if self.soft_couples and sharpness(image, scale, pts) > self.soft_above:
            return self.soft_couples
        return self.couples

    def dim(self, image: np.ndarray, scale: float, pts: np.ndarray) -> bool:
        """Whether the face at pts (68, 2) (frame pixels) in ``image`` (the grey frame resampled by ``scale``) is
        dim and noisy: its contrast over the image's noise (``signal_to_noise``) below ``dim_below``, for a model
        with a validator for such faces (``validator_for``)."""
        return self.dim_validator is not None and signal_to_noise(image, scale, pts) < self.dim_below

    def validator_for(self, image: np.ndarray, scale: float, pts: np.ndarray, *,
                      soft: bool = False) -> Validator | None:
        """The landmark validator for the fit at pts (68, 2) (frame pixels, after the landmark cascade) in
        ``image`` (the grey frame resampled by ``scale``): ``dim_validator`` when the face's contrast over the
        image's noise (``signal_to_noise``) is below ``dim_below``; else ``soft_validator`` for a fit of the soft
        landmark cascade (``soft``, as ``cascade_for`` picked it; helen_test blurred by 0.06 eye distances, 3D:
        89.1% -> 90.9% of the stills within NME 0.08, none of 330 blurred non-face stills accepted); else
        ``landmark_validator``. One validator for both kinds of face either refused good fits of small faces in a
        dim room (learned on each degradation alone) or, learned on them too, accepted more bad fits of clear
        faces (benchmarks/README.md, robustness)."""
        if self.dim(image, scale, pts):
            return self.dim_validator
        if soft and self.soft_validator is not None:
            return self.soft_validator
        return self.landmark_validator

    @property
    def n_params(self) -> int:
        return self.shape.n_q + self.shape.n_shape

    @property
    def param_names(self) -> tuple:
        return self.shape.param_names + tuple(self.shape.shape_names)


_SHAPE_ARRAYS = ("mean", "shape_units", "basis", "triangles", "landmark_map", "coef_lo", "coef_hi", "shape_sd")
_COUPLE_ARRAYS = ("free", "cascade", "cascade_bias", "update_matrix", "prior_step", "prior")


def save_model(model: Model, path: str | Path) -> None:
    """Write the model atomically (temporary name, renamed when complete)."""
    arrays = {f"shape/{k}": np.asarray(getattr(model.shape, k)) for k in _SHAPE_ARRAYS}
    for i, t in enumerate(model.textures):
        arrays[f"tex{i}/pix_xy"] = t.frame.pix_xy
        arrays[f"tex{i}/pix_vid"] = t.frame.pix_vid
        arrays[f"tex{i}/pix_bary"] = t.frame.pix_bary
        arrays[f"tex{i}/mean"] = t.mean
        arrays[f"tex{i}/appearance"] = t.appearance
    for prefix, couples in (("couple", model.couples), ("soft_couple", model.soft_couples)):
        for j, c in enumerate(couples):
            for k in _COUPLE_ARRAYS:
                arrays[f"{prefix}{j}/{k}"] = getattr(c, k)
    arrays["detector/box_points"] = model.detector_box_points
    v = model.validator
    arrays["validator/weights"], arrays["validator/mean"], arrays["validator/scale"] = v.weights, v.mean, v.scale
    lc = model.landmark_cascade
    if lc is not None:
        # float16: the trained regressors are already rounded to it (``train.landmarks``), and it halves the file
        arrays["landmarks/ref"], arrays["landmarks/regressors"], arrays["landmarks/biases"] = \
            lc.ref, lc.regressors.astype(np.float16), lc.biases
        arrays["landmarks/basis_mean"], arrays["landmarks/basis"] = lc.basis_mean, lc.basis
        arrays["landmarks/shape_regressors"] = lc.shape_regressors.astype(np.float16)
    sc, dc = model.soft_cascade, model.dim_cascade
    for prefix, other in (("soft_landmarks", sc), ("dim_landmarks", dc)):
        if other is not None:  # its reference shape and descriptor components are the landmark cascade's
            arrays[f"{prefix}/regressors"], arrays[f"{prefix}/biases"] = other.regressors.astype(np.float16), \
                other.biases
            arrays[f"{prefix}/shape_regressors"] = other.shape_regressors.astype(np.float16)
    lv = model.landmark_validator
    if lv is not None:
        arrays["landmark_validator/weights"], arrays["landmark_validator/mean"] = lv.weights, lv.mean
        arrays["landmark_validator/scale"] = lv.scale
        arrays["landmark_validator/descriptor_weights"] = lv.descriptor_weights
    for key, val in (("dim_validator", model.dim_validator), ("soft_validator", model.soft_validator)):
        if val is not None:
            arrays[f"{key}/weights"], arrays[f"{key}/mean"] = val.weights, val.mean
            arrays[f"{key}/scale"], arrays[f"{key}/descriptor_weights"] = val.scale, val.descriptor_weights
    sp = model.shape_prior
    if sp is not None:
        arrays["shape_prior/mean"], arrays["shape_prior/modes"] = sp.mean, sp.modes
        arrays["shape_prior/variances"] = sp.variances
    dv, sv = model.dim_validator, model.soft_validator
    meta = {
        "format_version": FORMAT_VERSION,
        "aamtrack_version": __version__,
        "kind": model.shape.kind,
        "shape_names": list(model.shape.shape_names),
        "coef_names": list(model.shape.coef_names),
        "features": {"kind": model.features.kind, "lcn_sigma": model.features.lcn_sigma,
                     "soft": model.features.soft, "eps": model.features.eps, "blur": model.features.blur},
        "textures": [list(t.frame.shape) for t in model.textures],
        "couples": [{"face_px": c.face_px, "texture": c.texture} for c in model.couples],
        "soft_couples": [{"face_px": c.face_px, "texture": c.texture} for c in model.soft_couples],
        "validator": {"names": list(v.names), "bias": v.bias},
        "landmark_cascade": None if lc is None else {"halves": list(lc.halves), "cells": lc.spec.cells,
                                                     "cell": lc.spec.cell, "bins": lc.spec.bins,
                                                     "floor": lc.spec.floor, "repeats": lc.repeats},
        "landmark_validator": None if lv is None else {"names": list(lv.names), "bias": lv.bias},
        "soft_landmarks": None if sc is None else {"above": model.soft_above},
        "dim_landmarks": None if dc is None else {},
        "dim_validator": None if dv is None else {"names": list(dv.names), "bias": dv.bias,
                                                  "below": model.dim_below},
        "soft_validator": None if sv is None else {"names": list(sv.names), "bias": sv.bias},
        "shape_prior": None if sp is None else {"residual_variance": sp.residual_variance},
        "config": model.config,
    }
    arrays["meta"] = np.array(json.dumps(meta))
    with atomic_write(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


class _Checker:
    """Reads and checks the arrays of one model file; every failure is a ModelFileError naming the file."""

    def __init__(self, path: Path, z):
        self.path, self.z = path, z

    def fail(self, what: str):
        raise ModelFileError(f"{self.path}: corrupt model, {what}")

    def array(self, key: str, dtype, shape: tuple, *, finite: bool = True) -> np.ndarray:
        """The entry ``key`` as a C-contiguous array of ``dtype``, its shape matching ``shape`` (None = any
        size), its values finite (floats)."""
        if key not in self.z.files:
            self.fail(f"missing '{key}'")
        self._check_header(key)
        a = self.z[key]
        if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
            self.fail(f"'{key}' has shape {a.shape}, expected {tuple('*' if s is None else s for s in shape)}")
        kind = np.dtype(dtype).kind
        if (kind == "f" and a.dtype.kind not in "fiu") or (kind in "iu" and a.dtype.kind not in "iu"):
            self.fail(f"'{key}' has dtype {a.dtype}, expected {np.dtype(dtype)}")
        a = np.ascontiguousarray(a, dtype=dtype)
        if finite and kind == "f" and not np.isfinite(a).all():
            self.fail(f"'{key}' has non-finite values")
        return a

    def _check_header(self, key: str) -> None:
        """Refuse an entry whose .npy header claims more bytes than the entry holds (or than any model needs)
        before numpy allocates them."""
        from numpy.lib import format as npformat

        info = self.z.zip.getinfo(f"{key}.npy")
        with self.z.zip.open(info) as fh:
            try:  # numpy parses the header with ast: a damaged one can raise SyntaxError or TokenError too
                version = npformat.read_magic(fh)
                if version == (1, 0):
                    shape, _, dtype = npformat.read_array_header_1_0(fh)
                else:
                    shape, _, dtype = npformat.read_array_header_2_0(fh)
            except (ValueError, SyntaxError, tokenize.TokenError):
                self.fail(f"'{key}' has an unreadable array header")
            header_len = fh.tell()
        if dtype.hasobject:
            self.fail(f"'{key}' holds Python objects")
        nbytes = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
        if nbytes > MAX_ENTRY_BYTES or nbytes != info.file_size - header_len:
            self.fail(f"'{key}' claims {nbytes} bytes of data, the file holds {info.file_size - header_len}")

    def index(self, key: str, shape: tuple, upper: int, what: str) -> np.ndarray:
        a = self.array(key, np.int64, shape)
        if a.size and (a.min() < 0 or a.max() >= upper):
            self.fail(f"'{key}' has {what} indices outside 0..{upper - 1}")
        return a


def _shape_model(c: _Checker, meta: dict) -> ShapeModel:
    kind = meta.get("kind")
    if kind not in ("2d", "3d"):
        c.fail(f"unknown model kind {kind!r}")
    mean = c.array("shape/mean", np.float64, (None, 3))
    n_v = len(mean)
    coef_names, shape_names = tuple(map(str, meta["coef_names"])), tuple(map(str, meta["shape_names"]))
    n_coef, n_shape = len(coef_names), len(shape_names)
    if kind == "2d" and n_shape:
        c.fail("a 2d model has shape units (is its 'kind' wrong?)")
    if kind == "3d" and not n_shape:
        c.fail("a 3d model without shape units (is its 'kind' wrong?)")
    coef_lo = c.array("shape/coef_lo", np.float64, (n_coef,))
    coef_hi = c.array("shape/coef_hi", np.float64, (n_coef,))
    if (coef_lo >= coef_hi).any():
        c.fail("coefficient bounds inverted or empty")
    shape_sd = c.array("shape/shape_sd", np.float64, (n_shape,))
    if (shape_sd <= 0).any():
        c.fail("non-positive shape-unit spreads")
    triangles = c.index("shape/triangles", (None, 3), n_v, "vertex").astype(np.int32)
    return ShapeModel(kind=kind, mean=mean, shape_units=c.array("shape/shape_units", np.float64, (n_shape, n_v, 3)),
                      basis=c.array("shape/basis", np.float64, (n_coef, n_v, 3)), triangles=triangles,
                      landmark_map=c.array("shape/landmark_map", np.float64, (N_LANDMARKS, n_v)),
                      shape_names=shape_names, coef_names=coef_names, coef_lo=coef_lo, coef_hi=coef_hi,
                      shape_sd=shape_sd)


def _texture(c: _Checker, i: int, shp, n_v: int, channels: int) -> Texture:
    h, w = (int(v) for v in shp)
    if not (2 <= h <= 4096 and 2 <= w <= 4096):
        c.fail(f"texture {i} of size {h}x{w}")
    xy = c.array(f"tex{i}/pix_xy", np.int32, (None, 2))
    n = len(xy)
    if n == 0 or xy.min() < 0 or (xy[:, 0] >= w).any() or (xy[:, 1] >= h).any():
        c.fail(f"texture {i} pixels outside its {w}x{h} map")
    vid = c.index(f"tex{i}/pix_vid", (n, 3), n_v, "vertex").astype(np.int32)
    bary = c.array(f"tex{i}/pix_bary", np.float32, (n, 3))
    if np.abs(bary.sum(1) - 1.0).max() > 1e-3:
        c.fail(f"texture {i} barycentric weights do not sum to 1")
    mean = c.array(f"tex{i}/mean", np.float32, (channels * n,))
    app = c.array(f"tex{i}/appearance", np.float32, (channels * n, None))
    return Texture(TextureFrame((h, w), xy, vid, bary), mean, app)


def _couple(c: _Checker, j: int, spec: dict, textures: tuple, n_params: int, prefix: str = "couple") -> Couple:
    name = f"{prefix.replace('_', ' ')} {j}"
    try:
        face_px, t = float(spec["face_px"]), int(spec["texture"])
    except (KeyError, TypeError, ValueError):
        c.fail(f"unreadable {name} settings")
    if not (np.isfinite(face_px) and 4 <= face_px <= 4096):
        c.fail(f"{name} face size {face_px}")
    if not 0 <= t < len(textures):
        c.fail(f"{name} names texture {t} of {len(textures)}")
    D = len(textures[t].mean)
    free = c.index(f"{prefix}{j}/free", (None,), n_params, "parameter")
    n = len(free)
    if n == 0 or len(np.unique(free)) != n:
        c.fail(f"{name} has empty or repeated parameter indices")
    cascade = c.array(f"{prefix}{j}/cascade", np.float32, (None, n, D))
    U = c.array(f"{prefix}{j}/update_matrix", np.float32, (n, None))
    if cascade.shape[0] == 0 and U.shape[1] != D:
        c.fail(f"{name} has neither a cascade nor an update matrix of {D} columns")
    return Couple(face_px, t, free, cascade, c.array(f"{prefix}{j}/cascade_bias", np.float64, (len(cascade), n)),
                  U, c.array(f"{prefix}{j}/prior_step", np.float64, (n, n) if U.shape[1] else (None, None)),
                  c.array(f"{prefix}{j}/prior", np.float64, (n,) if U.shape[1] else (None,)))


def _soft_couples(c: _Checker, specs, couples: tuple, textures: tuple, n_params: int, soft_above: float) -> tuple:
    """The couples for soft faces: none, or one learned cascade for each of ``couples``, at the same face sizes
    and textures (the search swaps one set for the other), read only with the soft landmark cascade's gate."""
    if not specs:
        return ()
    if not isinstance(specs, list) or len(specs) != len(couples):
        c.fail(f"soft couples do not match the model's {len(couples)} couples")
    if not math.isfinite(soft_above):
        c.fail("soft couples without a soft landmark cascade's sharpness gate")
    soft = tuple(_couple(c, j, spec, textures, n_params, "soft_couple") for j, spec in enumerate(specs))
    for j, (a, b) in enumerate(zip(soft, couples, strict=True)):
        if a.face_px != b.face_px or a.texture != b.texture or a.n_stages == 0 or not np.array_equal(a.free, b.free):
            c.fail(f"soft couple {j} differs from couple {j} in face size, texture or parameters, or has no cascade")
    return soft


def load_model(path: str | Path) -> Model:
    """Read and check a model file; raises ModelFileError naming the file and what is wrong."""
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    try:
        with open(path, "rb") as fh:  # our handle: closed on a bad zip too
            problem = npz_problem(fh)
            if problem == "empty file":
                raise ModelFileError(f"{path}: empty file, not an aamtrack model")
            if problem:
                raise ModelFileError(f"{path}: not an aamtrack model ({problem})")
            with np.load(fh, allow_pickle=False) as z:
                if "meta" not in z.files:
                    raise ModelFileError(f"{path}: not an aamtrack model (no 'meta' entry)")
                c = _Checker(path, z)
                meta = _meta(c)
                return _read(c, meta)
    except ModelFileError:
        raise
    except (OSError, ValueError, KeyError, TypeError, IndexError, zipfile.BadZipFile, zlib.error, EOFError,
            MemoryError, OverflowError, NotImplementedError) as exc:  # zipfile: unsupported features
        raise ModelFileError(f"{path}: not a readable aamtrack model ({exc.__class__.__name__}: {exc})") from None


def _meta(c: _Checker) -> dict:
    c._check_header("meta")
    raw = c.z["meta"]
    try:
        if raw.shape != () or raw.dtype.kind != "U":
            raise ValueError
        meta = json.loads(str(raw))
    except (ValueError, TypeError):
        c.fail("unreadable metadata")
    if not isinstance(meta, dict):
        c.fail("metadata is not a JSON object")
    version = meta.get("format_version")
    if type(version) is not int:  # 1.9, "1", true are not versions
        c.fail(f"format_version {version!r} is not an integer")
    if version != FORMAT_VERSION:
        raise ModelFileError(f"{c.path}: model format version {version} is not supported by aamtrack {__version__} "
                             f"(reads version {FORMAT_VERSION}); retrain it with 'aamtrack train'")
    return meta


def _read(c: _Checker, meta: dict) -> Model:
    shape = _shape_model(c, meta)
    f = meta["features"]
    if f.get("kind") not in FEATURE_KINDS:
        c.fail(f"unknown feature kind {f.get('kind')!r}")
    features = Features(kind=f["kind"], lcn_sigma=float(f["lcn_sigma"]), soft=float(f["soft"]), eps=float(f["eps"]),
                        blur=float(f["blur"]))
    if not all(np.isfinite(v) and 0 <= v <= 100 for v in (features.lcn_sigma, features.soft, features.eps,
                                                          features.blur)):
        c.fail("negative or non-finite feature settings")
    textures = tuple(_texture(c, i, shp, shape.n_vertices, features.channels) for i, shp in enumerate(meta["textures"]))
    n_params = shape.n_q + shape.n_shape
    couples = tuple(_couple(c, j, spec, textures, n_params) for j, spec in enumerate(meta["couples"]))
    if not couples:
        c.fail("no couples")
    validator = _validator(c, "validator", meta["validator"])
    box = c.array("detector/box_points", np.float64, (N_LANDMARKS, 2))
    config = meta.get("config", {})
    lc = _landmark_cascade(c, meta.get("landmark_cascade"))
    lv = meta.get("landmark_validator")
    if lv is not None and lc is None:
        c.fail("a landmark validator without a landmark cascade")
    soft, above = _soft_cascade(c, meta.get("soft_landmarks"), lc)
    soft_couples = _soft_couples(c, meta.get("soft_couples"), couples, textures, n_params, above)
    n_z = 0 if lc is None else N_LANDMARKS * lc.basis.shape[2]
    dim, below = _dim_validator(c, meta.get("dim_validator"), lv, n_z)
    sv = meta.get("soft_validator")
    if sv is not None and (lv is None or soft is None):
        c.fail("a validator for soft faces without a landmark validator and a soft landmark cascade")
    dim_cascade = _dim_cascade(c, meta.get("dim_landmarks"), lc, dim)
    shape_prior = _shape_prior(c, meta.get("shape_prior"))
    return Model(shape=shape, features=features, textures=textures, couples=couples, detector_box_points=box,
                 validator=validator, config=config if isinstance(config, dict) else {}, landmark_cascade=lc,
                 landmark_validator=None if lv is None else _validator(c, "landmark_validator", lv, n_z),
                 soft_cascade=soft, soft_above=above, dim_validator=dim, dim_below=below, soft_couples=soft_couples,
                 soft_validator=None if sv is None else _validator(c, "soft_validator", sv, n_z),
                 dim_cascade=dim_cascade, shape_prior=shape_prior)


def _shape_prior(c: _Checker, spec: dict | None) -> ShapePrior | None:
    """The shape prior or None (``mesh.shape_prior.ShapePrior``)."""
    if spec is None:
        return None
    rho = spec.get("residual_variance") if isinstance(spec, dict) else None
    if type(rho) not in (int, float) or not (math.isfinite(rho) and rho > 0):
        c.fail("unreadable shape_prior settings")
    variances = c.array("shape_prior/variances", np.float64, (None,))
    k = len(variances)
    if not (1 <= k < 2 * N_LANDMARKS) or not (variances > 0).all():
        c.fail("the shape prior's variances are not positive")
    return ShapePrior(mean=c.array("shape_prior/mean", np.float64, (N_LANDMARKS, 2)),
                      modes=c.array("shape_prior/modes", np.float64, (k, 2 * N_LANDMARKS)), variances=variances,
                      residual_variance=float(rho))


def _validator(c: _Checker, key: str, spec, n_descriptor: int = 0) -> Validator:
    """The validator stored under ``key`` (``n_descriptor`` > 0: with that many descriptor weights)."""
    if not isinstance(spec, dict) or not isinstance(spec.get("names"), list):
        c.fail(f"unreadable {key} settings")
    names = tuple(map(str, spec["names"]))
    if names != STAT_NAMES:  # the search computes these and no others
        c.fail(f"{key} reads {', '.join(names) or 'nothing'}; this version computes {', '.join(STAT_NAMES)}")
    k = len(names)
    try:
        bias = float(spec["bias"])
    except (KeyError, TypeError, ValueError):
        c.fail(f"unreadable {key} settings")
    v = Validator(names, c.array(f"{key}/weights", np.float64, (k,)), c.array(f"{key}/mean", np.float64, (k,)),
                  c.array(f"{key}/scale", np.float64, (k,)), bias,
                  c.array(f"{key}/descriptor_weights", np.float32, (n_descriptor,)) if n_descriptor else None)
    if (v.scale <= 0).any() or not np.isfinite(v.bias):
        c.fail(f"{key} scale or bias out of range")
    return v


def _dim_validator(c: _Checker, spec: dict | None, lv: dict | None, n_descriptor: int) -> tuple:
    """(validator for dim faces or None, its signal-to-noise threshold)."""
    if spec is None:
        return None, 0.0
    if lv is None:
        c.fail("a validator for dim faces without a landmark validator")
    below = _threshold(c, spec, "below", 0.0, 1e3, "dim_validator")
    return _validator(c, "dim_validator", spec, n_descriptor), below


def _threshold(c: _Checker, spec: dict, key: str, lo: float, hi: float, name: str) -> float:
    """The number ``spec[key]`` of the part ``name``, checked to lie in lo..hi."""
    try:
        value = float(spec[key])
    except (KeyError, TypeError, ValueError):
        c.fail(f"unreadable {name} settings")
    if not lo <= value <= hi:
        c.fail(f"{name} threshold {value} outside {lo:g}..{hi:g}")
    return value


def _landmark_cascade(c: _Checker, spec: dict | None) -> LandmarkCascade | None:
    if spec is None:
        return None
    if not isinstance(spec, dict):
        c.fail("unreadable landmark cascade settings")
    try:
        halves = tuple(float(h) for h in spec["halves"])
        ds = DescriptorSpec(int(spec["cells"]), int(spec["cell"]), int(spec["bins"]), float(spec["floor"]))
        repeats = spec["repeats"]
    except (KeyError, TypeError, ValueError):
        c.fail("unreadable landmark cascade settings")
    if not (all(0 < h <= 2 for h in halves) and 1 <= ds.cells <= 16 and 1 <= ds.cell <= 32 and 2 <= ds.bins <= 64
            and 0 <= ds.floor <= 1e3 and type(repeats) is int and 0 <= repeats <= 8):
        c.fail("landmark cascade settings out of range")
    K = len(halves)
    basis = c.array("landmarks/basis", np.float32, (K, ds.size, None))
    d = basis.shape[2]
    if not 1 <= d <= ds.size:
        c.fail(f"landmark cascade basis of {d} components for descriptors of {ds.size}")
    return LandmarkCascade(c.array("landmarks/ref", np.float64, (N_LANDMARKS, 2)), ds, halves,
                           c.array("landmarks/basis_mean", np.float32, (K, ds.size)), basis,
                           c.array("landmarks/regressors", np.float32, (K, 2 * N_LANDMARKS, N_LANDMARKS * d)),
                           c.array("landmarks/biases", np.float64, (K, 2 * N_LANDMARKS)),
                           c.array("landmarks/shape_regressors", np.float32, (K, 2 * N_LANDMARKS, 2 * N_LANDMARKS)),
                           repeats)


def _soft_cascade(c: _Checker, spec: dict | None, lc: LandmarkCascade | None) -> tuple:
    """(soft cascade or None, its sharpness threshold): the landmark cascade ``lc`` with the soft one's
    regressors."""
    if spec is None:
        return None, math.inf
    if lc is None:
        c.fail("a soft landmark cascade without a landmark cascade")
    above = _threshold(c, spec, "above", 0.0, 1.0, "soft landmark cascade")
    return _cascade_like(c, "soft_landmarks", lc), above


def _cascade_like(c: _Checker, prefix: str, lc: LandmarkCascade, **changes) -> LandmarkCascade:
    """The landmark cascade ``lc`` with the regressors stored under ``prefix`` (a cascade that shares its
    reference shape and descriptor components: the soft and the dim faces' ones), and ``changes``."""
    return replace(lc, regressors=c.array(f"{prefix}/regressors", np.float32, lc.regressors.shape),
                   biases=c.array(f"{prefix}/biases", np.float64, lc.biases.shape),
                   shape_regressors=c.array(f"{prefix}/shape_regressors", np.float32, lc.shape_regressors.shape),
                   **changes)


def _dim_cascade(c: _Checker, spec: dict | None, lc: LandmarkCascade | None, dim: Validator | None):
    """The dim faces' landmark cascade or None: the landmark cascade ``lc`` with its regressors, never repeated."""
    if spec is None:
        return None
    if lc is None or dim is None:
        c.fail("a landmark cascade for dim faces without a landmark cascade and a validator for dim faces")
    return _cascade_like(c, "dim_landmarks", lc, repeats=0)


__all__ = ["FORMAT_VERSION", "N_POSE", "STAT_NAMES", "Couple", "Model", "Texture", "Validator", "load_model", "save_model"]
