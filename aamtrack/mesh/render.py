"""Drawing a textured face mesh at a pose: a weak-perspective view with depth and a painter's rasteriser.

Used by training's face profiling (``aamtrack.train.profile``: training faces turned to new poses) and by the
pose check benchmark (``benchmarks/pose_check.py``: renders at known poses).
"""

from __future__ import annotations

import cv2
import numpy as np

from .shape_model import rotation_matrix


def posed(X: np.ndarray, q) -> tuple[np.ndarray, np.ndarray]:
    """Weak-perspective view of model points X (n, 3) under q = [rx, ry, rz, s, tx, ty, ...]: image points
    (n, 2) (u = s (RX)_x + tx, v = -s (RX)_y + ty) and depth (n,) = (RX)_z (larger is nearer the camera)."""
    RX = X @ rotation_matrix(q[0], q[1], q[2]).T
    uv = np.column_stack([q[3] * RX[:, 0] + q[4], -q[3] * RX[:, 1] + q[5]])
    return uv, RX[:, 2]


def orient_triangles(triangles: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(t, 3) int triangles rewound consistently (every inner edge crossed in opposite directions by its two
    triangles, spread from each connected piece's first triangle), each piece then flipped so that its
    area-weighted normal points towards +z (outward for a face seen from the front) at ``vertices`` (n, 3).
    Candide-3's triangle list is not consistently wound, so culling needs this."""
    from collections import defaultdict, deque

    tri = np.array(triangles, dtype=np.int64)
    by_edge = defaultdict(list)
    for i, (a, b, c) in enumerate(tri):
        for u, v in ((a, b), (b, c), (c, a)):
            by_edge[(min(u, v), max(u, v))].append(i)
    done = np.zeros(len(tri), bool)
    for seed in range(len(tri)):
        if done[seed]:
            continue
        done[seed] = True
        piece, queue = [seed], deque([seed])
        while queue:
            i = queue.popleft()
            a, b, c = tri[i]
            for u, v in ((a, b), (b, c), (c, a)):
                for j in by_edge[(min(u, v), max(u, v))]:
                    if done[j]:
                        continue
                    x, y, z = tri[j]
                    if (u, v) in ((x, y), (y, z), (z, x)):  # same direction: j is wound the other way
                        tri[j] = tri[j][::-1]
                    done[j] = True
                    piece.append(j)
                    queue.append(j)
        t = tri[piece]
        n = np.cross(vertices[t[:, 1]] - vertices[t[:, 0]], vertices[t[:, 2]] - vertices[t[:, 0]])
        if n[:, 2].sum() < 0:
            tri[piece] = t[:, ::-1]
    return tri


def render_mesh(texture: np.ndarray, src_uv: np.ndarray, dst_uv: np.ndarray, depth: np.ndarray, triangles: np.ndarray,
           background: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Painter's rasteriser: each triangle of ``triangles`` (t, 3) is the affine warp of ``texture`` from its
    source corners ``src_uv`` (n, 2) to its destination corners ``dst_uv`` (n, 2), drawn back to front by
    the mean ``depth`` (n,) of its corners (larger is nearer); triangles whose destination is wound clockwise
    on screen (image y down), i.e. facing away for the model's outward-wound mesh, are culled.

    Returns (image like ``background``, (H, W) bool mask of the pixels drawn). Approximation: the visibility
    is per triangle (no z-buffer), exact for a mesh without interpenetrating triangles."""
    out = background.copy()
    H, W = out.shape[:2]
    drawn = np.zeros((H, W), bool)
    tri = np.asarray(triangles)
    a, b, c = dst_uv[tri[:, 0]], dst_uv[tri[:, 1]], dst_uv[tri[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    order = np.argsort(depth[tri].mean(1), kind="stable")
    for t in order:
        if area2[t] >= -1e-9:  # counter-clockwise in model (y up) = clockwise on screen: front faces are < 0
            continue
        d = dst_uv[tri[t]].astype(np.float64)
        x0, y0 = np.floor(d.min(0)).astype(int)
        x1, y1 = np.ceil(d.max(0)).astype(int) + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
        if x1 <= x0 or y1 <= y0:
            continue
        off = np.array([x0, y0], float)
        M = cv2.getAffineTransform(src_uv[tri[t]].astype(np.float32), (d - off).astype(np.float32))
        patch = cv2.warpAffine(texture, M, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        cv2.fillConvexPoly(mask, np.round((d - off) * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
        m = mask.astype(bool)
        out[y0:y1, x0:x1][m] = patch[m]
        drawn[y0:y1, x0:x1] |= m
    return out, drawn
