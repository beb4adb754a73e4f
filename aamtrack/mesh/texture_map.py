"""The shape-free texture map: the mesh's frontal view rasterised at one resolution, each map pixel tied to
the triangle under it by fixed barycentric weights (so the warp needs no triangle search at run time)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .landmarks import barycentric_map


@dataclass(frozen=True)
class TextureFrame:
    """The shape-free texture map at one resolution.

    shape : (height, width) of the map; pix_xy : (N, 2) int32 map pixel of each texture sample;
    pix_vid : (N, 3) int32 vertices of the triangle under it; pix_bary : (N, 3) float32 its weights.
    """

    shape: tuple
    pix_xy: np.ndarray
    pix_vid: np.ndarray
    pix_bary: np.ndarray

    @property
    def n_pixels(self) -> int:
        return len(self.pix_vid)


def texture_frame(ref2d: np.ndarray, triangles: np.ndarray, width: int) -> TextureFrame:
    """Rasterise the mesh (ref2d (n, 2) in image axes) into a map ``width`` pixels wide (1 pixel margin).
    A pixel covered by several triangles takes the first of them."""
    used = ref2d[np.unique(triangles)]  # vertices outside every triangle (landmark vertices) do not count
    lo = used.min(0)
    scale = (width - 3) / max(np.ptp(used[:, 0]), 1e-9)
    pts = (ref2d - lo) * scale + 1.0
    height = int(np.ceil(pts[np.unique(triangles), 1].max())) + 2
    yy, xx = np.mgrid[0:height, 0:width]
    grid = np.column_stack([xx.ravel(), yy.ravel()]).astype(float)
    W = barycentric_map(grid, pts, triangles)  # extrapolates outside; keep only pixels truly inside
    inside = np.isclose(W.sum(1), 1.0) & (W.min(1) >= -1e-9)
    W = W[inside]
    vid = np.argsort(-np.abs(W), axis=1)[:, :3].astype(np.int32)
    vid.sort(axis=1)
    bary = np.take_along_axis(W, vid, axis=1).astype(np.float32)
    return TextureFrame((height, width), grid[inside].astype(np.int32), vid, bary)
