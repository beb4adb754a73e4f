"""Texture learning (poster step 2): the shape-free texture map, feature textures warped into it, the mean
texture I_m and an appearance basis.

Appearance model: besides I_m, the leading principal components B (orthonormal) of the training textures are
kept, and the search works on the residual projected off them, e = (I - B B^T)(T - I_m) ("project-out"):
lighting and identity changes that B spans do not pull the pose. Update matrices and cascades are learned on
that same projected residual.
"""

from __future__ import annotations

import numpy as np

from ..kernels import normalize, texture
from ..mesh.texture_map import TextureFrame


def sample_texture(image: np.ndarray, scale: float, shift: float, shape3d: np.ndarray, basis: np.ndarray,
                   p: np.ndarray, frame: TextureFrame, mode: int) -> np.ndarray:
    """(C * N,) float32 finished texture of a feature image (C, H, W) float32, resampled by (scale, shift), under
    the search vector p."""
    tex = np.empty(image.shape[0] * frame.n_pixels, dtype=np.float32)
    return texture(image, scale, shift, shape3d, basis, p, frame.pix_vid, frame.pix_bary, mode,
                   np.empty((len(shape3d), 2)), tex)


def learn_appearance(textures: np.ndarray, *, n_modes: int, mode: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean texture (D,) float32 (z-normalised itself for grey levels, mode 0) and appearance basis (D, n_modes)
    float32, orthonormal, from (n_images, D) finished textures."""
    mean = textures.mean(0).astype(np.float32)
    if mode == 0:
        normalize(mean)
    if n_modes == 0:
        return mean, np.zeros((len(mean), 0), np.float32)
    _, _, Vt = np.linalg.svd(textures - mean, full_matrices=False)
    return mean, np.ascontiguousarray(Vt[:n_modes].T.astype(np.float32))
