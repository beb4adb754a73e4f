"""Synthetic frames for the io tests: each frame shows its index as 8 black/white blocks (one bit each), large
enough to survive MJPG and mp4v compression, on a faint seeded-noise background."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from aamtrack.result import FrameResult

WIDTH, HEIGHT = 128, 64
BLOCK = 16  # 8 blocks of 16x16 px along the top row encode bits 0..7 of the index


def index_image(index: int, rng: np.random.Generator, *, size=(WIDTH, HEIGHT)) -> np.ndarray:
    """(H, W, 3) uint8 BGR frame encoding ``index`` (0..255) in its top row of blocks."""
    w, h = size
    image = rng.integers(90, 110, size=(h, w, 3), dtype=np.uint8)  # mid gray, low noise
    block = w // 8
    for bit in range(8):
        value = 240 if (index >> bit) & 1 else 15
        image[: h // 4, bit * block : (bit + 1) * block] = value
    return image


def decode_index(image: np.ndarray) -> int:
    """Index written by :func:`index_image` (block centres are compared with mid gray)."""
    h, w = image.shape[:2]
    block = w // 8
    g = image.mean(axis=2) if image.ndim == 3 else image
    index = 0
    for bit in range(8):
        cell = g[h // 16 : h // 4 - h // 16, bit * block + block // 4 : (bit + 1) * block - block // 4]
        index |= int(cell.mean() > 128) << bit
    return index


def make_video(path: Path, n_frames: int, *, fourcc: str, fps: float = 30.0, seed: int = 0,
               size=(WIDTH, HEIGHT)) -> Path:
    """Write ``n_frames`` index-encoded frames with cv2.VideoWriter; returns ``path``."""
    rng = np.random.default_rng(seed)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, size)
    assert writer.isOpened(), f"cannot open a {fourcc} writer for {path}"
    for i in range(n_frames):
        writer.write(index_image(i, rng, size=size))
    writer.release()
    return path


def make_results(n_frames: int, rng: np.random.Generator, *, n_anim: int = 3, n_shape: int = 2,
                 with_3d: bool = False, fps: float = 30.0) -> list[FrameResult]:
    """FrameResults cycling through the statuses, with random pose, landmarks and parameters where successful."""
    cycle = ("detected", "tracked", "tracked", "lost", "tracked", "dropped", "unreadable", "tracked")
    out = []
    for i in range(n_frames):
        status = cycle[i % len(cycle)]
        if status in ("detected", "tracked"):
            out.append(FrameResult(
                frame=i, timestamp=i / fps, status=status, confidence=float(rng.uniform(0.5, 1.0)),
                landmarks=rng.uniform(0, 640, size=(68, 2)),
                landmarks3d=rng.normal(size=(68, 3)) if with_3d else None,
                rotation=rng.uniform(-0.5, 0.5, size=3), translation=rng.uniform(0, 640, size=2),
                scale=float(rng.uniform(50, 200)), anim_params=rng.normal(size=n_anim),
                shape_params=rng.normal(size=n_shape), vertices=rng.uniform(0, 640, size=(113, 2))))
        else:
            out.append(FrameResult(frame=i, timestamp=i / fps, status=status))
    return out
