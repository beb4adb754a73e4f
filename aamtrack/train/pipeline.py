"""Offline learning end to end: shape model and per-image fits, texture maps, mean textures and appearance
bases, and one update matrix per couple. Library code: progress goes through the ``progress`` wrapper the
caller hands in (the CLI passes tqdm), messages through ``logging``."""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Iterable

import numpy as np

from .._kernels.warp import _accumulate_gradient
from ..mesh.candide import Candide
from ..mesh.candide_model import candide_shape_model
from ..mesh.landmarks import N_CANDIDE_SKIN_TRIANGLES, candide_landmark_map, refine_landmark_map
from ..mesh.shape_model import N_POSE, ShapeModel
from ..model import Couple, Model, Texture
from ..track.pyramid import Octaves, octave_factor, to_gray32
from ..track.detector import calibrate_detector
from .shape2d import pca_shape_model, procrustes_mean
from .shape_fit import ShapeFit, fit_landmarks
from ..mesh.texture_map import texture_frame
from .texture import learn_appearance, sample_texture
from .update import perturbation_steps, prior_weights, update_matrix

log = logging.getLogger(__name__)

Progress = Callable[..., Iterable]


def _no_progress(iterable, **_):
    return iterable


@dataclass(frozen=True)
class TrainConfig:
    """couples: ((face_px, texture_width), ...) coarse to fine; a couple is valid only when its texture is no
    wider than the face at its image resolution (face_px, see ``track.pyramid``).
    n_appearance: appearance modes projected out.
    pose_only_couples: how many of the coarsest couples search the pose only (shape is left to finer ones).
    lcn_sigma: local contrast normalisation of each couple's image (pixels; 0 = off). On helen_test it took
    the displaced-start search from mean NME 0.080 to 0.065 (2D model, 150 training images).
    ring: 2D only, an outer ring of vertices this far beyond the outline (``shape2d.ring_operator``). At 0.12
    it improved helen_test stills (0.065 -> 0.055) but drifted on video (cap12 0.056 -> 0.15: the ring locks
    onto the static background), so it is off by default.
    prior: Gaussian prior on the coefficients in the search, as the mean squared residual that a coefficient
    one prior spread from 0 costs (``update.prior_weights``); without it the coefficients of the 2D model
    ran to their bounds on video, fitting texture with shape. On cap12 (2D model) the mean NME went
    0.056 -> 0.043 (0.003) -> 0.042 with no frame above 0.10 (0.01); helen_test displaced-start stills
    0.065 -> 0.064 -> 0.070 (a stronger prior trades some capture range).
    forehead_cut: 3D only, texture triangles whose centre is above this model y (hairline) are left out."""

    couples: tuple = ((32, 20), (64, 32), (128, 48))
    n_appearance: int = 8
    pose_only_couples: int = 2
    lcn_sigma: float = 8.0
    ring: float = 0.0
    prior: float = 0.01
    map_refine_rounds: int = 2
    map_refine_images: int = 300
    forehead_cut: float = 0.55

    def __post_init__(self):
        for face_px, tex in self.couples:
            if tex > face_px:
                raise ValueError(f"couple ({face_px}, {tex}): texture finer than the face's pixels")


@dataclass(frozen=True)
class TrainReport:
    """Per-image landmark fit residuals in pixels (the sigma-learning fit), and timings in seconds."""

    names: tuple
    fit_rms_px: np.ndarray
    timings: dict = field(default_factory=dict)


def _model_residuals(sm: ShapeModel, fits: list[ShapeFit], points: np.ndarray) -> np.ndarray:
    """(n, 68, 2) annotated minus fitted landmarks in model units and axes (scale and roll undone)."""
    out = np.empty((len(fits), 68, 2))
    for i, f in enumerate(fits):
        d = points[i] - sm.landmarks(f.q, f.shape_params)
        d[:, 1] = -d[:, 1]
        c, s = np.cos(f.q[2]), np.sin(f.q[2])
        out[i, :, 0] = (c * d[:, 0] + s * d[:, 1]) / f.q[3]
        out[i, :, 1] = (-s * d[:, 0] + c * d[:, 1]) / f.q[3]
    return out


