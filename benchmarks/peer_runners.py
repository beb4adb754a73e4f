"""Peer face trackers run on the same frames as aamtrack: dlib's 68-point shape predictor (from its HOG
detector on every frame, or tracking from the previous frame's landmarks) and MediaPipe Face Mesh.
Each runner returns a PeerRun; a peer that cannot be imported raises PeerUnavailable("skipped: ...").
Used by peers.py (see it for the install commands of the optional peers)."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np

try:
    import cv2
except ImportError:  # pragma: no cover - the harness needs OpenCV for colour conversion
    cv2 = None

from aamtrack.metrics import MEDIAPIPE_SUBSET, from_dlib, from_normalised, mediapipe_to_ibug

_SUBSET = list(MEDIAPIPE_SUBSET)
_MAX_SIZE_CHANGE = 1.4  # dlib_tracking: lost when the landmark box grows or shrinks more than this per frame


def _stack(arrays, n_points: int, dim: int = 2) -> np.ndarray:
    return np.stack(arrays) if arrays else np.zeros((0, n_points, dim))


class PeerUnavailable(RuntimeError):
    """A peer's package cannot be imported or its model file is missing; the message starts with 'skipped:'."""


@dataclass(frozen=True)
class PeerRun:
    """Output of one peer on one sequence.

    name : str
    landmarks : (n_frames, 68, 2) float64, the package's pixels (``aamtrack.metrics.PIXEL_ORIGIN``); NaN where
        nothing was found (or no iBUG counterpart)
    times : (n_frames,) float64, seconds of landmarking work per frame
    setup_s : float, seconds to load the model / build the graph (not in ``times``)
    detector_runs : int, frames on which a face detector ran (dlib; 0 for MediaPipe, whose graph decides itself)
    points468 : (n_frames, 468, 3) float64 or None; MediaPipe only: x, y in pixels, z in MediaPipe's units
    tracking : bool, the tracker carries state from frame to frame (dlib tracking, MediaPipe video, aamtrack video)
    wall_times : (n_frames,) float64 or None; aamtrack only: seconds of the whole tracker step
    """

    name: str
    landmarks: np.ndarray
    times: np.ndarray
    setup_s: float
    detector_runs: int = 0
    points468: np.ndarray | None = None
    tracking: bool = False
    wall_times: np.ndarray | None = None


# ---------------------------------------------------------------------------------------------------- dlib


def _dlib():
    """(dlib module, path of shape_predictor_68_face_landmarks.dat), or PeerUnavailable."""
    try:
        import dlib
    except ImportError as exc:
        raise PeerUnavailable(f"skipped: dlib not importable ({exc}); pip install dlib-bin") from None
    try:
        import face_recognition_models
    except ImportError as exc:
        raise PeerUnavailable(
            f"skipped: dlib's 68-point model not found ({exc}); pip install face-recognition-models"
        ) from None
    path = face_recognition_models.pose_predictor_model_location()
    if not os.path.exists(path):
        raise PeerUnavailable(f"skipped: dlib's 68-point model file missing at {path}")
    return dlib, path


