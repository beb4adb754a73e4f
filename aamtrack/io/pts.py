"""iBUG ``.pts`` landmark files: read (header form or bare ``x y`` lines) and write (header form, atomically).

The standard form, as in the 300-W / 300-VW annotations::

    version: 1
    n_points:  68
    {
    x y
    ...
    }

Pixel convention (the one statement of it for the package): the 300-W markup, and so every ``.pts`` file
aamtrack reads or writes, is 1-based, Matlab-style: the centre of the top-left pixel is (1, 1), where OpenCV's
is (0, 0) (``aamtrack.metrics.PIXEL_ORIGIN`` = 1). Every landmark position a user gives or gets is in this
convention: :func:`read_pts` returns coordinates exactly as written, :func:`write_pts` writes them exactly as
given, training takes them so, and the tracker's results (landmarks, mesh vertices, pose translation, the CSV
columns, ``run --pts``) come out so; a ``.pts`` file written by ``run --pts`` overlays the image exactly as a
300-W annotation does. Inside, a model works in OpenCV's pixels, where its images are resampled and warped:
``train.pipeline.train_model`` moves the labels by -1 on the way in and ``Tracker._result`` moves the results by
+1 on the way out (the overlay draws them at -1 again). Until 2026-11-26 models learned the 1-based labels as they
were, so they learned the 1-pixel offset in face units at the training faces' size and scaled it with every face
(0.27 px at 30 px between the eyes); and training mirrored the labels as ``w - 1 - x``, which put every mirrored
label 2 px left of its face and the models 1 px left of every unmirrored one. Code that moves points with an
image (a mirror, a resize, a rotation made with OpenCV) goes through OpenCV's convention: subtract the origin,
transform, add it back (``mesh.landmarks.mirror_points``, ``mesh.landmarks.affine_points``).
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .atomic import atomic_write

__all__ = ["read_pts", "write_pts", "write_pts_per_frame", "N_LANDMARKS"]

logger = logging.getLogger(__name__)

#: Points per face in the iBUG-68 markup, used for every landmark file, CSV column block and model map.
N_LANDMARKS = 68


def _parse_point(text: str, path: str, line_no: int) -> tuple[float, float]:
    fields = text.split()
    if len(fields) != 2:
        raise InputError(f"{path}: line {line_no}: expected 'x y', got {text[:40]!r}")
    try:
        x, y = float(fields[0]), float(fields[1])
    except ValueError:
        raise InputError(f"{path}: line {line_no}: expected two numbers 'x y', got {text[:40]!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{path}: line {line_no}: non-finite coordinate {text[:40]!r}")
    return x, y


def read_pts(path: str | os.PathLike, *, n_points: int | None = N_LANDMARKS) -> np.ndarray:
    """Read an iBUG ``.pts`` file.

    Parameters
    ----------
    path : str or PathLike
        The file, in the standard form (``version:``, ``n_points:``, ``{``, ``x y`` lines, ``}``) or as bare
        ``x y`` lines. Blank lines are ignored.
    n_points : int or None
        Expected number of points; None accepts any number (at least one).

    Returns
    -------
    points : (n_points, 2) float64
        x, y per point, in the file's pixel coordinates (1-based, unshifted: see the module docstring).

    Raises
    ------
    InputError
        Missing or unreadable file, non-numeric line, unterminated ``{``, or a wrong number of points; the
        message names the file and the problem, e.g. ``faces/a.pts: 67 points, expected 68``.
    """
    name = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{name}: is a folder, expected a .pts file") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read ({exc.strerror or exc})") from None

    lines = [(i + 1, s.strip()) for i, s in enumerate(text.splitlines())]
    lines = [(i, s) for i, s in lines if s]
    if not lines:
        raise InputError(f"{name}: empty file, expected landmark points")

    declared = None
    body = lines
    if any(s.startswith("{") for _, s in lines) or lines[0][1].lower().startswith(("version", "n_points")):
        start = next((k for k, (_, s) in enumerate(lines) if s.startswith("{")), None)
        if start is None:
            raise InputError(f"{name}: header without '{{', not a .pts file")
        for line_no, s in lines[:start]:
            key, _, value = s.partition(":")
            if key.strip().lower() == "n_points":
                try:
                    declared = int(value)
                except ValueError:
                    raise InputError(f"{name}: line {line_no}: bad n_points {value.strip()!r}") from None
        stop = next((k for k in range(start + 1, len(lines)) if lines[k][1].startswith("}")), None)
        if stop is None:
            raise InputError(f"{name}: missing closing '}}'")
        body = lines[start + 1 : stop]

    points = np.array([_parse_point(s, name, i) for i, s in body], dtype=np.float64).reshape(-1, 2)
    n = len(points)
    if declared is not None and declared != n:
        raise InputError(f"{name}: header says n_points {declared}, file holds {n} points")
    if n_points is not None and n != n_points:
        raise InputError(f"{name}: {n} points, expected {n_points}")
    if n == 0:
        raise InputError(f"{name}: no points")
    return points


def write_pts(path: str | os.PathLike, points: np.ndarray, *, decimals: int = 3) -> None:
    """Write ``points`` to ``path`` in the standard iBUG form, atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination (its folder must exist).
    points : (n_points, 2) array_like of float
        x, y per point, finite.
    decimals : int
        Digits after the decimal point.

    Raises
    ------
    ValueError
        Points of the wrong shape or not finite.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) == 0:
        raise ValueError(f"points must have shape (n_points, 2), got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError(f"{path}: cannot write non-finite points to a .pts file")
    with atomic_write(path, "w", newline="\n") as f:
        f.write(f"version: 1\nn_points:  {len(points)}\n{{\n")
        f.writelines(f"{x:.{decimals}f} {y:.{decimals}f}\n" for x, y in points)
        f.write("}\n")


def write_pts_per_frame(directory: str | os.PathLike, result, *, template: str = "frame_{:06d}.pts") -> Path | None:
    """Write the landmarks of one tracked frame to ``directory/frame_000123.pts`` (for ``aamtrack run --pts``).

    Parameters
    ----------
    directory : str or PathLike
        Output folder; created if absent.
    result : FrameResult
        Only successful frames (``result.success``) are written.
    template : str
        File name, formatted with ``result.frame``.

    Returns
    -------
    Path or None
        The file written, or None for a frame without a face.
    """
    if not result.success:
        return None
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / template.format(int(result.frame))
    write_pts(path, result.landmarks)
    return path
