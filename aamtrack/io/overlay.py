"""Overlay video: each input frame with the fitted mesh, the 68 landmarks, the head's axes, the frame number,
status and confidence drawn on it (a full-width banner on frames without a result), written atomically in a
codec browsers play: through PyAV (the ``video`` extra, ``pip install "aamtrack[video]"``) where it is installed,
else where OpenCV has one (:func:`codec_attempts`).

Frames are written to a temporary name that keeps the video extension (``.name.<random>.tmp.mp4``, so OpenCV
picks the container from it) and renamed to the destination on ``close()``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
import sys
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np

from ..mesh.shape_model import rotation_matrix
from ..metrics import PIXEL_ORIGIN

from ..errors import OutputError
from .atomic import TemporaryOutput, check_replaceable, discard_temporary
from .frames import opencv_path

__all__ = ["OverlayWriter", "mesh_edges", "draw_result"]

logger = logging.getLogger(__name__)

_SHIFT = 4  # sub-pixel bits for cv2 drawing
# Colours, BGR (the legend is in README, "Overlay"):
_MESH_COLOR = {"tracked": (80, 200, 80), "detected": (60, 200, 230)}  # green when tracked, yellow on detection
_POINT_COLOR = (40, 40, 240)  # landmarks: red dots
_AXIS_COLORS = ((60, 60, 255), (60, 220, 60), (255, 140, 40))  # head axes x (red), y (green), z (blue)
_STATUS_COLOR = {"tracked": (80, 220, 80), "detected": (60, 220, 240), "lost": (50, 50, 235),
                 "dropped": (0, 150, 255), "unreadable": (170, 170, 170)}
_BANNER_COLOR = {"lost": (30, 30, 200), "dropped": (0, 120, 230), "unreadable": (90, 90, 90)}
_FONT = cv2.FONT_HERSHEY_SIMPLEX


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
    """Draw one :class:`~aamtrack.result.FrameResult` on ``image`` in place and return it.

    Parameters
    ----------
    image : (H, W, 3) uint8 BGR
    result : FrameResult
        Successful: mesh edges between ``result.vertices`` (if ``edges`` and vertices are given) as thin lines
        (green when tracked, yellow on a detection), the landmarks as red dots and the head's axes from the nose
        tip (x red, y green, z blue, from ``result.rotation``). Every frame: frame number, status and confidence
        in the top-left corner. A frame without a result gets a full-width banner across the top (red "LOST"
        with the reason, orange "DROPPED", grey "UNREADABLE") and a frame border of the same colour.
    edges : (n_edges, 2) int, optional
        From :func:`mesh_edges`.
    """
    if result.success:
        _draw_face(image, result, edges)
    else:
        _draw_banner(image, result)
    _draw_status(image, result)
    return image


def _text_scale(image: np.ndarray) -> float:
    return max(0.4, min(image.shape[0], 1.3 * image.shape[1]) / 600.0)


def _draw_face(image: np.ndarray, result, edges) -> None:
    scale = 1 << _SHIFT
    # results are in the package's 1-based pixels (metrics.PIXEL_ORIGIN); OpenCV draws at 0-based ones
    if edges is not None and result.vertices is not None and len(edges):
        vertices = np.asarray(result.vertices, dtype=np.float64) - PIXEL_ORIGIN
        if edges.max() < len(vertices):
            segments = vertices[edges]  # (n_edges, 2, 2)
            segments = segments[np.isfinite(segments).all(axis=(1, 2))]
            if len(segments):
                pts = np.round(segments * scale).astype(np.int32)
                cv2.polylines(image, list(pts), False, _MESH_COLOR.get(result.status, _MESH_COLOR["tracked"]),
                              1, cv2.LINE_AA, _SHIFT)
        else:
            logger.debug("frame %d: triangles index past %d vertices, mesh not drawn", result.frame, len(vertices))
    landmarks = np.asarray(result.landmarks, dtype=np.float64) - PIXEL_ORIGIN
    for x, y in landmarks[np.isfinite(landmarks).all(axis=1)]:
        cv2.circle(image, (int(round(x * scale)), int(round(y * scale))), 2 * scale, _POINT_COLOR, -1,
                   cv2.LINE_AA, _SHIFT)
    _draw_axes(image, landmarks, np.asarray(result.rotation, dtype=np.float64))


def axes_endpoints(landmarks: np.ndarray, rotation: np.ndarray) -> np.ndarray | None:
    """(4, 2) image points: the nose tip (iBUG 30) and the tips of the head's x, y, z axes drawn from it, each half
    the face width long; None without finite landmarks and rotation.

    The model projects a point X as ``(s (R X)_x + tx, -s (R X)_y + ty)`` (image y points down), so the unit
    axis k appears along ``(R[0, k], -R[1, k])``: x to the face's left (image right when frontal), y up, z out of
    the face towards the camera (a dot when frontal).
    """
    if landmarks.shape != (68, 2) or not np.isfinite(landmarks).all() or rotation.shape != (3,) \
            or not np.isfinite(rotation).all():
        return None
    length = 0.5 * float(np.ptp(landmarks[:, 0]))
    R = rotation_matrix(*rotation)
    origin = landmarks[30]
    tips = origin + length * np.column_stack([R[0, :], -R[1, :]])  # (3, 2), one row per axis
    return np.vstack([origin, tips])


def _draw_axes(image: np.ndarray, landmarks: np.ndarray, rotation: np.ndarray) -> None:
    ends = axes_endpoints(landmarks, rotation)
    if ends is None:
        return
    scale = 1 << _SHIFT
    o = tuple(np.round(ends[0] * scale).astype(int))
    thickness = max(2, round(image.shape[0] / 240))
    order = np.argsort([-rotation_matrix(*rotation)[2, k] for k in range(3)])  # draw the far axes first
    for k in order:
        tip = ends[k + 1]
        if np.hypot(*(tip - ends[0])) < 1.0:
            continue
        cv2.arrowedLine(image, o, tuple(np.round(tip * scale).astype(int)), _AXIS_COLORS[k], thickness,
                        cv2.LINE_AA, _SHIFT, 0.15)


def _draw_status(image: np.ndarray, result) -> None:
    """'#frame status confidence' on a dark box in the top-left corner (below the banner on lost frames)."""
    fs = _text_scale(image)
    thick = max(1, round(fs * 1.5))
    text = f"#{result.frame}  {result.status}  conf {result.confidence:.2f}"
    (tw, th), base = cv2.getTextSize(text, _FONT, fs, thick)
    pad = max(3, round(4 * fs))
    y0 = 0 if result.success else _banner_height(image)
    x0 = 0 if result.success else _border(image)  # inside the loss border
    x1, y1 = min(image.shape[1], x0 + tw + 2 * pad), min(image.shape[0], y0 + th + base + 2 * pad)
    roi = image[y0:y1, x0:x1]
    roi[:] = (roi * 0.35).astype(np.uint8)  # darkened box: readable on any footage
    cv2.putText(image, text, (x0 + pad, y0 + pad + th), _FONT, fs, _STATUS_COLOR.get(result.status, (255, 255, 255)),
                thick, cv2.LINE_AA)


def _border(image: np.ndarray) -> int:
    return max(2, round(image.shape[0] / 100))


def _banner_height(image: np.ndarray) -> int:
    return max(24, round(0.13 * image.shape[0]))


def _draw_banner(image: np.ndarray, result) -> None:
    """A full-width banner across the top and a border, in the status colour, with the status and reason."""
    color = _BANNER_COLOR.get(result.status, _BANNER_COLOR["lost"])
    h, w = image.shape[:2]
    bh = min(h, _banner_height(image))
    band = image[:bh]
    band[:] = (0.2 * band + 0.8 * np.array(color)).astype(np.uint8)
    border = _border(image)
    cv2.rectangle(image, (0, 0), (w - 1, h - 1), color, 2 * border)
    reason = getattr(result, "reason", "")
    text = result.status.upper() + (f": {reason}" if reason else "")
    fs = _text_scale(image) * 1.1
    thick = max(1, round(fs * 2))
    while fs > 0.3 and cv2.getTextSize(text, _FONT, fs, thick)[0][0] > w - 2 * border - 8:
        fs *= 0.9
    (tw, th), _ = cv2.getTextSize(text, _FONT, fs, thick)
    cv2.putText(image, text, (max(border + 4, (w - tw) // 2), (bh + th) // 2), _FONT, fs, (255, 255, 255), thick,
                cv2.LINE_AA)


_BROWSER_CODECS = ("avc1", "VP80", "VP90")


def codec_attempts(path: Path, *, fast: bool = False) -> list[tuple[Path, str]]:
    """(file, fourcc) pairs to try, best first: codecs web browsers play (H.264 in .mp4, VP8 / VP9 in .webm),
    then mp4v in .mp4 and MJPG in .avi, which they do not. The suffix of ``path`` picks the first container.
    ``fast``: mp4v in .mp4 first, then MJPG in .avi. OpenCV's VP8 encoder is the slowest part of a run with an
    overlay: measured 2026-12-01 (Intel Xeon VM, quiet; cap12 frames scaled, 40 frames): VP8 15.6 / 41 / 77 ms
    a frame at 640x480 / 1280x720 / 1920x1080, mp4v 1.3 / 3.5 / 12 ms (VLC, mpv and QuickTime play mp4v, web
    browsers do not); OpenCV's writer here takes no encoder options (``OPENCV_FFMPEG_WRITER_OPTIONS`` with a
    bitrate, deadline or cpu-used left the VP8 file as it was) to make VP8 faster."""
    mp4, webm, avi = path.with_suffix(".mp4"), path.with_suffix(".webm"), path.with_suffix(".avi")
    if fast:
        return [(mp4, "mp4v"), (avi, "MJPG")]
    suffix = path.suffix.lower()
    if suffix == ".avi":
        return [(avi, "MJPG")]
    if suffix == ".webm":
        return [(webm, "VP80"), (webm, "VP90"), (mp4, "avc1"), (mp4, "mp4v"), (avi, "MJPG")]
    if suffix == ".mp4":
        # VP9 is left out here: OpenCV's libvpx-vp9 writes about 60 ms per 400x300 frame, VP8 about 7
        return [(mp4, "avc1"), (webm, "VP80"), (mp4, "mp4v"), (avi, "MJPG")]
    return [(path, "mp4v"), (avi, "MJPG")]


#: PyAV's encoders by the overlay's suffix: (codec, fourcc reported, options). OpenCV's writer takes no encoder
#: options, and its VP8 encodes at libvpx's default deadline: measured 2026-12-02 (Intel Xeon VM, one thread, 60
#: frames of a 1920x1080 clip) 3.8 frames a second, 7.9 at 1280x720, 14.6 at 960x540, so an overlay bounded
#: ``aamtrack run --video`` far below the tracker's speed. PyAV 18.1 on the same frames: VP8 at the realtime
#: deadline and cpu-used 8 29.9 frames a second (2.4 MB), H.264 (x264, crf 23) at preset ultrafast 41.3 (0.95 MB),
#: superfast 29.0 (1.2 MB), veryfast 23.0 (0.6 MB); Chromium plays the .webm and the .mp4
#: (``tests/io/test_io_report.py``).
PYAV_CODECS = {".webm": ("libvpx", "VP80", {"deadline": "realtime", "cpu-used": "8"}),
               ".mp4": ("libx264", "avc1", {"preset": "ultrafast", "crf": "23"})}
_VP8_BITS_PER_PIXEL = 0.1  # per pixel and frame: 5.2 Mbit/s at 1920x1080 and 25 frames a second
#: OpenCV's VP8 at about 7.5 million pixels a second (the figures above: 3.8 frames a second at 1920x1080, 7.9 at
#: 1280x720, 14.6 at 960x540): from 1280x720 up an overlay through it is slower than real time, and a run with
#: --video says what would be faster
VP8_PIXELS_PER_SECOND = 7.5e6
SLOW_VP8_PIXELS = 1280 * 720


def _temporary_name(suffix: str) -> str:
    """An ASCII file name for an overlay being written, hidden, with the video's suffix (the container)."""
    return f".overlay.{secrets.token_hex(4)}.tmp{suffix}"