def _gray(frame: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame


def _shape_array(shape) -> np.ndarray:
    """dlib's 68 points in its own 0-based pixels (the runners return them in the package's: ``from_dlib``)."""
    return np.array([(p.x, p.y) for p in shape.parts()], dtype=np.float64)


def _largest(rects):
    return max(rects, key=lambda r: r.width() * r.height()) if len(rects) else None


def dlib_detect_every_frame(frames, *, upsample: int = 0) -> PeerRun:
    """dlib HOG detector + 68-point shape predictor on every frame (largest face).

    Parameters
    ----------
    frames : iterable of (h, w, 3) uint8 BGR arrays (or (h, w) gray)
    upsample : int
        Times the detector upsamples the image (0: faces >= 80 px; 1: >= 40 px at 4x the cost).

    Returns
    -------
    PeerRun
    """
    dlib, model_path = _dlib()
    t0 = time.perf_counter()
    detector = dlib.get_frontal_face_detector()
    predictor = dlib.shape_predictor(model_path)
    setup_s = time.perf_counter() - t0
    landmarks, times = [], []
    for frame in frames:
        t = time.perf_counter()
        gray = _gray(frame)
        rect = _largest(detector(gray, upsample))
        points = _shape_array(predictor(gray, rect)) if rect is not None else np.full((68, 2), np.nan)
        times.append(time.perf_counter() - t)
        landmarks.append(points)
    n = len(landmarks)
    return PeerRun(f"dlib detect every frame (up{upsample})", from_dlib(_stack(landmarks, 68)), np.array(times),
                   setup_s, n)


def _landmark_box(points: np.ndarray) -> tuple[float, float, float]:
    """(centre x, centre y, size) of a shape's bounding box; size is the geometric mean of width and height."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2.0
    return float(centre[0]), float(centre[1]), float(math.sqrt(max((hi - lo).prod(), 1e-9)))


def dlib_tracking(frames, *, upsample: int = 0) -> PeerRun:
    """dlib in tracking mode: detect when needed, otherwise predict from a box placed on the last landmarks.

    Parameters
    ----------
    frames : iterable of (h, w, 3) uint8 BGR arrays, in video order
    upsample : int
        Detector upsampling for the (re-)detections.

    Returns
    -------
    PeerRun
    """
    dlib, model_path = _dlib()
    t0 = time.perf_counter()
    detector = dlib.get_frontal_face_detector()
    predictor = dlib.shape_predictor(model_path)
    setup_s = time.perf_counter() - t0
    landmarks, times = [], []
    prev = None  # previous frame's landmarks, None when lost
    detector_runs = 0
    calib = None  # detector box relative to the landmark box at the last detection: (dx, dy, side) / size

    def detect(gray):
        rect = _largest(detector(gray, upsample))
        if rect is None:
            return None, None
        points = _shape_array(predictor(gray, rect))
        cx, cy, size = _landmark_box(points)
        rx, ry = (rect.left() + rect.right()) / 2.0, (rect.top() + rect.bottom()) / 2.0
        side = (rect.width() + rect.height()) / 2.0
        return points, ((rx - cx) / size, (ry - cy) / size, side / size)

    for frame in frames:
        t = time.perf_counter()
        gray = _gray(frame)
        h, w = gray.shape[:2]
        points = None
        if prev is not None:
            cx, cy, size = _landmark_box(prev)
            bx, by, half = cx + calib[0] * size, cy + calib[1] * size, calib[2] * size / 2.0
            rect = dlib.rectangle(round(bx - half), round(by - half), round(bx + half), round(by + half))
            points = _shape_array(predictor(gray, rect))
            ncx, ncy, nsize = _landmark_box(points)
            if not (1 / _MAX_SIZE_CHANGE < nsize / size < _MAX_SIZE_CHANGE and 0 <= ncx < w and 0 <= ncy < h):
                points = None  # lost: detect again on this frame
        if points is None:
            detector_runs += 1
            points, new_calib = detect(gray)
            if new_calib is not None:
                calib = new_calib
        times.append(time.perf_counter() - t)
        prev = points
        landmarks.append(points if points is not None else np.full((68, 2), np.nan))
    return PeerRun(f"dlib tracking (up{upsample})", from_dlib(_stack(landmarks, 68)), np.array(times), setup_s,
                   detector_runs, tracking=True)


# ------------------------------------------------------------------------------------------------ MediaPipe


def _mediapipe():
    try:
        import mediapipe
        face_mesh = mediapipe.solutions.face_mesh
    except Exception as exc:  # ImportError, or an AttributeError from a build without the legacy solutions
        raise PeerUnavailable(f"skipped: mediapipe face mesh not importable ({type(exc).__name__}: {exc})") from None
    return face_mesh


def mediapipe_face_mesh(frames, *, static: bool = False) -> PeerRun:
    """MediaPipe Face Mesh (468 points, one face, no iris refinement).

    Parameters
    ----------
    frames : iterable of (h, w, 3) uint8 BGR arrays
    static : bool
        False for video (the graph tracks between frames), True for unrelated still images.

    Returns
    -------
    PeerRun
        ``landmarks`` holds the iBUG points of ``MEDIAPIPE_TO_IBUG`` (others NaN); ``points468`` all 468 points.
    """
    face_mesh = _mediapipe()
    t0 = time.perf_counter()
    mesh = face_mesh.FaceMesh(static_image_mode=static, max_num_faces=1, refine_landmarks=False)
    setup_s = time.perf_counter() - t0
    points468, times = [], []
    try:
        for frame in frames:
            t = time.perf_counter()
            result = mesh.process(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
            if result.multi_face_landmarks:
                h, w = frame.shape[:2]
                lms = result.multi_face_landmarks[0].landmark
                points = np.array([(p.x, p.y, p.z * w) for p in lms], dtype=np.float64)
                points[:, :2] = from_normalised(points, w, h)  # normalised over the image's extent -> pixels
            else:
                points = np.full((468, 3), np.nan)
            times.append(time.perf_counter() - t)
            points468.append(points)
    finally:
        mesh.close()
    points468 = _stack(points468, 468, 3)
    landmarks = np.full((len(points468), 68, 2), np.nan)
    landmarks[:, _SUBSET] = mediapipe_to_ibug(points468)
    name = "mediapipe face mesh" + (" (static)" if static else "")
    return PeerRun(name, landmarks, np.array(times), setup_s, 0, points468, tracking=not static)


# ------------------------------------------------------------------------------------------------- aamtrack