def learn_shape(points: np.ndarray, kind: str, *, candide: Candide | None, config: TrainConfig,
                progress: Progress = _no_progress) -> tuple[ShapeModel, list[ShapeFit]]:
    """The shape model and each image's fit (pose, sigma, coefficients)."""
    if kind == "2d":
        sm = pca_shape_model(points, ring=config.ring)
        return sm, [fit_landmarks(sm, p) for p in progress(points, desc="fit shapes", unit="img")]
    if candide is None:
        raise ValueError("the 3D model needs the Candide mesh")
    mean68, _ = procrustes_mean(points)
    sm = candide_shape_model(candide, candide_landmark_map(candide.vertices, candide.triangles, mean68))
    rng = np.random.default_rng(0)
    sub = rng.permutation(len(points))[: config.map_refine_images]
    for r in range(config.map_refine_rounds):
        fits = [fit_landmarks(sm, points[i]) for i in progress(sub, desc=f"place landmarks {r + 1}", unit="img")]
        lm = refine_landmark_map(sm.landmark_map, sm.mean, sm.triangles,
                                 _model_residuals(sm, fits, points[sub]), n_preferred=N_CANDIDE_SKIN_TRIANGLES)
        sm = ShapeModel(**{**sm.__dict__, "landmark_map": lm})
    fits = [fit_landmarks(sm, p) for p in progress(points, desc="fit shapes", unit="img")]
    sigma = np.array([f.shape_params for f in fits])
    # The training set's average person becomes the mean shape; sigma's prior spread is the set's spread.
    mean = sm.neutral(sigma.mean(0))
    sm = ShapeModel(**{**sm.__dict__, "mean": mean, "shape_sd": np.maximum(sigma.std(0), 0.05)})
    fits = [ShapeFit(f.q, f.shape_params - sigma.mean(0), f.rms_px) for f in fits]
    return sm, fits


def texture_triangles(sm: ShapeModel, config: TrainConfig) -> np.ndarray:
    """Triangles of the texture map: 3D leaves out the hairline band of the forehead."""
    if sm.kind != "3d":
        return sm.triangles
    centre_y = sm.mean[sm.triangles][:, :, 1].mean(1)
    return sm.triangles[centre_y < config.forehead_cut]


def _person_couple(images, fits, sm: ShapeModel, textures, config: TrainConfig, progress) -> Couple:
    """Update matrix of the finest couple over pose, coefficients and sigma (``ShapeModel.person_view``)."""
    basis, free, _, _ = sm.person_view()
    steps = perturbation_steps(sm, person=True)
    face_px = config.couples[-1][0]
    t = textures[-1]
    mean = np.ascontiguousarray(sm.mean)
    G = np.zeros((t.frame.n_pixels, len(free)))
    e0 = np.empty(t.frame.n_pixels)
    width = sm.frontal_width()
    for i in progress(range(len(images)), desc="person update matrix", unit="img"):
        r = octave_factor(fits[i].q[3] * width, face_px)
        q_ext = np.r_[fits[i].q, fits[i].shape_params]
        _accumulate_gradient(Octaves(to_gray32(images[i]), config.lcn_sigma).get(r), r, mean, basis, q_ext, free,
                             steps, t.mean, t.appearance, t.frame.pix_vid, t.frame.pix_bary, G, e0)
    U, prior_step = update_matrix(G / len(images), prior := prior_weights(sm, free, t.frame.n_pixels,
                                                                          config.prior))
    return Couple(float(face_px), len(textures) - 1, U, free, prior_step, prior)


def _residual_levels(images, fits, sm, textures, couples, config, *, n_images: int = 200,
                     shift: float = 0.25) -> tuple[float, float]:
    """Median RMS residual of the finest couple at the true fits (a good fit) and with the pose moved by
    ``shift`` of the face width (a lost track): the ends of the confidence scale."""
    from ..model import Model
    from ..track.search import Searcher

    searcher = Searcher(Model(sm, tuple(textures), tuple(couples), {"lcn_sigma": config.lcn_sigma}))
    rng = np.random.default_rng(1)
    good, bad = [], []
    for i in rng.permutation(len(images))[:n_images]:
        lv = searcher.levels(images[i])
        q = fits[i].q
        good.append(searcher.residual(lv, q, fits[i].shape_params))
        qb = q.copy()
        ang = rng.uniform(0, 2 * np.pi)
        qb[4:6] += shift * q[3] * sm.frontal_width() * np.array([np.cos(ang), np.sin(ang)])
        bad.append(searcher.residual(lv, qb, fits[i].shape_params))
    return float(np.median(good)), float(np.median(bad))


