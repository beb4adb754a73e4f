"""Overlay video: each input frame with the fitted mesh and the 68 landmarks drawn on it, written atomically.

Frames are written to a temporary name that keeps the video extension (``.name.<random>.tmp.mp4``, so OpenCV
picks the container from it) and renamed to the destination on ``close()``.
"""

from __future__ import annotations

import logging
import os
import secrets
from pathlib import Path

import cv2
import numpy as np

from ..errors import OutputError
from .atomic import TemporaryOutput, check_replaceable, discard_temporary
from .frames import opencv_path

__all__ = ["OverlayWriter", "mesh_edges", "draw_result"]

logger = logging.getLogger(__name__)

_SHIFT = 4  # sub-pixel bits for cv2 drawing
_MESH_COLOR = {"tracked": (80, 200, 80), "detected": (60, 200, 230)}  # BGR: green when tracked, yellow on detection
_POINT_COLOR = (40, 40, 240)
_TEXT_COLOR = (40, 40, 240)


def mesh_edges(triangles: np.ndarray) -> np.ndarray:
    """Unique undirected edges of a triangle mesh.

    Parameters
    ----------
    triangles : (n_triangles, 3) int array
        Vertex indices.

    Returns
    -------
    edges : (n_edges, 2) int64
        Sorted vertex index pairs, each edge once.
    """
    tri = np.asarray(triangles, dtype=np.int64)
    if tri.ndim != 2 or tri.shape[1] != 3:
        raise ValueError(f"triangles must have shape (n_triangles, 3), got {tri.shape}")
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return np.unique(np.sort(edges, axis=1), axis=0)


def draw_result(image: np.ndarray, result, edges: np.ndarray | None = None) -> np.ndarray:
    """Draw one :class:`~aamtrack.track.result.FrameResult` on ``image`` in place and return it.

    Parameters
    ----------
    image : (H, W, 3) uint8 BGR
    result : FrameResult
        Successful: mesh edges between ``result.vertices`` (if ``edges`` and vertices are given) as thin lines
        and the landmarks as small dots. Otherwise the status ("lost", "dropped", ...) as small text.
    edges : (n_edges, 2) int, optional
        From :func:`mesh_edges`.
    """
    if not result.success:
        cv2.putText(image, str(result.status), (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, _TEXT_COLOR, 1, cv2.LINE_AA)
        return image
    scale = 1 << _SHIFT
    if edges is not None and result.vertices is not None and len(edges):
        vertices = np.asarray(result.vertices, dtype=np.float64)
        if edges.max() < len(vertices):
            segments = vertices[edges]  # (n_edges, 2, 2)
            segments = segments[np.isfinite(segments).all(axis=(1, 2))]
            if len(segments):
                pts = np.round(segments * scale).astype(np.int32)
                cv2.polylines(image, list(pts), False, _MESH_COLOR.get(result.status, _MESH_COLOR["tracked"]),
                              1, cv2.LINE_AA, _SHIFT)
        else:
            logger.debug("frame %d: triangles index past %d vertices, mesh not drawn", result.frame, len(vertices))
    landmarks = np.asarray(result.landmarks, dtype=np.float64)
    for x, y in landmarks[np.isfinite(landmarks).all(axis=1)]:
        cv2.circle(image, (int(round(x * scale)), int(round(y * scale))), 2 * scale, _POINT_COLOR, -1,
                   cv2.LINE_AA, _SHIFT)
    return image


class OverlayWriter(TemporaryOutput):
    """Write overlay frames to a video, atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination, normally ``.mp4`` (codec 'mp4v'). If no mp4v writer can be opened, an MJPG ``.avi`` is
        written instead at ``path`` with the suffix ``.avi`` (logged as a warning; see ``self.path``).
    fps : float
        Frame rate of the output.
    size : (width, height)
        Frame size of the output; images of another size are resized to it.
    triangles : (n_triangles, 3) int array, optional
        Mesh triangles indexing ``result.vertices``; None draws landmarks only.

    Attributes
    ----------
    path : Path -- where the video will be on ``close()``
    n_frames : int -- frames written so far
    """

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int], *, triangles=None):
        self.size = (int(size[0]), int(size[1]))
        if self.size[0] <= 0 or self.size[1] <= 0 or not fps > 0:
            raise ValueError(f"need size > 0 and fps > 0, got size={size!r}, fps={fps!r}")
        self.edges = None if triangles is None else mesh_edges(triangles)
        self.n_frames = 0
        path = Path(path)
        attempts = [(path, "mp4v")] if path.suffix.lower() != ".avi" else []
        attempts.append((path.with_suffix(".avi"), "MJPG"))
        self._handle = None
        for target, fourcc in attempts:
            check_replaceable(target)
            # An ASCII temporary name, handed to OpenCV through a name it can take (see opencv_path).
            name = f".overlay.{secrets.token_hex(4)}.tmp{target.suffix}"
            tmp = target.parent / name
            with opencv_path(target.parent, directory=True) as folder:
                writer = cv2.VideoWriter(f"{folder}/{name}", cv2.VideoWriter_fourcc(*fourcc), float(fps), self.size)
            if writer.isOpened():
                if target != path:
                    logger.warning("%s: cannot open an mp4v video writer; writing MJPG to %s instead", path, target)
                self.path, self._tmp, self._handle, self.fourcc = target, tmp, writer, fourcc
                break
            writer.release()
            discard_temporary(tmp)
        if self._handle is None:
            raise OutputError(f"{path}: OpenCV cannot open a video writer (tried "
                              f"{', '.join(f for _, f in attempts)})")

    def write(self, image: np.ndarray | None, result) -> None:
        """Draw ``result`` on a copy of ``image`` and append it as the next frame.

        Parameters
        ----------
        image : (H, W, 3) uint8 BGR, or None
            The input frame; None (an unreadable frame) writes a black frame, so the frame count stays exact.
        result : FrameResult
        """
        if self._handle is None:
            raise ValueError(f"{self.path}: writer is closed")
        w, h = self.size
        if image is None:
            canvas = np.zeros((h, w, 3), np.uint8)
        else:
            canvas = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
            if canvas.shape[:2] != (h, w):
                canvas = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
            else:
                canvas = canvas.copy()
        self._handle.write(draw_result(canvas, result, self.edges))
        self.n_frames += 1

    def _release(self) -> None:
        self._handle.release()

    def _finish(self) -> None:
        """OpenCV's writer reports no write error (a full disk leaves an unplayable file): read the finished
        file's frame count back and refuse a file that does not hold every frame written."""
        with opencv_path(self._tmp) as name:
            cap = cv2.VideoCapture(name, cv2.CAP_FFMPEG)
        try:
            n = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else -1
        finally:
            cap.release()
        if n != self.n_frames:
            raise OutputError(f"{self.path}: overlay video could not be written completely "
                              f"({'unreadable' if n < 0 else f'{n:.0f} of {self.n_frames} frames'}; disk full?)")

    def _closed(self) -> None:
        logger.info("%s: %d frames", self.path, self.n_frames)
