"""A synthetic Candide-like 3D face for tests that need nothing outside the repository: the 68 points of
``synth.face_layout`` lifted onto a curved surface, with a ring of outer vertices, the shape and animation units
the 3D model reads (``aamtrack.mesh.candide_model``) as smooth deterministic displacement fields, and a renderer
of posed faces (the texture follows the projected landmarks, ``synth.render``)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from aamtrack.mesh.candide import Candide
from aamtrack.mesh.candide_model import FRONTAL_SHAPE_UNITS, candide_shape_model
from aamtrack.mesh.landmarks import CANDIDE_ANCHORS, candide_landmark_map
from aamtrack.metrics import PIXEL_ORIGIN
import synth


def _depth(xy: np.ndarray) -> np.ndarray:
    """A head-like bulge: z = 0.35 (1 - x^2 / 0.4) - 0.1 y^2, and a nose ridge."""
    return 0.35 * (1 - xy[:, 0] ** 2 / 0.4) - 0.1 * xy[:, 1] ** 2 + 0.12 * np.exp(-xy[:, 0] ** 2 / 0.004) * (
        (xy[:, 1] > -0.12) & (xy[:, 1] < 0.22))


def _field(xy: np.ndarray, rng: np.random.Generator, amplitude: float) -> np.ndarray:
    """(n, 3) a smooth displacement: one Gaussian bump of random centre and direction."""
    c = rng.uniform([-0.3, -0.4], [0.3, 0.35])
    d = rng.normal(0, 1, 3)
    d *= amplitude / np.linalg.norm(d)
    w = np.exp(-((xy - c) ** 2).sum(1) / (2 * 0.2 ** 2))
    return w[:, None] * d


def synthetic_candide(seed: int = 0) -> Candide:
    rng = np.random.default_rng(seed)
    lm = synth.face_layout()
    a = np.linspace(0, 2 * np.pi, 25)[:-1]
    ring = np.column_stack([0.62 * np.cos(a), 0.75 * np.sin(a) + 0.05])  # forehead, temples, below the chin
    points = np.vstack([lm, ring])
    # the vertices Candide-3 anchors the landmark map on (``CANDIDE_ANCHORS``) hold those landmarks here too
    order = np.full(len(points), -1)
    for i, v in CANDIDE_ANCHORS.items():
        order[v] = i
    order[order < 0] = [i for i in range(len(points)) if i not in CANDIDE_ANCHORS]
    xy = points[order]
    verts = np.column_stack([xy, _depth(xy)])
    tris = Delaunay(xy).simplices.astype(np.int32)
    anim = np.stack([_field(xy, rng, 0.05) for _ in range(15)])
    anim[11] = 0.0
    anim[11, :, 1] = -0.2 * np.clip((-0.25 - xy[:, 1]) / 0.4, 0, 1)  # AUV11 jaw drop: the chin and lower lip go down
    anim_names = tuple(f"AUV{i} synthetic unit {i}" for i in range(15))
    shape = np.stack([_field(xy, rng, 0.04) for _ in FRONTAL_SHAPE_UNITS])
    return Candide(verts, tris, anim, anim_names, shape, FRONTAL_SHAPE_UNITS)


def shape_model(candide: Candide):
    """The 3D ShapeModel of the synthetic Candide, landmarks on their own vertices."""
    return candide_shape_model(candide, candide_landmark_map(candide.vertices, candide.triangles,
                                                             synth.face_layout() * np.array([1.0, -1.0])))


def posed_faces(candide: Candide, n: int, rng: np.random.Generator, *, size=(220, 220), scale=130.0,
                yaw_sd=0.15, pitch_sd=0.1, shape_sd=0.7, observable=None):
    """n faces rendered from the synthetic 3D face with random pose (yaw, pitch, roll, scale, position) and shape
    units: (images, (n, 68, 2) landmarks (labels, in the package's 1-based pixels), (n, n_q) poses (the model's own
    OpenCV pixels, as a search returns them), (n, n_shape) shape units)."""
    sm = shape_model(candide)
    names = list(sm.shape_names)
    units = range(sm.n_shape) if observable is None else [names.index(u) for u in observable]
    images, points, qs, sigmas = [], [], [], []
    for _ in range(n):
        sigma = np.zeros(sm.n_shape)
        for j in units:
            sigma[j] = rng.normal(0, shape_sd)
        q = np.zeros(sm.n_q)
        q[:6] = (rng.normal(0, pitch_sd), rng.normal(0, yaw_sd), rng.normal(0, 0.05), scale * np.exp(rng.normal(0, 0.05)),
                 size[0] / 2 + rng.normal(0, 4), size[1] / 2 + rng.normal(0, 4))
        pts = sm.landmarks(q, sigma)
        images.append(synth.render(synth.face_layout(), pts, size, noise=2.0, rng=rng))
        points.append(pts + PIXEL_ORIGIN)
        qs.append(q)
        sigmas.append(sigma)
    return images, np.array(points), np.array(qs), np.array(sigmas)
