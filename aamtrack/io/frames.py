"""Frame sources: a video file, a folder of images or a glob pattern, read frame-exactly.

One :class:`Frame` per frame, in order, none skipped or repeated: a frame that cannot be decoded or read is
delivered with ``image=None`` (the tracker records it as "unreadable") rather than dropped. Problems that make a
source unusable (missing, not a video, no frames, no images) are found by :func:`open_frames` itself, which
reads the first frame eagerly, so a command fails before it writes any output.

A video's frame numbers and timestamps come from the stream's presentation timestamps (``CAP_PROP_POS_MSEC``
after each grab), so a frame the decoder drops silently still has its row and the frames after it keep their
own numbers (see :class:`VideoFrames`). Images are numbered in order and stamped ``index / fps``.
"""

from __future__ import annotations

import contextlib
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

__all__ = ["Frame", "FrameSource", "VideoFrames", "ImageFrames", "open_frames", "gray", "IMAGE_SUFFIXES",
           "VIDEO_SUFFIXES", "natural_key",
           "opencv_path", "read_image", "display_name"]

logger = logging.getLogger(__name__)

#: Image file suffixes read as frames (run) and as training images (train): the formats OpenCV decodes.
#: Video file suffixes a folder or glob of a batch run gives as inputs, one per file (anything else OpenCV's
#: FFmpeg backend reads is still read when named on the command line).
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv", ".flv", ".3gp", ".ts",
                  ".mts", ".m2ts", ".ogv")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pbm", ".jp2")
DEFAULT_FPS = 25.0
MIN_FPS, MAX_FPS = 1e-3, 1e5  # frame rates outside are typos, not cameras
_MAX_FAILED_GRABS = 8  # consecutive failed grabs before a video read gives up (end of stream or a broken tail)
_MAX_WARNINGS = 3  # problems of one read reported as warnings; the rest at INFO (-v)


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame of a source.

    index : int -- 0-based position in the source
    timestamp : float -- seconds: the stream's presentation time (video), else ``index / fps``
    image : (H, W, 3) uint8 BGR, or None when the frame could not be decoded or read
    thumbnail : (24, 32) float32 or None -- ``imaging.thumbnail`` of the image when made ahead (the tracker's
        shot-change test makes it itself otherwise)
    """

    index: int
    timestamp: float
    image: np.ndarray | None
    thumbnail: np.ndarray | None = None


def gray(image: np.ndarray) -> np.ndarray:
    """Convert a BGR(A) image, (H, W, 3 or 4) uint8, to gray, (H, W) uint8; a 2-D image is returned as is."""
    if image.ndim == 2:
        return image
    code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
    return cv2.cvtColor(image, code)


def display_name(path: str | os.PathLike) -> str:
    """``path`` as printable text: bytes that are not UTF-8 (kept by Python as surrogates) shown as ``\\xff``."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


@contextlib.contextmanager
def opencv_path(path: str | os.PathLike, *, directory: bool = False) -> Iterator[str]:
    """A name under which OpenCV can open ``path`` (a file, or with ``directory`` a folder to create files in).

    OpenCV takes file names as UTF-8 text and crashes (segfault) on a Python name holding bytes that are not
    UTF-8. Such a path is opened here and handed over as ``/proc/self/fd/N`` (Linux), valid inside the block;
    where that is impossible the name is refused with :class:`InputError`. Other names are made absolute:
    FFmpeg reads a relative name with a colon (``10:00.mp4``, ``pipe:1.mp4``) as a protocol and a URL.
    """
    text = os.fspath(path)
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        pass
    else:
        yield os.path.abspath(text)
        return
    if not os.path.isdir("/proc/self/fd"):
        raise InputError(f"{display_name(text)}: file name is not valid UTF-8 (rename the file)")
    flags = os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0)
    try:
        fd = os.open(text, flags)
    except OSError as exc:
        raise InputError(f"{display_name(text)}: cannot open ({exc.strerror})") from None
    try:
        yield f"/proc/self/fd/{fd}"
    finally:
        os.close(fd)


