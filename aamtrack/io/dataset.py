"""Training sets: a folder of images, each with an iBUG ``.pts`` file of the same stem."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from .pts import read_pts

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")


def find_pairs(folder: str | Path) -> list[tuple[Path, Path]]:
    """Sorted (image, pts) pairs in ``folder``; InputError when the folder is missing or has none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder")
    pairs = []
    for img in sorted(folder.iterdir()):
        if img.suffix.lower() in IMAGE_SUFFIXES and img.with_suffix(".pts").is_file():
            pairs.append((img, img.with_suffix(".pts")))
    if not pairs:
        raise InputError(f"{folder}: no image with a .pts file of the same name")
    return pairs


def read_image_gray(path: str | Path) -> np.ndarray:
    """(H, W) uint8 grey image; InputError naming the file when it cannot be decoded."""
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None or img.size == 0:
        raise InputError(f"{path}: cannot read image (missing, corrupt or not an image)")
    return img


def load_pair(image_path: Path, pts_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(grey image (H, W) uint8, points (68, 2) float64), checked."""
    return read_image_gray(image_path), read_pts(pts_path, n_points=68)
