"""Texture learning (poster step 2): the shape-free texture map, textures warped into it, their photometric
normalisation, the mean texture I_m and an appearance basis.

Appearance model: besides I_m, the leading principal components B (orthonormal) of the normalised training
textures are kept, and the search works on the residual projected off them, e = (I - B B^T)(W(I) - I_m)
("project-out"): lighting and identity changes that B spans do not pull the pose. The update matrices are
learned on that same projected residual, so U annihilates B's span.
"""

from __future__ import annotations

import numpy as np

from .._kernels.warp import _normalize, _project, _warp
from ..mesh.texture_map import TextureFrame


def sample_texture(image: np.ndarray, scale: float, shape3d: np.ndarray, basis: np.ndarray,
                   q: np.ndarray, frame: TextureFrame) -> np.ndarray:
    """(N,) float32 normalised texture of ``image`` (H, W) float32 under parameters q."""
    verts = np.empty((len(shape3d), 2))
    _project(shape3d, basis, q, verts)
    tex = np.empty(frame.n_pixels, dtype=np.float32)
    _warp(image, verts, scale, frame.pix_vid, frame.pix_bary, tex)
    _normalize(tex)
    return tex


def learn_appearance(textures: np.ndarray, *, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean texture (N,) float32 (itself normalised) and appearance basis (N, n_modes) float32, orthonormal,
    from (n_images, N) normalised textures."""
    mean = textures.mean(0).astype(np.float32)
    _normalize(mean)
    if n_modes == 0:
        return mean, np.zeros((len(mean), 0), np.float32)
    _, _, Vt = np.linalg.svd(textures - mean, full_matrices=False)
    return mean, np.ascontiguousarray(Vt[:n_modes].T.astype(np.float32))
