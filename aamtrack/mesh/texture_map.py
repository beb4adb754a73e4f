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


def texture_frame(ref2d: np.ndarray, triangles: np.ndarray, width: int, *, band: float = 0.0,
                  band_below: float = np.inf) -> TextureFrame:
    """Rasterise the mesh (ref2d (n, 2) in image axes) into a map ``width`` pixels wide (1 pixel margin).
    A pixel covered by several triangles takes the first of them.

    ``band`` > 0 adds the pixels within ``band`` (a share of the mesh width) outside the mesh and below
    ``band_below`` (image-axis y of ref2d), tied to their nearest triangle by extrapolated weights: the face's
    outline (the jaw against neck or background) then lies inside the map.
    """
    lo = ref2d.min(0)
    span = max(np.ptp(ref2d[:, 0]), 1e-9)
    pad = band * span
    scale = (width - 3) / (span + 2 * pad)
    pts = (ref2d - lo + pad) * scale + 1.0
    height = int(np.ceil(pts[:, 1].max() + pad * scale)) + 2
    yy, xx = np.mgrid[0:height, 0:width]
    grid = np.column_stack([xx.ravel(), yy.ravel()]).astype(float)
    W = barycentric_map(grid, pts, triangles)  # extrapolates outside; keep pixels inside (or in the band)
    inside = np.isclose(W.sum(1), 1.0) & (W.min(1) >= -1e-9)
    if band > 0:
        from scipy.ndimage import distance_transform_edt  # training only: keeps 'aamtrack run' start-up short

        dist = distance_transform_edt(~inside.reshape(height, width)).ravel()
        below = (grid[:, 1] - 1.0) / scale + lo[1] - pad > band_below
        inside |= (dist <= band * span * scale) & below
    W = W[inside]
    vid = np.argsort(-np.abs(W), axis=1)[:, :3].astype(np.int32)
    vid.sort(axis=1)
    bary = np.take_along_axis(W, vid, axis=1).astype(np.float32)
    return TextureFrame((height, width), grid[inside].astype(np.int32), vid, bary)


def render_texture(frame: TextureFrame, values: np.ndarray) -> np.ndarray:
    """(height, width) float32 image of texture values (for figures and debugging); NaN off the mask."""
    img = np.full(frame.shape, np.nan, np.float32)
    img[frame.pix_xy[:, 1], frame.pix_xy[:, 0]] = values
    return img
