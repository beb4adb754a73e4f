"""Face profiling: training faces turned to new head poses, so the 3D model's update cascades learn from a
spread of yaw and pitch the labelled photos do not have (in the spirit of Zhu et al., "Face alignment across
large poses: a 3D solution", CVPR 2016, whose 300W-LP set is 300-W turned by rendering).

A fitted training face becomes the texture of the model's mesh at its fit; the mesh is drawn at a new yaw and
pitch (roll, scale, translation, expression and the person's shape kept) by the painter's rasteriser of
``aamtrack.mesh.render``, over the photo whose own face region is first replaced by a heavy blur of it (so no
second set of eyes shows beside the turned face). The new search vector is known exactly, and its landmarks
are the model's.

Approximations, said plainly: texture the source photo does not show (the far cheek of a turned source) is
stretched from what it does show; the face's border is a hard cut against blurred surroundings; hair, ears and
neck stay at the source pose. The renders are therefore used to learn the update cascades only, never the mean
texture or the appearance modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..mesh.render import orient_triangles, posed, render_mesh
from ..mesh.shape_model import ShapeModel


@dataclass(frozen=True)
class ProfileSpread:
    """Target poses, degrees: yaw uniform in [-yaw, yaw] and pitch in [-pitch, pitch], each at most ``max_turn``
    away from the source's own angle (a larger turn shows too much texture the source hides)."""

    yaw: float = 50.0
    pitch: float = 25.0
    max_turn: float = 40.0


TURNED_YAW = (60.0, 80.0)  # degrees: ``turned_start``'s turns (either way)
TURNED_READ = (35.0, 50.0)  # degrees: the yaw its fits start at


def _target_angle(src: float, limit: float, max_turn: float, rng: np.random.Generator) -> float:
    lo, hi = max(-limit, src - max_turn), min(limit, src + max_turn)
    return float(rng.uniform(lo, hi)) if hi > lo else float(src)


def profile_face(image: np.ndarray, p: np.ndarray, sm: ShapeModel, rx: float, ry: float,
                 triangles: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One face of ``image`` (grey or BGR) fitted at search vector p (pose, coefficients, shape units) drawn at
    pitch rx and yaw ry (radians). Returns (image like the input, the new search vector, its (68, 2)
    landmarks)."""
    n_q = sm.n_q
    q_src, sigma = p[:n_q], p[n_q:]
    triangles = orient_triangles(sm.triangles, sm.mean) if triangles is None else triangles
    src_uv, _ = posed(sm.shape3d(q_src, sigma), q_src)
    q_new = np.array(q_src, float)
    q_new[0], q_new[1] = rx, ry
    dst_uv, depth = posed(sm.shape3d(q_new, sigma), q_new)

    H, W = image.shape[:2]
    mask = np.zeros((H, W), np.uint8)
    cv2.fillConvexPoly(mask, np.round(cv2.convexHull(src_uv.astype(np.float32))[:, 0]).astype(np.int32), 1)
    face_w = float(np.ptp(src_uv[:, 0]))
    mask = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)),
                      iterations=max(1, int(0.02 * face_w)))
    blurred = cv2.GaussianBlur(image, (0, 0), max(1.0, face_w / 6.0))
    inside = mask.astype(bool)
    background = image.copy()
    background[inside] = blurred[inside]
    out, _ = render_mesh(image, src_uv, dst_uv, depth, triangles, background)
    return out, np.r_[q_new, sigma], sm.landmark_map @ dst_uv


def profile_faces(images: list, P: np.ndarray, sm: ShapeModel, share: float, *, rng: np.random.Generator,
                  spread: ProfileSpread = ProfileSpread()) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """Turned copies of a random ``share`` of the fitted faces (``images[i]`` fitted at P[i]). Returns (images,
    search vectors (m, n_params), landmarks (m, 68, 2), index of each copy's source)."""
    if sm.kind != "3d":
        raise ValueError("face profiling needs the 3D model (the 2D model has no depth to turn)")
    pick = np.sort(rng.permutation(len(images))[:int(round(share * len(images)))])
    tri = orient_triangles(sm.triangles, sm.mean)
    out, P_out, pts_out = [], [], []
    for i in pick:
        rx = np.radians(_target_angle(np.degrees(P[i, 0]), spread.pitch, spread.max_turn, rng))
        ry = np.radians(_target_angle(np.degrees(P[i, 1]), spread.yaw, spread.max_turn, rng))
        img, p, pts = profile_face(images[i], P[i], sm, rx, ry, tri)
        out.append(img)
        P_out.append(p)
        pts_out.append(pts)
    n_p = P.shape[1]
    return out, np.array(P_out).reshape(-1, n_p), np.array(pts_out).reshape(-1, 68, 2), pick


def turned_start(image: np.ndarray, p: np.ndarray, sm: ShapeModel, rng: np.random.Generator,
                 triangles: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A face turned past what the model fits, and where a tracker's search of it would start: the face of
    ``image`` fitted at p drawn at a yaw of ``TURNED_YAW`` degrees either way (its pitch kept), and its true search
    vector with the yaw read at ``TURNED_READ`` degrees the same way (the 3D model's search stops turning near 45
    degrees while the head turns on: ``benchmarks/pose_check.py --sweep``). Returns (image, start, the turned
    face's (68, 2) landmarks). For the landmark validator's hard negatives (``TrainConfig.validator_turned``)."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    yaw, read = (sign * np.radians(rng.uniform(*r)) for r in (TURNED_YAW, TURNED_READ))
    img, q, truth = profile_face(image, p, sm, float(p[0]), yaw, triangles)
    start = q.copy()
    start[1] = read
    return img, start, truth
