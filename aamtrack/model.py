"""The trained model: shape model, texture maps with their mean textures and appearance bases, and one update
matrix per couple (image resolution x texture resolution); saved as one versioned ``.npz``.

File layout (``np.savez_compressed``, read with ``allow_pickle=False``): ``meta`` is a JSON string with
``format_version``, the package version, the model kind, names and the training configuration; arrays are
``shape/*``, ``tex{i}/*`` and ``couple{j}/U``.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .errors import ModelFileError
from .io.atomic import atomic_write
from .mesh.shape_model import ShapeModel
from .mesh.texture_map import TextureFrame

FORMAT_VERSION = 1


@dataclass(frozen=True)
class Texture:
    """One texture resolution: its map, mean texture (N,) float32 and appearance basis (N, m) float32."""

    frame: TextureFrame
    mean: np.ndarray
    appearance: np.ndarray


@dataclass(frozen=True)
class Couple:
    """One couple: runs on the image resampled so the face is ``face_px`` wide, on texture ``texture``, with
    update matrix U (n_free, N) float32 (delta = U e) for the parameters ``free`` (n_free,) int64 of q
    (coarse couples may search the pose only); prior_step (n_free, n_free) and prior (n_free,) carry the
    Gaussian prior on the coefficients (see ``aamtrack.train.update.update_matrix``)."""

    face_px: float
    texture: int
    U: np.ndarray
    free: np.ndarray
    prior_step: np.ndarray
    prior: np.ndarray


@dataclass(frozen=True)
class Model:
    """A trained AAM. Couples are ordered coarse to fine. ``person`` (3D only) is a couple whose update matrix
    also moves the shape units sigma (``ShapeModel.person_view``): the tracker runs it in the first good frames
    of a video to estimate the person's sigma, which it then holds."""

    shape: ShapeModel
    textures: tuple
    couples: tuple
    config: dict = field(default_factory=dict)
    person: Couple | None = None

    @property
    def kind(self) -> str:
        return self.shape.kind

    @property
    def face_width_units(self) -> float:
        return self.shape.frontal_width()


_SHAPE_ARRAYS = ("mean", "shape_units", "basis", "triangles", "landmark_map", "coef_lo", "coef_hi", "shape_sd")


def save_model(model: Model, path: str | Path) -> None:
    """Write the model atomically (temporary name, renamed when complete)."""
    arrays = {f"shape/{k}": np.asarray(getattr(model.shape, k)) for k in _SHAPE_ARRAYS}
    for i, t in enumerate(model.textures):
        arrays[f"tex{i}/pix_xy"] = t.frame.pix_xy
        arrays[f"tex{i}/pix_vid"] = t.frame.pix_vid
        arrays[f"tex{i}/pix_bary"] = t.frame.pix_bary
        arrays[f"tex{i}/mean"] = t.mean
        arrays[f"tex{i}/appearance"] = t.appearance
    for j, c in enumerate(model.couples):
        for k in ("U", "free", "prior_step", "prior"):
            arrays[f"couple{j}/{k}"] = getattr(c, k)
    if model.person is not None:
        for k in ("U", "free", "prior_step", "prior"):
            arrays[f"person/{k}"] = getattr(model.person, k)
    meta = {
        "format_version": FORMAT_VERSION,
        "aamtrack_version": __version__,
        "kind": model.shape.kind,
        "shape_names": list(model.shape.shape_names),
        "coef_names": list(model.shape.coef_names),
        "textures": [list(t.frame.shape) for t in model.textures],
        "couples": [{"face_px": c.face_px, "texture": c.texture} for c in model.couples],
        "config": model.config,
        "person": None if model.person is None else {"face_px": model.person.face_px,
                                                     "texture": model.person.texture},
    }
    arrays["meta"] = np.array(json.dumps(meta))
    with atomic_write(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _couple(data: dict, key: str, spec: dict) -> Couple:
    return Couple(float(spec["face_px"]), int(spec["texture"]), data[f"{key}/U"],
                  data[f"{key}/free"].astype(np.int64), data[f"{key}/prior_step"], data[f"{key}/prior"])


def load_model(path: str | Path) -> Model:
    """Read a model file; raises ModelFileError naming the file and what is wrong."""
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ModelFileError(f"{path}: not a readable aamtrack model ({exc.__class__.__name__}: {exc})")
    if "meta" not in data:
        raise ModelFileError(f"{path}: not an aamtrack model (no 'meta' entry)")
    try:
        meta = json.loads(str(data["meta"]))
        version = int(meta["format_version"])
    except (ValueError, KeyError, TypeError):
        raise ModelFileError(f"{path}: corrupt model metadata")
    if version != FORMAT_VERSION:
        raise ModelFileError(f"{path}: model format version {version} is not supported by aamtrack {__version__} "
                             f"(reads version {FORMAT_VERSION}); retrain it with 'aamtrack train'")
    try:
        shape = ShapeModel(kind=meta["kind"], shape_names=tuple(meta["shape_names"]),
                           coef_names=tuple(meta["coef_names"]),
                           **{k: data[f"shape/{k}"] for k in _SHAPE_ARRAYS})
        textures = tuple(
            Texture(TextureFrame(tuple(shp), data[f"tex{i}/pix_xy"], data[f"tex{i}/pix_vid"],
                                 data[f"tex{i}/pix_bary"]), data[f"tex{i}/mean"], data[f"tex{i}/appearance"])
            for i, shp in enumerate(meta["textures"]))
        couples = tuple(_couple(data, f"couple{j}", c) for j, c in enumerate(meta["couples"]))
        pm = meta.get("person")
        person = None if pm is None else _couple(data, "person", pm)
    except KeyError as exc:
        raise ModelFileError(f"{path}: corrupt model, missing {exc}")
    n_ext = shape.n_q + shape.n_shape
    for c in couples + ((person,) if person is not None else ()):
        n_pix = textures[c.texture].frame.n_pixels
        if (c.U.shape != (len(c.free), n_pix) or c.prior_step.shape != (len(c.free),) * 2
                or c.prior.shape != (len(c.free),) or c.free.max() >= n_ext):
            raise ModelFileError(f"{path}: corrupt model, update matrix of shape {c.U.shape}, "
                                 f"expected {(len(c.free), n_pix)}")
    return Model(shape=shape, textures=textures, couples=couples, config=meta.get("config", {}), person=person)