def _check_fps(fps) -> float:
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"frame rate {fps!r} is not a number") from None
    if not (math.isfinite(value) and MIN_FPS <= value <= MAX_FPS):
        raise InputError(f"frame rate must be a number of frames per second in [{MIN_FPS:g}, {MAX_FPS:g}], "
                         f"got {fps!r}")
    return value


def natural_key(text: str) -> list:
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
    fps : float -- frames per second (the video's own rate, or as given)
    n_frames : int or None -- number of frames if known (for a video, as the container states it)
    width, height : int -- size of the delivered images (after ``resize``)
    """

    def __init__(self, *, name: str, fps: float, n_frames: int | None, width: int, height: int, resize=None):
        self.name = name
        self.fps = _check_fps(fps)
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

    Frame numbers and timestamps come from the stream: a decoded frame's presentation time ``t`` (seconds from
    the stream's start) is its timestamp, and ``round(t * rate)`` its index, ``rate`` being the container's
    frame rate. So one item comes out per frame the container holds, each at its own index:

    * A frame the decoder drops silently (a damaged packet) leaves a gap in the presentation times; the missing
      indices are delivered as ``image=None`` before the next decoded frame.
    * ``grab()`` succeeds, ``retrieve()`` fails: the frame exists but cannot be decoded -> ``image=None``.
    * ``grab()`` fails: end of stream, or a damaged stretch. Reading retries up to 8 times in a row when the
      container says frames remain. When reading ends before the container's frame count, the remaining
      indices are delivered as ``image=None`` (a truncated or damaged tail), so the count always matches.

    Indices never pass the container's frame count, nor go back. For a variable-frame-rate file the index is
    an approximation (the presentation time on the nominal rate's grid). With ``fps`` given, timestamps are
    ``index / fps`` instead of the stream's own.

    Limitation: the rows stay aligned as far as the stream's timestamps are right. MP4/MOV/MKV take them from
    the container's index, so a damaged packet costs its own row only. AVI has no per-frame timestamps:
    FFmpeg numbers the chunks it finds, and a chunk whose header is destroyed shifts the frames after it by
    one (the count is still made up at the end, with an empty last row).
    """

    def __init__(self, path: str | os.PathLike, *, fps: float | None = None, resize=None,
                 decode_threads: int | None = None):
        self.path = Path(path)
        self._threads = decode_threads
        name = str(path)
        if not self.path.exists():
            raise InputError(f"{name}: no such file")
        if not self.path.is_file():
            raise InputError(f"{name}: not a file")
        if self.path.stat().st_size == 0:
            raise InputError(f"{name}: empty file, not a video")
        self._user_fps = fps is not None
        if fps is not None:
            _check_fps(fps)
        cap = self._open_capture(self.path, name, self._threads)
        try:
            ok = cap.grab()
            if not ok:
                raise InputError(f"{name}: video contains no frames (empty or unreadable stream)")
            first_t = _stream_time(cap)
            ok, first = cap.retrieve()
            n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
            n_frames = int(n) if math.isfinite(n) and 0 < n < 1e9 else None
            own_fps = cap.get(cv2.CAP_PROP_FPS)
            self._rate = own_fps if math.isfinite(own_fps) and 0 < own_fps <= 1000 else None
            if fps is None:
                fps = self._rate
                if fps is None:
                    logger.warning("%s: video states no usable frame rate (%r), using %g fps", name, own_fps, DEFAULT_FPS)
                    fps = DEFAULT_FPS
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
        self._first = (first_t, first)
        self._fresh = True  # the capture sits just after the first frame, which is kept in self._first
        logger.info("%s: %s", name, self)

    @staticmethod
    def _open_capture(path: Path, name: str, threads: int | None = None) -> cv2.VideoCapture:
        """FFmpeg's capture of ``path``; ``threads``: its decoding threads (None: FFmpeg's choice, one per core;
        the frames are the same either way)."""
        params = [] if threads is None else [cv2.CAP_PROP_N_THREADS, int(threads)]
        with opencv_path(path) as cv_name:
            cap = cv2.VideoCapture(cv_name, cv2.CAP_FFMPEG, params)
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
            cap = self._cap = self._open_capture(self.path, self.name, self._threads)
            if not cap.grab():
                raise InputError(f"{self.name}: video contains no frames on re-reading")
            first_t = _stream_time(cap)
            ok, image = cap.retrieve()
            first = (first_t, image if ok else None)
        return self._read(cap, first)

    def _index_of(self, t: float | None, next_index: int) -> int:
        """Index of a decoded frame at stream time ``t`` when ``next_index`` is the first one not yet given."""
        if t is None or self._rate is None:
            return next_index
        index = round(t * self._rate)
        if index < next_index or (self.n_frames is not None and index >= self.n_frames):
            return next_index  # timestamps going back, or past the stated count: count frames instead
        return index

    def _make(self, index: int, t: float | None, image: np.ndarray | None) -> Frame:
        if self._user_fps or t is None:
            return self._frame(index, image)
        return Frame(index, t, _resized(image, self._resize))

    def _read(self, cap: cv2.VideoCapture, first: tuple) -> Iterator[Frame]:
        next_index = 0
        failed = 0
        pending = first  # (stream time, image) of a frame grabbed but not yet delivered
        n_reports = [0]

        def report(msg, *args):  # the first few problems as warnings, the rest with -v only (a badly damaged
            n_reports[0] += 1    # file must not flood the terminal)
            logger.log(logging.WARNING if n_reports[0] <= _MAX_WARNINGS else logging.INFO, msg, *args)

        while not self._closed:
            if pending is not None:
                t, image = pending
                pending = None
                index = self._index_of(t, next_index)
                if index > next_index:
                    report("%s: frame(s) %d..%d missing from the decoded stream (damaged); delivered empty",
                           self.name, next_index, index - 1)
                    for k in range(next_index, index):
                        yield self._frame(k, None)
                yield self._make(index, t, image)
                next_index = index + 1
                failed = 0
            if not cap.grab():
                failed += 1
                remaining = self.n_frames is None or next_index < self.n_frames
                if not remaining or failed >= _MAX_FAILED_GRABS:
                    break
                continue
            t = _stream_time(cap)
            ok, image = cap.retrieve()
            if not ok:
                report("%s: frame at %s could not be decoded", self.name,
                       f"{t:.3f} s" if t is not None else f"position {next_index}")
            pending = (t, image if ok else None)
        if self._closed:
            return
        if n_reports[0] > _MAX_WARNINGS:
            logger.warning("%s: %d more damaged frames or stretches (aamtrack -v lists them)", self.name,
                           n_reports[0] - _MAX_WARNINGS)
        if self.n_frames is not None and next_index < self.n_frames:
            logger.warning("%s: reading stopped at frame %d of %d (damaged or truncated file); the rest delivered "
                           "empty", self.name, next_index, self.n_frames)
            for k in range(next_index, self.n_frames):
                yield self._frame(k, None)

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        self._first = None
        super().close()


def _stream_time(cap: cv2.VideoCapture) -> float | None:
    """Presentation time (s from the stream's start) of the frame just grabbed, or None if the stream has none."""
    msec = cap.get(cv2.CAP_PROP_POS_MSEC)
    return msec / 1000.0 if math.isfinite(msec) and msec >= 0 else None


def read_image(path: str | os.PathLike, flags: int = cv2.IMREAD_COLOR, *, warn: bool = True) -> np.ndarray | None:
    """The decoded image ((H, W, 3) uint8 BGR with the default ``flags``), or None if the file cannot be read
    or decoded (with a warning naming it, unless not ``warn``). Reads the bytes in Python, so any file name works
    (non-ASCII, not UTF-8)."""
    try:
        data = np.fromfile(path, dtype=np.uint8)
        image = cv2.imdecode(data, flags) if data.size else None
    except (OSError, cv2.error) as exc:
        if warn:
            logger.warning("%s: cannot read image: %s", display_name(path), exc)
        return None
    if image is None or image.size == 0:
        if warn:
            logger.warning("%s: cannot decode image", display_name(path))
        return None
    return image



class ImageFrames(FrameSource):
    """Frames from a list of image files, in the given order; an unreadable file gives ``image=None``.

    ``width``/``height`` are those of the first readable image; images of another size are delivered as they
    are (with a warning) unless ``resize`` is given. ``first_readable``: that image's index (the files before it
    could not be read, and were warned of, when the source was opened).
    """

    def __init__(self, paths, *, name: str, fps: float | None = None, resize=None):
        self.paths = [Path(p) for p in paths]
        if not self.paths:
            raise InputError(f"{name}: no images")
        fps = DEFAULT_FPS if fps is None else _check_fps(fps)
        first = None
        for k, path in enumerate(self.paths):  # noqa: B007 - k is used after the loop
            first = read_image(path, warn=len(self.paths) > 1)  # one file: the error below says it all
            if first is not None:
                break
        if first is None and len(self.paths) == 1:
            raise InputError(f"{display_name(self.paths[0])}: cannot read the image (not an image file, or truncated)")
        if first is None:
            raise InputError(f"{name}: none of the {len(self.paths)} image files could be read")
        self.first_readable = k  # (the files before it could not be read: not read, nor warned of, again)
        self._first_image = first  # delivered without a second read, once
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
            if index < self.first_readable:
                image = None
            elif index == self.first_readable and self._first_image is not None:
                image, self._first_image = self._first_image, None
            else:
                image = read_image(path)
            if image is not None:
                native = native or image.shape[:2]
                if image.shape[:2] != native and not warned and self._resize is None:
                    logger.warning("%s: images differ in size (%s is %dx%d)", self.name, path.name,
                                   image.shape[1], image.shape[0])
                    warned = True
            yield self._frame(index, image)


def _image_files(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    return sorted(files, key=lambda p: natural_key(p.name))


def open_frames(source: str | os.PathLike, *, fps: float | None = None, resize=None,
                decode_threads: int | None = None) -> FrameSource:
    """Open a video file, a folder of images, a glob pattern or a single image as a :class:`FrameSource`.

    Parameters
    ----------
    source : str or PathLike
        A video file (whatever OpenCV's FFmpeg backend reads: mp4/H.264, avi/MJPG, ...); a folder, whose image
        files (``.png``, ``.jpg``, ...) are read in natural name order (``frame2`` before ``frame10``); a glob
        pattern such as ``"dir/*.png"`` (image files among the matches, natural order of their paths); or one
        image file (a one-frame source).
    fps : float, optional
        Frame rate for timestamps (``index / fps``), in [0.001, 100000]. Default: a video's own
        presentation timestamps; 25.0 for images.
    resize : (width, height), optional
        Deliver every image resized to this size (INTER_AREA when shrinking, else bilinear).
    decode_threads : int, optional
        FFmpeg's decoding threads for a video (default: FFmpeg's choice, one per core). 1 where other
        processes keep the cores busy (a batch's worker processes): the same frames for less CPU time.

    Returns
    -------
    FrameSource
        Iterable of :class:`Frame`; a context manager.

    Raises
    ------
    InputError
        Missing file or folder, a file that is not a video, a video without frames, a folder or pattern without
        (readable) images, a bad ``fps``. The first frame is read here, so these surface before any output is
        written.
    """
    text = os.fspath(source)
    path = Path(text)
    if not path.exists() and _glob.has_magic(text):
        matches = [Path(p) for p in _glob.glob(text)]
        files = [p for p in matches if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
        if not files:
            detail = f" ({len(matches)} matches, none an image file)" if matches else ""
            raise InputError(f"{text}: pattern matches no images{detail}")
        files.sort(key=lambda p: natural_key(str(p)))
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
    return VideoFrames(path, fps=fps, resize=resize, decode_threads=decode_threads)
