"""Synthetic faces for tests: a 68-point face-like layout with a smooth analytic texture, rendered with known
parameters by an independent (slow, numpy) piecewise-affine renderer. Ground truth for every numerical test."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from aamtrack.metrics import PIXEL_ORIGIN


def face_layout() -> np.ndarray:
    """(68, 2) a face-like landmark layout in model units (x right, y up, width about 1)."""
    pts = []
    t = np.linspace(-np.pi * 0.95, -np.pi * 0.05, 17)           # jaw 0..16
    pts += list(np.column_stack([0.5 * np.cos(t[::-1]) * -1, 0.6 * np.sin(t) + 0.1]))
    for cx in (-0.22, 0.22):                                    # brows 17..26
        pts += [[cx + dx, 0.32 + 0.04 * (1 - (dx / 0.14) ** 2)] for dx in np.linspace(-0.14, 0.14, 5)]
    pts += [[0.0, y] for y in np.linspace(0.2, -0.05, 4)]       # nose bridge 27..30
    pts += [[x, -0.1 - 0.02 * (1 - abs(x) / 0.1)] for x in np.linspace(-0.1, 0.1, 5)]  # nostrils 31..35
    for cx in (-0.2, 0.2):                                      # eyes 36..47
        a = np.linspace(0, 2 * np.pi, 7)[:-1]
        pts += list(np.column_stack([cx - 0.08 * np.cos(a), 0.15 + 0.035 * np.sin(a)]))
    a = np.linspace(0, 2 * np.pi, 13)[:-1]                      # outer lip 48..59
    pts += list(np.column_stack([-0.18 * np.cos(a), -0.32 + 0.07 * np.sin(a)]))
    a = np.linspace(0, 2 * np.pi, 9)[:-1]                       # inner lip 60..67
    pts += list(np.column_stack([-0.11 * np.cos(a), -0.32 + 0.03 * np.sin(a)]))
    return np.array(pts, float)


def texture_fn(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Smooth grey texture over model coordinates: skin with fine detail (for the search to lock on to) and
    dark eyes, brows, nostrils and mouth, a bright nose ridge (so OpenCV's Haar face cascade fires on it)."""
    v = 175 + 14 * np.sin(9 * x) * np.cos(7 * y) + 10 * np.cos(17 * x + 6 * y)
    for cx, cy, sx, sy, a in ((-0.2, 0.15, 0.07, 0.03, -120), (0.2, 0.15, 0.07, 0.03, -120),
                              (-0.22, 0.3, 0.1, 0.02, -90), (0.22, 0.3, 0.1, 0.02, -90),
                              (0, -0.32, 0.13, 0.04, -100), (0, 0.02, 0.03, 0.12, 25),
                              (-0.08, -0.1, 0.03, 0.02, -60), (0.08, -0.1, 0.03, 0.02, -60)):
        v += a * np.exp(-((x - cx) ** 2 / (2 * sx * sx) + (y - cy) ** 2 / (2 * sy * sy)))
    return v


def project2d(shape: np.ndarray, rz: float, s: float, tx: float, ty: float) -> np.ndarray:
    """Similarity projection into image axes (y down) of (n, 2) model points."""
    c, n = np.cos(rz), np.sin(rz)
    x = s * (c * shape[:, 0] - n * shape[:, 1]) + tx
    y = -s * (n * shape[:, 0] + c * shape[:, 1]) + ty
    return np.column_stack([x, y])


def render(ref: np.ndarray, pts_img: np.ndarray, size: tuple[int, int], *, background: float = 60.0,
           noise: float = 0.0, rng: np.random.Generator | None = None) -> np.ndarray:
    """(H, W) uint8: the textured face whose model-frame vertices ``ref`` (68, 2) land at ``pts_img``.
    Each pixel inside a triangle takes texture_fn at its barycentric position in ``ref``."""
    W, H = size
    tri = Delaunay(ref).simplices
    yy, xx = np.mgrid[0:H, 0:W]
    P = np.column_stack([xx.ravel(), yy.ravel()]).astype(float)
    img = np.full(len(P), background)
    img += 25 * np.sin(P[:, 0] / 9.0) * np.sin(P[:, 1] / 11.0)  # textured background
    for t in tri:
        a, b, c = pts_img[t]
        v0, v1, v2 = b - a, c - a, P - a
        den = v0[0] * v1[1] - v1[0] * v0[1]
        if abs(den) < 1e-12:
            continue
        w1 = (v2[:, 0] * v1[1] - v1[0] * v2[:, 1]) / den
        w2 = (v0[0] * v2[:, 1] - v2[:, 0] * v0[1]) / den
        w0 = 1 - w1 - w2
        inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
        m = ref[t]
        X = w0 * m[0, 0] + w1 * m[1, 0] + w2 * m[2, 0]
        Y = w0 * m[0, 1] + w1 * m[1, 1] + w2 * m[2, 1]
        img[inside] = texture_fn(X[inside], Y[inside])
    if noise and rng is not None:
        img += rng.normal(0, noise, img.shape)
    return np.clip(img, 0, 255).reshape(H, W).astype(np.uint8)


def random_faces(n: int, rng: np.random.Generator, *, size=(160, 160), scale=90.0, shape_sd=0.015,
                 roll_sd=0.08, shift_sd=6.0) -> tuple[list[np.ndarray], np.ndarray]:
    """n rendered faces with random similarity pose and small smooth shape changes; (images, (n, 68, 2) pts). The
    points are labels in the package's 1-based pixels (``PIXEL_ORIGIN`` added to where the renderer, in OpenCV's
    pixels, put them), as 300-W's are."""
    ref = face_layout()
    images, points = [], []
    for _ in range(n):
        shape = ref + rng.normal(0, shape_sd, (1, 2)) * ref * np.array([1.0, 1.0]) + rng.normal(0, shape_sd / 10, ref.shape)
        pts = project2d(shape, rng.normal(0, roll_sd), scale * np.exp(rng.normal(0, 0.05)),
                        size[0] / 2 + rng.normal(0, shift_sd), size[1] / 2 + rng.normal(0, shift_sd))
        images.append(render(shape, pts, size, noise=2.0, rng=rng))
        points.append(pts + PIXEL_ORIGIN)
    return images, np.array(points)


def moving_face_frames(n: int, *, size=(320, 240), scale=130.0, amplitude=10.0, away=()) -> tuple[list, np.ndarray]:
    """n BGR frames of the mean face moving smoothly (translation up to ``amplitude`` px, roll up to 4 degrees);
    frames whose index is in ``away`` show no face. Returns (frames, (n, 68, 2) true landmarks in the package's 1-based
    pixels, NaN when away)."""
    ref = face_layout()
    frames, truth = [], np.full((n, 68, 2), np.nan)
    for i in range(n):
        if i in away:
            pts = project2d(ref, 0.0, scale, -10 * size[0], -10 * size[1])
        else:
            t = 2 * np.pi * i / max(n, 1)
            pts = project2d(ref, np.radians(4) * np.sin(t), scale * (1 + 0.03 * np.sin(2 * t)),
                            size[0] / 2 + amplitude * np.sin(t), size[1] / 2 + 0.6 * amplitude * np.cos(t))
            truth[i] = pts + PIXEL_ORIGIN
        g = render(ref, pts, size)
        frames.append(np.dstack([g, g, g]))
    return frames, truth


def write_video(path, frames, fps: float = 25.0, fourcc: str = "MJPG") -> None:
    import cv2

    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (w, h))
    assert vw.isOpened()
    for f in frames:
        vw.write(f)
    vw.release()
