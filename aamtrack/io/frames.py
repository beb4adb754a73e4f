"""Frame sources: a video file, a folder of images or a glob pattern, read frame-exactly.

One :class:`Frame` per frame, in order, none skipped or repeated: a frame that cannot be decoded or read is
delivered with ``image=None`` (the tracker records it as "unreadable") rather than dropped. Problems that make a
source unusable (missing, not a video, no frames, no images) are found by :func:`open_frames` itself, which
reads the first frame eagerly, so a command fails before it writes any output.

Timestamps are ``index / fps``: frame-exact and robust. The container's own timestamps
(``CAP_PROP_POS_MSEC``) are consulted only to size a gap after a failed read, never for ``Frame.timestamp``.
"""

from __future__ import annotations

import glob as _glob
import logging
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from ..errors import InputError

__all__ = ["Frame", "FrameSource", "VideoFrames", "ImageFrames", "open_frames", "gray", "IMAGE_SUFFIXES"]

logger = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pbm", ".jp2")
DEFAULT_FPS = 25.0
_MAX_FAILED_GRABS = 8  # consecutive failed grabs before a video read gives up (end of stream or a broken tail)


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame of a source.

    index : int -- 0-based position in the source
    timestamp : float -- seconds, ``index / fps``
    image : (H, W, 3) uint8 BGR, or None when the frame could not be decoded or read
    """

    index: int
    timestamp: float
    image: np.ndarray | None


def gray(image: np.ndarray) -> np.ndarray:
    """Convert a BGR(A) image, (H, W, 3 or 4) uint8, to gray, (H, W) uint8; a 2-D image is returned as is."""
    if image.ndim == 2:
        return image
    code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
    return cv2.cvtColor(image, code)


def _natural_key(text: str) -> list:
    """Sort key putting ``frame2`` before ``frame10`` (digits compare as numbers, letters case-insensitively)."""
    parts = re.split(r"(\d+)", text)
    return [int(p) if k % 2 else p.lower() for k, p in enumerate(parts)]


def _check_resize(resize) -> tuple[int, int] | None:
    if resize is None:
        return None
    w, h = (int(v) for v in resize)
    if w <= 0 or h <= 0:
        raise ValueError(f"resize must be (width, height) > 0, got {resize!r}")
    return w, h


def _resized(image: np.ndarray | None, size: tuple[int, int] | None) -> np.ndarray | None:
    if image is None or size is None or (image.shape[1], image.shape[0]) == size:
        return image
    shrink = size[0] * size[1] < image.shape[0] * image.shape[1]
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


class FrameSource:
    """Base of the frame sources: iterate for :class:`Frame` items; use as a context manager or call ``close()``.

    Attributes
    ----------
    name : str -- the file, folder or pattern, for messages
    fps : float -- frames per second (timestamps are ``index / fps``)
    n_frames : int or None -- number of frames if known (for a video, as the container states it)
    width, height : int -- size of the delivered images (after ``resize``)
    """

    def __init__(self, *, name: str, fps: float, n_frames: int | None, width: int, height: int, resize=None):
        self.name = name
        self.fps = float(fps)
        self.n_frames = n_frames
        self._resize = _check_resize(resize)
        self.width, self.height = self._resize if self._resize else (int(width), int(height))
        self._closed = False

    def __iter__(self) -> Iterator[Frame]:  # pragma: no cover - abstract
        raise NotImplementedError

    def _frame(self, index: int, image: np.ndarray | None) -> Frame:
        return Frame(index, index / self.fps, _resized(image, self._resize))

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"{self.name}: frame source is closed")

    def close(self) -> None:
        """Release the underlying file handles. Idempotent."""
        self._closed = True

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.name!r}, fps={self.fps:g}, n_frames={self.n_frames}, "
                f"size={self.width}x{self.height})")


class VideoFrames(FrameSource):
    """Frames of a video file, decoded with OpenCV's FFmpeg backend.

    Each iteration reads the file from the start (the first one reuses the frame read at open time).

    Reading rules, so that one item comes out per frame and iteration always ends:

    * ``grab()`` succeeds, ``retrieve()`` fails: the frame exists but cannot be decoded -> ``image=None``.
    * ``grab()`` fails: end of stream, or a damaged stretch. Reading retries up to 8 times in a row when the
      container says frames remain; if a later frame comes, the frames lost in between (estimated from its
      container timestamp, bounded by the frame count) are delivered as ``image=None``. Otherwise it stops.
    """

    def __init__(self, path: str | os.PathLike, *, fps: float | None = None, resize=None):
        self.path = Path(path)
        name = str(path)
        if not self.path.exists():
            raise InputError(f"{name}: no such file")
        if not self.path.is_file():
            raise InputError(f"{name}: not a file")
        if self.path.stat().st_size == 0:
            raise InputError(f"{name}: empty file, not a video")
        cap = self._open_capture(name)
        try:
            ok = cap.grab()
            if not ok:
                raise InputError(f"{name}: video contains no frames (empty or unreadable stream)")
            ok, first = cap.retrieve()
            n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
            n_frames = int(n) if math.isfinite(n) and 0 < n < 1e9 else None
            own_fps = cap.get(cv2.CAP_PROP_FPS)
            if fps is None:
                fps = own_fps
                if not (math.isfinite(fps) and 0 < fps <= 1000):
                    logger.warning("%s: video states no usable frame rate (%r), using %g fps", name, own_fps, DEFAULT_FPS)
                    fps = DEFAULT_FPS
            elif fps <= 0:
                raise ValueError(f"fps must be > 0, got {fps}")
            if ok:
                height, width = first.shape[:2]
            else:
                logger.warning("%s: first frame could not be decoded", name)
                first = None
                width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        except BaseException:
            cap.release()
            raise
        super().__init__(name=name, fps=fps, n_frames=n_frames, width=width, height=height, resize=resize)
        self._cap = cap
        self._first = first
        self._fresh = True  # the capture sits just after the first frame, which is kept in self._first
        logger.info("%s: %s", name, self)

    @staticmethod
    def _open_capture(name: str) -> cv2.VideoCapture:
        cap = cv2.VideoCapture(name, cv2.CAP_FFMPEG)
        if not cap.isOpened():
            cap.release()
            raise InputError(f"{name}: not a readable video (FFmpeg cannot open it: not a video, or truncated)")
        return cap

    def __iter__(self) -> Iterator[Frame]:
        self._check_open()
        if self._fresh:
            cap, first = self._cap, self._first
            self._fresh, self._first = False, None
        else:
            if self._cap is not None:
                self._cap.release()
            cap = self._cap = self._open_capture(self.name)
            if not cap.grab():
                raise InputError(f"{self.name}: video contains no frames on re-reading")
            ok, first = cap.retrieve()
            first = first if ok else None
        return self._read(cap, first)

    def _read(self, cap: cv2.VideoCapture, first: np.ndarray | None) -> Iterator[Frame]:
        yield self._frame(0, first)
        index = 1
        failed = 0
        while not self._closed:
            if not cap.grab():
                failed += 1
                remaining = self.n_frames is None or index < self.n_frames
                if not remaining or failed >= _MAX_FAILED_GRABS:
                    break
                continue
            if failed:
                for _ in range(self._lost_frames(cap, index, failed)):
                    yield self._frame(index, None)
                    index += 1
                failed = 0
            ok, image = cap.retrieve()
            if not ok:
                logger.warning("%s: frame %d could not be decoded", self.name, index)
            yield self._frame(index, image if ok else None)
            index += 1
        if failed and self.n_frames is not None and index < self.n_frames:
            logger.warning("%s: reading stopped at frame %d of %d (damaged or truncated file)",
                           self.name, index, self.n_frames)

    def _lost_frames(self, cap: cv2.VideoCapture, index: int, failed: int) -> int:
        """Frames lost before the one just grabbed, after ``failed`` failed grabs: from its container time."""
        msec = cap.get(cv2.CAP_PROP_POS_MSEC)
        lost = round(msec * self.fps / 1000.0) - index if math.isfinite(msec) and msec > 0 else 0
        if self.n_frames is not None:
            lost = min(lost, self.n_frames - 1 - index)
        lost = max(lost, 0)
        logger.warning("%s: read failed before frame %d (%d failed attempts); %d frame(s) lost, delivered empty",
                       self.name, index, failed, lost)
        return lost

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        self._first = None
        super().close()


def _read_image(path: Path) -> np.ndarray | None:
    """(H, W, 3) uint8 BGR, or None if the file cannot be read or decoded (works with non-ASCII paths)."""
    try:
        data = np.fromfile(path, dtype=np.uint8)
        image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    except (OSError, cv2.error) as exc:
        logger.warning("%s: cannot read image: %s", path, exc)
        return None
    if image is None:
        logger.warning("%s: cannot decode image", path)
    return image


class ImageFrames(FrameSource):
    """Frames from a list of image files, in the given order; an unreadable file gives ``image=None``.

    ``width``/``height`` are those of the first readable image; images of another size are delivered as they
    are (with a warning) unless ``resize`` is given.
    """

    def __init__(self, paths, *, name: str, fps: float | None = None, resize=None):
        self.paths = [Path(p) for p in paths]
        if not self.paths:
            raise InputError(f"{name}: no images")
        fps = DEFAULT_FPS if fps is None else float(fps)
        if fps <= 0:
            raise ValueError(f"fps must be > 0, got {fps}")
        first = None
        for k, path in enumerate(self.paths):
            first = _read_image(path)
            if first is not None:
                break
        if first is None:
            raise InputError(f"{name}: none of the {len(self.paths)} image files could be read")
        self._first = (k, first)
        super().__init__(name=name, fps=fps, n_frames=len(self.paths), width=first.shape[1],
                         height=first.shape[0], resize=resize)
        logger.info("%s: %s", name, self)

    def __iter__(self) -> Iterator[Frame]:
        self._check_open()
        return self._read()

    def _read(self) -> Iterator[Frame]:
        warned = False
        native = None
        for index, path in enumerate(self.paths):
            if self._closed:
                return
            if self._first is not None and self._first[0] == index:
                image, self._first = self._first[1], None
            else:
                image = _read_image(path)
            if image is not None:
                native = native or image.shape[:2]
                if image.shape[:2] != native and not warned and self._resize is None:
                    logger.warning("%s: images differ in size (%s is %dx%d)", self.name, path.name,
                                   image.shape[1], image.shape[0])
                    warned = True
            yield self._frame(index, image)


def _image_files(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=lambda p: _natural_key(p.name))


def open_frames(source: str | os.PathLike, *, fps: float | None = None, resize=None) -> FrameSource:
    """Open a video file, a folder of images, a glob pattern or a single image as a :class:`FrameSource`.

    Parameters
    ----------
    source : str or PathLike
        A video file (whatever OpenCV's FFmpeg backend reads: mp4/H.264, avi/MJPG, ...); a folder, whose image
        files (``.png``, ``.jpg``, ...) are read in natural name order (``frame2`` before ``frame10``); a glob
        pattern such as ``"dir/*.png"`` (image files among the matches, natural order of their paths); or one
        image file (a one-frame source).
    fps : float, optional
        Frame rate for timestamps. Default: the video's own rate; 25.0 for images.
    resize : (width, height), optional
        Deliver every image resized to this size (INTER_AREA when shrinking, else bilinear).

    Returns
    -------
    FrameSource
        Iterable of :class:`Frame`; a context manager.

    Raises
    ------
    InputError
        Missing file or folder, a file that is not a video, a video without frames, a folder or pattern without
        (readable) images. The first frame is read here, so these surface before any output is written.
    """
    text = os.fspath(source)
    path = Path(text)
    if not path.exists() and _glob.has_magic(text):
        matches = [Path(p) for p in _glob.glob(text)]
        files = [p for p in matches if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
        if not files:
            detail = f" ({len(matches)} matches, none an image file)" if matches else ""
            raise InputError(f"{text}: pattern matches no images{detail}")
        files.sort(key=lambda p: _natural_key(str(p)))
        return ImageFrames(files, name=text, fps=fps, resize=resize)
    if path.is_dir():
        files = _image_files(path)
        if not files:
            raise InputError(f"{text}: folder holds no image files ({', '.join(IMAGE_SUFFIXES[:4])}, ...)")
        return ImageFrames(files, name=text, fps=fps, resize=resize)
    if not path.exists():
        raise InputError(f"{text}: no such file or folder")
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return ImageFrames([path], name=text, fps=fps, resize=resize)
    return VideoFrames(path, fps=fps, resize=resize)
