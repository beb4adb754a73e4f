"""What the couples see of an image: its resolution (relative to the face) and its features.

Shared by training and tracking, so it sits below both (``train`` and ``track`` import it; it imports only
``_kernels``). Feature images (``Features``): grey levels with local contrast normalisation (one channel), or
edge-structure gradient orientations (two channels, ``aamtrack._kernels.features``).

Resolutions for the couples (image resolution x texture resolution), defined relative to the face.

When tracking, a couple with ``face_px = F`` runs on the image resampled (area interpolation) by
r = min(1, F / face_px), so the face is F pixels wide there whatever its size in the frame (never upsampled: a
smaller face is used as it is), and the contrast normalisation and texture sampling see every face at the same
pixel scale. (With dyadic octaves for tracking too, a 240-pixel face and a 120-pixel face ran the finest couple
at scales 2x apart, and cap12 upscaled to 640x480 lost 5 frames, 40 above NME 0.10; now none.) Training learns
each couple on dyadic octaves instead (``aamtrack.train.octaves``), which measured better.

``cv2.resize`` maps a source coordinate x to ``r * x + (0.5 * r - 0.5)``: the kernels sample a level at
``scale * x + shift`` and take ``shift = level_shift(r)``.
"""

from __future__ import annotations

import math

from dataclasses import dataclass

import cv2
import numpy as np

from ._kernels.features import gradient_features
from ._kernels.resample import _resize_area

FEATURE_KINDS = ("intensity", "gradient")


@dataclass(frozen=True)
class Features:
    """The feature image of a resampled grey image, channel-major (C, H, W) float32.

    kind : "intensity" (C = 1: grey levels, local contrast normalised over ``lcn_sigma`` pixels, 0 = none; the
        warped texture is then z-normalised) or "gradient" (C = 2: edge-structure gradient orientations,
        damped by ``soft`` * mean |g| + ``eps`` grey levels; turned into the face's axes after warping).
    blur : Gaussian sigma (pixels of the level) applied to the gradient channels: the texture map samples the
        level every 1.5 to 3 pixels, and pooling the orientations over about that span (as HOG's cells do)
        keeps the samples from aliasing.
    """

    kind: str = "gradient"
    lcn_sigma: float = 8.0
    soft: float = 1.0
    eps: float = 1.0
    blur: float = 0.0

    def __post_init__(self):
        if self.kind not in FEATURE_KINDS:
            raise ValueError(f"unknown feature kind {self.kind!r} (known: {', '.join(FEATURE_KINDS)})")

    @property
    def channels(self) -> int:
        return 1 if self.kind == "intensity" else 2

    @property
    def mode(self) -> int:
        """The kernels' texture mode (``aamtrack._kernels.warp._finish_texture``)."""
        return 0 if self.kind == "intensity" else 1

    def __call__(self, img: np.ndarray) -> np.ndarray:
        if self.kind == "intensity":
            out = local_contrast(img, self.lcn_sigma) if self.lcn_sigma > 0 else img
            return np.ascontiguousarray(out, dtype=np.float32)[None]
        out = gradient_features(img, soft=self.soft, eps=self.eps)
        if self.blur > 0:
            for ch in out:
                cv2.GaussianBlur(ch, (0, 0), self.blur, dst=ch, borderType=cv2.BORDER_REPLICATE)
        return out


