"""Training sets: a folder of images, each with an iBUG ``.pts`` file of the same stem."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from .frames import IMAGE_SUFFIXES, display_name, read_image
from .pts import N_LANDMARKS, read_pts

MIN_IMAGE_PX = 16  # smaller images hold no face worth learning from
MAX_OUTSIDE = 1 / 3  # share of points allowed outside the image (faces cut by the frame edge)


def find_pairs(folder: str | Path) -> list[tuple[Path, Path]]:
    """Sorted (image, pts) pairs in ``folder``; InputError when the folder is missing or has none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{display_name(folder)}: no such folder")
    pairs = []
    for img in sorted(folder.iterdir()):
        if img.suffix.lower() in IMAGE_SUFFIXES and img.with_suffix(".pts").is_file():
            pairs.append((img, img.with_suffix(".pts")))
    if not pairs:
        raise InputError(f"{display_name(folder)}: no image with a .pts file of the same name")
    return pairs


def read_image_gray(path: str | Path) -> np.ndarray:
    """(H, W) uint8 grey image; InputError naming the file when it cannot be decoded or is too small."""
    img = read_image(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"{display_name(path)}: cannot read image (missing, corrupt or not an image)")
    if min(img.shape[:2]) < MIN_IMAGE_PX:
        raise InputError(f"{display_name(path)}: image is {img.shape[1]}x{img.shape[0]} px, "
                         f"too small to train on (at least {MIN_IMAGE_PX}x{MIN_IMAGE_PX})")
    return img


def check_points(points: np.ndarray, size: tuple[int, int], name: str) -> None:
    """InputError unless the (n, 2) ``points`` can annotate a face in an image of ``size`` (width, height):
    most points inside the image, none farther out than the image is large (a .pts file of another image or
    another size), and spread in two dimensions (not all on one point or one line)."""
    w, h = size
    x, y = points[:, 0], points[:, 1]
    outside = (x < 0) | (x > w) | (y < 0) | (y > h)
    far = (x < -w) | (x > 2 * w) | (y < -h) | (y > 2 * h)
    if far.any() or outside.mean() > MAX_OUTSIDE:
        raise InputError(f"{name}: {int(outside.sum())} of {len(points)} points lie outside the {w}x{h} image "
                         f"(x {x.min():.0f}..{x.max():.0f}, y {y.min():.0f}..{y.max():.0f}): a .pts file of "
                         "another image or size?")
    centred = points - points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if not (sv[0] > 1e-6 and sv[-1] > 1e-3 * sv[0] and np.ptp(x) >= 2 and np.ptp(y) >= 2):
        raise InputError(f"{name}: degenerate landmarks (all on one point or one line)")


def load_pair(image_path: Path, pts_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(grey image (H, W) uint8, points (68, 2) float64 in pixels), checked against each other."""
    image = read_image_gray(image_path)
    points = read_pts(pts_path, n_points=N_LANDMARKS)
    check_points(points, (image.shape[1], image.shape[0]), display_name(pts_path))
    return image, points
