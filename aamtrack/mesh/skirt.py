"""An outer band of texture for the 3D model: triangles from Candide's outline out past the labelled jaw line.

Candide-3's mesh ends inside the face: the 68-point jaw line lies about a tenth of the face width outside its
outline, so a texture map made of Candide's triangles holds no pixel of the contour (jaw against neck or
background) and the search can place the jaw only from what the inner face implies. The band adds a ring of
vertices, each jaw landmark pushed ``band`` of its distance away from the centroid of the 68 landmarks (linear
in the vertices, so the ring follows pose, shape units and animation units exactly as the landmarks do; the 2D
model's ``train.shape2d.ring_operator`` is the same idea), and a strip of triangles between the part of
Candide's outline below the hairline cut and that ring. The band's triangles are texture only: they join the
texture map, not ``ShapeModel.triangles`` (the mesh that is drawn and exported stays Candide's).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import replace

import numpy as np

from .shape_model import ShapeModel

JAW = tuple(range(17))


def outline_loop(triangles: np.ndarray) -> np.ndarray:
    """Vertex ids of the longest closed boundary loop of a triangle mesh (its outline), in walking order."""
    count = Counter()
    for a, b, c in np.asarray(triangles):
        for u, v in ((a, b), (b, c), (c, a)):
            count[(min(u, v), max(u, v))] += 1
    adj = defaultdict(list)
    for (u, v), n in count.items():
        if n == 1:
            adj[u].append(v)
            adj[v].append(u)
    seen, best = set(), []
    for start in adj:
        if start in seen:
            continue
        loop, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = [w for w in adj[cur] if w != prev and w not in seen]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            loop.append(cur)
            seen.add(cur)
        if len(loop) > len(best):
            best = loop
    return np.array(best, dtype=np.int64)


def _strip(inner: np.ndarray, outer: np.ndarray, t_inner: np.ndarray, t_outer: np.ndarray) -> np.ndarray:
    """Triangles joining two vertex chains ordered by the same parameter (t_inner, t_outer increasing)."""
    tris, i, j = [], 0, 0
    while i < len(inner) - 1 or j < len(outer) - 1:
        if j == len(outer) - 1 or (i < len(inner) - 1 and t_inner[i + 1] <= t_outer[j + 1]):
            tris.append((inner[i], outer[j], inner[i + 1]))
            i += 1
        else:
            tris.append((inner[i], outer[j], outer[j + 1]))
            j += 1
    return np.array(tris, dtype=np.int32)


def with_skirt(sm: ShapeModel, texture_triangles: np.ndarray, band: float, jaw: tuple = JAW
               ) -> tuple[ShapeModel, np.ndarray]:
    """The 3D model with the band's ring vertices appended (in no ``triangles``; landmark map unchanged), and the
    band's triangles (k, 3) int32 for the texture map. ``texture_triangles``: the mesh the band borders (its
    outline's lower part, below the hairline cut, is the strip's inner edge). ``jaw``: the jaw landmarks (a
    contiguous run of 0..16) the ring follows."""
    L = sm.landmark_map
    n_v = sm.n_vertices
    # ring vertex i = (1 + band) l_i - band * mean(l): rows of a linear map from the vertices
    E = (1.0 + band) * L[list(jaw)] - band * L.mean(0, keepdims=True)

    def extend(arr):
        return np.concatenate([arr, np.einsum("rv,kvd->krd", E, arr)], axis=1)

    ring = E @ sm.mean
    lm = L @ sm.mean
    centre = lm.mean(0)
    loop = outline_loop(texture_triangles)
    jaw_top = min(lm[jaw[0], 1], lm[jaw[-1], 1])
    below = loop[sm.mean[loop, 1] <= jaw_top + 0.5 * (sm.mean[loop, 1].max() - jaw_top)]

    def param(xy):  # angle around the centre, 0 straight down, increasing towards +x: monotonic along the jaw
        return np.arctan2(xy[:, 0] - centre[0], -(xy[:, 1] - centre[1]))

    t_in, t_out = param(sm.mean[below]), param(ring)
    o_in, o_out = np.argsort(t_in), np.argsort(t_out)
    tris = _strip(below[o_in], n_v + o_out, t_in[o_in], t_out[o_out])
    out = replace(sm, mean=np.vstack([sm.mean, ring]), shape_units=extend(sm.shape_units), basis=extend(sm.basis),
                  landmark_map=np.hstack([L, np.zeros((68, len(E)))]))
    return out, tris