def to_gray32(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 grey image from a BGR/grey uint8 or float image."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(image, dtype=np.float32)


def crop_gray32(image: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """``to_gray32(image[y0:y1, x0:x1])``, the same bits. A colour crop is copied into one block first: OpenCV
    converts a crop of a frame (rows not contiguous) several times slower per pixel than a contiguous image, and
    the copy is a plain memcpy of its rows. Measured 2026-12-01 (Intel Xeon VM, one thread, the freed memory kept
    as ``aamtrack run`` and ``bench`` keep it, medians over 60 cap12 frames cycled): a tracked 640x480 frame's crop
    (256 x 281) 88 -> 47 us; crops of 0.15-0.6 of the frame's width at 640x480, 1280x720 and 1920x1080 10-42%
    faster, whole frames the same. (Before, crops at least a third of the frame's width were converted as
    their band of whole rows, then cut: 88 us there.)"""
    crop = image[y0:y1, x0:x1]
    return to_gray32(np.ascontiguousarray(crop) if crop.ndim == 3 else crop)


def grey_u8(image: np.ndarray) -> np.ndarray:
    """A grey, BGR or BGRA frame as grey levels of its own dtype (a grey frame as it is): what ``thumbnail`` and
    ``frame_structure`` read."""
    if image.ndim == 2:
        return image
    return cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY)


THUMBNAIL_SIZE = (32, 24)


def thumbnail(image: np.ndarray) -> np.ndarray:
    """(24, 32) float32 grey thumbnail of a BGR/grey frame, zero mean and unit norm (all zeros for a uniform
    frame), so that the sum of two thumbnails' product is their correlation (``Tracker.track``'s shot-change
    test). The frame is subsampled to about 64 px on its short side (a strided view), then area-resized: about
    0.05 ms at any frame size on one core; area resizing of the whole frame would take 0.2 ms at 640x480."""
    H, W = image.shape[:2]
    step = max(1, min(H, W) // 64)
    # grey per pixel before resizing: a grey frame and its BGR original give the same bits
    small = grey_u8(np.ascontiguousarray(image[::step, ::step]))
    t = cv2.resize(small, THUMBNAIL_SIZE, interpolation=cv2.INTER_AREA).astype(np.float32)
    t -= t.mean()
    norm = float(np.linalg.norm(t))
    return t / norm if norm > 1e-3 else np.zeros_like(t)


STRUCTURE_BLOCK = 8  # pixels: ``frame_structure``'s fine blocks


def frame_structure(image: np.ndarray) -> float:
    """How much of a frame's variation is coarse: sqrt(variance of the means of its coarse blocks / variance of
    the means of its 8 x 8 pixel blocks), grey, the coarse blocks an eighth of the frame's short side (rounded
    down to whole 8-pixel blocks), over the largest top-left part made of whole coarse blocks; 1 (not judged)
    for a frame under 256 pixels on its short side, 0 for a uniform one. Noise varies at its own grain only: a
    coarse block of c pixels averages (c / 8)^2 independent fine ones of white noise, so it gives 8 / c (0.14 at
    640 x 480, 0.06 at 1920 x 1080), noise blurred by a few pixels a little more; a scene, whose variation is
    mostly coarse (light, walls, people), much more, whatever the frame's size (the blocks scale with it). The
    fine blocks average a camera's sensor noise away (its grain is a pixel), so a dark, noisy scene reads its
    scene. Measured (/tmp harness, 2026-11-30): of 330 noise stills (Gaussian, grey and colour, blurred 0-3 px,
    and other textures; 640 x 480 to 1280 x 720) 0.08-0.64 (median 0.15; the high ones blurred by 3-8 px), the
    nine whose fits the dim faces' validator accepted 0.13-0.20; helen_test made small, dark and noisy (the
    robustness suite's dim_small) 0.35-0.94 (median 0.70); ``benchmarks/hard_clips.py``'s face clips 0.6 or more;
    cap12's face alone, small, rolled, at 0.12-0.3 of its brightness with noise of 6-12 grey levels in a
    near-black 960 x 540 frame 0.72-0.86. For ``TrackerConfig.dim_min_structure``; about 0.4 ms for a 640 x 480
    frame on one core."""
    H, W = image.shape[:2]
    if min(H, W) < 256:
        return 1.0
    f = STRUCTURE_BLOCK
    c = min(H, W) // 8 // f * f
    h, w = H // c * c, W // c * c
    fine = cv2.resize(grey_u8(image[:h, :w]).astype(np.float32), (w // f, h // f), interpolation=cv2.INTER_AREA)
    var = float(fine.var())
    if var < 1e-6:
        return 0.0
    coarse = fine.reshape(h // c, c // f, w // c, c // f).mean(axis=(1, 3))
    return math.sqrt(float(coarse.var()) / var)


def unsharp(image: np.ndarray, sigma: float, amount: float) -> np.ndarray:
    """``image + amount * (image - G_sigma * image)`` (unsharp masking, Gaussian sigma in pixels), clipped to the
    image's integer range; same shape and dtype (``Tracker.fit_still``'s second look at a soft face)."""
    f = image.astype(np.float32)
    out = f + amount * (f - cv2.GaussianBlur(f, (0, 0), sigma))
    if np.issubdtype(image.dtype, np.integer):
        info = np.iinfo(image.dtype)
        np.clip(np.rint(out, out=out), info.min, info.max, out=out)
    return out.astype(image.dtype)


def smoothed(image: np.ndarray, sigma: float) -> np.ndarray:
    """``image`` smoothed by a Gaussian of ``sigma`` pixels, same shape and dtype (``Tracker.fit_still``'s second
    look at a dim, noisy face)."""
    return cv2.GaussianBlur(image, (0, 0), sigma)


def level_factor(face_px: float, couple_face_px: float) -> float:
    """r = min(1, couple_face_px / face_px): the resampling that makes the face ``couple_face_px`` wide."""
    if not np.isfinite(face_px) or face_px <= couple_face_px:
        return 1.0
    return float(couple_face_px / face_px)


def level_shift(r: float) -> float:
    """Where frame pixel 0 lands in a level resampled by r (``Levels``, cv2.resize): x -> r * x + level_shift(r)."""
    return 0.5 * r - 0.5


def local_contrast(img: np.ndarray, sigma: float) -> np.ndarray:
    """(I - B*I) / sqrt(B*(I - B*I)^2 + eps): local contrast normalisation (lighting invariance), with B a
    box filter of the same standard deviation as a Gaussian of ``sigma`` (width sigma * sqrt(12), odd).
    Box filters cost the same at any width: 23x faster than the Gaussian at sigma 8 on a 480x480 crop,
    with outputs correlated at 0.9998."""
    k = max(3, int(round(sigma * math.sqrt(12.0))) | 1)
    d = img - cv2.blur(img, (k, k))
    return d / np.sqrt(cv2.blur(d * d, (k, k)) + 25.0)


def resize_area(img: np.ndarray, k: float) -> np.ndarray:
    """``cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_AREA)`` of a (H, W) float32 image, k <= 1; the
    same bits, from a compiled kernel when 0.5 < k < 1 and 1 / k is not a whole number (OpenCV's general area
    path, slow on small images; ``aamtrack._kernels.resample``), else from OpenCV."""
    scale = 1.0 / k
    if not 0.5 < k < 1.0 or abs(scale - round(scale)) < 2.220446049250313e-16 or img.dtype != np.float32 \
            or img.ndim != 2:
        return cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_AREA)
    H, W = img.shape
    h, w = int(np.rint(H * k)), int(np.rint(W * k))  # cv2's size: saturate_cast<int>, rounding half to even
    if h < 1 or w < 1:
        return cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_AREA)  # its own error
    if (h, w) == (H, W):
        return img.copy()  # as cv2.resize does for a size that stays
    out = np.empty((h, w), np.float32)
    _resize_area(np.ascontiguousarray(img), scale, out)
    return out


class Levels:
    """The images one frame (or crop) offers the couples: ``get(r)`` resamples by r and computes the feature
    image (C, h, w) float32, once per factor. ``edge``: the image reaches the frame's edge (``Tracker.crop``: a crop
    that touches it), where what lies past it is missing rather than the border's value
    (``_kernels.warp._residual``'s ``fill``, ``_kernels.patches._blank_outside``); off by default (training reads
    its photos as the shipped models learned them)."""

    def __init__(self, gray: np.ndarray, features: Features, *, edge: bool = False):
        self.gray = np.ascontiguousarray(gray, dtype=np.float32)
        self.features = features
        self.edge = edge  # whether the image's edges are the picture's (not a crop's inside it): ``Searcher.fit``
        self._cache: dict[float, np.ndarray] = {}
        self._raw: dict[float, np.ndarray] = {1.0: self.gray}

    def resampled(self, r: float) -> np.ndarray:
        """The image resampled by r, from the nearest finer one already made (r/r' of a smaller image; the
        half-pixel mappings compose exactly: r/r' (r' x + r'/2 - 1/2 + 1/2) - 1/2 = r x + r/2 - 1/2)."""
        img = self._raw.get(r)
        if img is None:
            src = min((f for f in self._raw if f >= r), default=1.0)
            while r / src < 0.5 and min(self._raw[src].shape) >= 4:  # exact halvings first: INTER_AREA's fast path
                half = self._raw.get(src / 2)
                if half is None:
                    half = self._raw[src / 2] = cv2.resize(self._raw[src], None, fx=0.5, fy=0.5,
                                                           interpolation=cv2.INTER_AREA)
                src /= 2
            k = r / src
            img = self._raw[src] if k == 1.0 else resize_area(self._raw[src], k)
            if min(img.shape) < 2:
                img = np.zeros((2, 2), np.float32)
            self._raw[r] = img
        return img

    def get(self, r: float) -> np.ndarray:
        img = self._cache.get(r)
        if img is None:
            img = self._cache[r] = self.features(self.resampled(min(r, 1.0)))
        return img