def train_model(images: list[np.ndarray], points: np.ndarray, kind: str, *, candide: Candide | None = None,
                config: TrainConfig = TrainConfig(), names: tuple = (),
                progress: Progress = _no_progress) -> tuple[Model, TrainReport]:
    """Train a model from grey or BGR images and their (n, 68, 2) landmarks."""
    t0 = time.perf_counter()
    sm, fits = learn_shape(points, kind, candide=candide, config=config, progress=progress)
    t_shape = time.perf_counter() - t0
    log.info("shape fits: mean RMS %.2f px", np.mean([f.rms_px for f in fits]))
    ref2d = sm.mean[:, :2] * np.array([1.0, -1.0])
    tris = texture_triangles(sm, config)
    width = sm.frontal_width()
    steps = perturbation_steps(sm)
    free = sm.free
    basis = np.ascontiguousarray(sm.basis)
    couple_data = []
    for face_px, tex_w in config.couples:
        frame = texture_frame(ref2d, tris, tex_w)
        couple_data.append([face_px, frame, []])
    neutral = [np.ascontiguousarray(sm.neutral(f.shape_params)) for f in fits]

    def couple_images(i):
        """(image at the couple's training octave, its factor, texture frame, q) per couple (see
        ``track.pyramid``: training learns at the octave, tracking runs at exactly face_px)."""
        lv = Octaves(to_gray32(images[i]), config.lcn_sigma)
        for face_px, frame, _ in couple_data:
            r = octave_factor(fits[i].q[3] * width, face_px)
            yield lv.get(r), r, frame, fits[i].q

    for i in progress(range(len(images)), desc="textures", unit="img"):
        for (img, r, frame, q), cd in zip(couple_images(i), couple_data):
            cd[2].append(sample_texture(img, r, neutral[i], basis, q, frame))
    textures = []
    for face_px, frame, tex in couple_data:
        mean, app = learn_appearance(np.array(tex), n_modes=config.n_appearance)
        textures.append(Texture(frame, mean, app))
    t_tex = time.perf_counter() - t0 - t_shape
    grads = [np.zeros((t.frame.n_pixels, len(free))) for t in textures]
    for i in progress(range(len(images)), desc="update matrices", unit="img"):
        for (img, r, frame, q), t, G in zip(couple_images(i), textures, grads):
            e0 = np.empty(frame.n_pixels)
            _accumulate_gradient(img, r, neutral[i], basis, q, free, steps, t.mean, t.appearance,
                                 frame.pix_vid, frame.pix_bary, G, e0)
    couples = []
    n_pose = int(np.sum(free < N_POSE))
    for k, (cd, G) in enumerate(zip(couple_data, grads)):
        cols = np.arange(n_pose) if k < config.pose_only_couples else np.arange(len(free))
        prior = prior_weights(sm, free[cols], G.shape[0], config.prior)
        U, prior_step = update_matrix(G[:, cols] / len(images), prior)
        couples.append(Couple(float(cd[0]), k, U, free[cols].copy(), prior_step, prior))
    couples = tuple(couples)
    person = _person_couple(images, fits, sm, textures, config, progress) if sm.n_shape else None
    t_upd = time.perf_counter() - t0 - t_shape - t_tex
    box_points, n_detected = calibrate_detector(images, points)
    log.info("Haar detector found %d of %d training faces", n_detected, len(images))
    good, bad = _residual_levels(images, fits, sm, textures, couples, config)
    timings = {"shape_s": t_shape, "texture_s": t_tex, "update_s": t_upd,
               "calibration_s": time.perf_counter() - t0 - t_shape - t_tex - t_upd}
    cfg = {**asdict(config), "n_images": len(images), "kind": kind, "residual_good": good, "residual_bad": bad,
           "detector_box_points": box_points.round(5).tolist(), "detector_images": n_detected}
    model = Model(shape=sm, textures=tuple(textures), couples=couples, config=cfg, person=person)
    return model, TrainReport(tuple(names), np.array([f.rms_px for f in fits]), timings)