def _pyav():
    """The ``av`` module (PyAV), or None where it is not installed."""
    try:
        import av
    except ImportError:
        return None
    return av


def _reason(exc: BaseException) -> str:
    """An encoder's or the disk's error in a few words (an OSError's own, without the temporary file's name)."""
    return (getattr(exc, "strerror", None) or str(exc)).strip() or type(exc).__name__


class _PyAVWriter:
    """What ``OverlayWriter`` uses of ``cv2.VideoWriter`` (``write`` a BGR frame, ``release``), over PyAV with the
    encoder and options of ``PYAV_CODECS`` for the file's suffix, one encoding thread. Raises ``OutputError`` when
    the file cannot be opened or written (PyAV reports a full disk where OpenCV's writer does not)."""

    def __init__(self, av, filename: str, suffix: str, fps: float, size: tuple[int, int], name: str):
        codec, self.fourcc, options = PYAV_CODECS[suffix]
        self._av, self._name = av, name
        try:
            self._out = av.open(filename, "w", format=suffix[1:])
            try:
                stream = self._out.add_stream(codec, rate=Fraction(fps).limit_denominator(100000), options=options)
                stream.width, stream.height = size
                stream.pix_fmt = "yuv420p"
                stream.thread_count = 1
                if codec == "libvpx":
                    stream.bit_rate = int(_VP8_BITS_PER_PIXEL * size[0] * size[1] * fps)
                stream.codec_context.open()  # an encoder that refuses these settings says so here, not later
            except BaseException:
                self._out.close()
                raise
        except (av.FFmpegError, OSError, ValueError) as exc:
            raise OutputError(f"{name}: PyAV cannot open a {codec} writer ({_reason(exc)})") from exc
        self._stream = stream

    def write(self, image: np.ndarray) -> None:
        try:
            for packet in self._stream.encode(self._av.VideoFrame.from_ndarray(image, format="bgr24")):
                self._out.mux(packet)
        except (self._av.FFmpegError, OSError) as exc:
            raise OutputError(f"{self._name}: overlay video could not be written ({_reason(exc)})") from exc

    def release(self) -> None:
        try:
            for packet in self._stream.encode():  # the frames the encoder still holds
                self._out.mux(packet)
        except (self._av.FFmpegError, OSError) as exc:
            raise OutputError(f"{self._name}: overlay video could not be written ({_reason(exc)})") from exc
        finally:
            self._out.close()


@contextlib.contextmanager
def _quiet_stderr():
    """Silence file descriptor 2 (C-level stderr) for the duration; Python's sys.stderr is flushed first."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no real fd 2 (embedded interpreters)
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


class OverlayWriter(TemporaryOutput):
    """Write overlay frames to a video, atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination, normally ``.mp4`` or ``.webm``. With PyAV installed, H.264 for ``.mp4`` and VP8 for
        ``.webm`` through it (:data:`PYAV_CODECS`; frames of even width and height). Else the first codec OpenCV
        can open of :func:`codec_attempts` is used, and the suffix follows it: for ``.mp4``, H.264 (``avc1``) where OpenCV has an encoder for it,
        else VP8 in ``.webm`` (the pip wheels of OpenCV have VP8 but no H.264 encoder), else ``mp4v`` (logged as
        a warning: browsers do not play it), else MJPG in ``.avi``. See ``self.path`` and ``self.fourcc``.
    fps : float
        Frame rate of the output.
    size : (width, height)
        Frame size of the output; images of another size are resized to it.
    triangles : (n_triangles, 3) int array, optional
        Mesh triangles indexing ``result.vertices``; None draws landmarks only.
    fast : bool
        mp4v in ``.mp4`` (else MJPG in ``.avi``), several times faster to write than VP8, which browsers play and
        mp4v not (:func:`codec_attempts`).

    Attributes
    ----------
    path : Path -- where the video will be on ``close()``
    fourcc : str -- the codec used
    backend : str -- "pyav" (PyAV's encoders, :data:`PYAV_CODECS`: the ``video`` extra, for ``.webm`` and ``.mp4``
        of even size, several times faster) or "opencv"
    n_frames : int -- frames written so far
    """

    def __init__(self, path: str | os.PathLike, fps: float, size: tuple[int, int], *, triangles=None,
                 fast: bool = False):
        self.size = (int(size[0]), int(size[1]))
        if self.size[0] <= 0 or self.size[1] <= 0 or not fps > 0:
            raise ValueError(f"need size > 0 and fps > 0, got size={size!r}, fps={fps!r}")
        self.edges = None if triangles is None else mesh_edges(triangles)
        self.n_frames = 0
        path = Path(path)
        attempts = codec_attempts(path, fast=fast)
        self._handle = None
        self.backend = "opencv"
        av = None if fast else _pyav()
        suffix = path.suffix.lower()
        # PyAV where installed, for the suffixes it has an encoder for and even sizes (4:2:0 chroma; x264 refuses
        # odd ones), else OpenCV as below
        if av is not None and suffix in PYAV_CODECS and self.size[0] % 2 == 0 and self.size[1] % 2 == 0:
            check_replaceable(path)
            tmp = path.parent / _temporary_name(path.suffix)
            try:
                self._handle = _PyAVWriter(av, str(tmp), suffix, float(fps), self.size, str(path))
            except OutputError as exc:
                discard_temporary(tmp)
                logger.warning("%s; OpenCV's writer instead", exc)
            else:
                self.path, self._tmp, self.fourcc, self.backend = path, tmp, self._handle.fourcc, "pyav"
                return
        for target, fourcc in attempts:
            check_replaceable(target)
            # An ASCII temporary name, handed to OpenCV through a name it can take (see opencv_path).
            name = _temporary_name(target.suffix)
            tmp = target.parent / name
            with opencv_path(target.parent, directory=True) as folder, _quiet_stderr():
                # _quiet_stderr: FFmpeg prints to the C stderr for every encoder it cannot open
                writer = cv2.VideoWriter(f"{folder}/{name}", cv2.VideoWriter_fourcc(*fourcc), float(fps), self.size)
            if writer.isOpened():
                if fourcc not in _BROWSER_CODECS and path.suffix.lower() != ".avi" and not fast:
                    logger.warning("%s: this OpenCV build has no H.264 or VP8 encoder; writing %s to %s, which "
                                   "web browsers do not play (VLC and ffplay do)", path, fourcc, target)
                elif fourcc in ("VP80", "VP90") and self.size[0] * self.size[1] >= SLOW_VP8_PIXELS:
                    logger.warning("overlay video: OpenCV's VP8 writes about %.0f frames a second at %dx%d, slower "
                                   "than the tracker; pip install \"aamtrack[video]\" writes H.264 several times "
                                   "faster (or use --fast-video)",
                                   VP8_PIXELS_PER_SECOND / (self.size[0] * self.size[1]), *self.size)
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
