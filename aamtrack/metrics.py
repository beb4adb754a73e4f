"""Landmark error metrics for benchmarks: NME, cumulative error distribution, jitter, MediaPipe-468 subset.

Pure numpy (no cv2), so the peer-tracker harness in ``benchmarks/`` can use it from a venv that has neither numba
nor scipy.

Definitions (the project's error convention, see ``shared/data/README.md``):

NME
    Per frame or image, the mean over the points of the Euclidean distance between predicted and reference
    point, divided by the reference's outer eye-corner distance (iBUG points 36 and 45, 0-based). A frame whose
    prediction has a NaN coordinate (nothing found) gets NaN; it is counted by :func:`ced` as a failure.
CED
    For each threshold t, the share of *all* items whose NME is <= t; NaN items count as above every threshold.
Jitter
    Mean over the consecutive frame pairs (t-1, t) that are both marked still of the mean over the points of
    ``|x_t - x_{t-1}|`` in pixels. On frames where the reference hardly moves, this is how much a tracker wobbles.
Still frames
    Frame t is still when the reference's mean point motion from frame t-1 to t is below ``thresh`` times its
    outer eye-corner distance at frame t; runs of still frames shorter than ``min_len`` are dropped (frame 0 has
    no predecessor and is never still).

MediaPipe correspondence
    :data:`MEDIAPIPE_TO_IBUG` maps iBUG-68 indices to MediaPipe Face Mesh (468-point) indices for the points with
    an unambiguous anatomical counterpart. Checked on ``cap12_edit`` against the dlib reference (median distance
    in units of the dlib outer eye-corner distance, about 65 px there)::

        iBUG  MediaPipe  what                                median
        36    33         right eye outer corner (image left)  0.018
        39    133        right eye inner corner               0.023
        42    362        left eye inner corner                0.010
        45    263        left eye outer corner (image right)  0.028
        30    4          nose tip on the ridge                0.037
        33    2          nose base middle (subnasale)         0.027
        48    61         mouth corner (image left)            0.024
        54    291        mouth corner (image right)           0.027
        51    0          upper lip, top middle                0.034
        57    17         lower lip, bottom middle             0.031
        8     152        chin (menton)                        0.026

    MediaPipe's "left"/"right" are the subject's, as are iBUG's: iBUG 36 is the subject's right outer eye
    corner, which appears on the image left. MediaPipe's point 1 (often called "nose tip") is *not* used for
    iBUG 30: on cap12 it sits 0.10 eye-distance below iBUG 30, halfway to iBUG 33; point 4, just above it on the
    ridge, matches. Inner-lip corners, eyebrows and the jaw line have no single counterpart and are left out.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "CED_THRESHOLDS",
    "IBUG_LEFT_EYE_OUTER",
    "IBUG_RIGHT_EYE_OUTER",
    "MEDIAPIPE_TO_IBUG",
    "MEDIAPIPE_SUBSET",
    "PIXEL_ORIGIN",
    "from_dlib",
    "from_normalised",
    "ced",
    "eye_distance",
    "jitter",
    "mediapipe_to_ibug",
    "nme",
    "nme_subset",
    "still_frames",
]

#: The pixel coordinate of the centre of the top-left pixel in every landmark position aamtrack handles: 300-W's
#: 1-based convention (``aamtrack.io.pts`` states it); OpenCV's is 0. Moving points with an image transformed by
#: OpenCV: subtract it, transform, add it back.
PIXEL_ORIGIN = 1.0


def from_dlib(points) -> np.ndarray:
    """Points as dlib gives them (``full_object_detection.part``: 0-based pixel indices, the top-left pixel's
    centre at 0, as OpenCV's) in the package's convention (``PIXEL_ORIGIN``), float64. cap12's reference
    ``cap12_edit_dlib68.npz`` is dlib's output: read as it is, it sat 0.84 / 0.76 px up and left of aamtrack's
    points (mean x / y difference over the 1337 frames, shipped 3D model), and dlib's own points on helen_test
    fitted the human labels best about 0.75 px further right and down (mean NME 0.0281 as given, 0.0270 one pixel
    on, 0.0315 two pixels on)."""
    return np.asarray(points, np.float64) + PIXEL_ORIGIN


def from_normalised(points, width: float, height: float) -> np.ndarray:
    """Points in image coordinates normalised to 0..1 over the image's extent (MediaPipe's ``landmark.x``,
    ``.y``: 0 at the left edge of the first pixel, 1 at the right edge of the last) in the package's pixels: the
    first pixel's centre, normalised 0.5 / width, is ``PIXEL_ORIGIN``. Only x and y are taken."""
    xy = np.asarray(points, np.float64)[..., :2]
    return xy * np.array([float(width), float(height)]) + (PIXEL_ORIGIN - 0.5)


#: iBUG-68 outer eye corners (0-based): 36 on the image left (subject's right eye), 45 on the image right.
IBUG_RIGHT_EYE_OUTER = 36
IBUG_LEFT_EYE_OUTER = 45

#: iBUG-68 regions (0-based point ranges): where a fit's error lies, e.g. the jaw line against the inner points.
IBUG_REGIONS = {"jaw": range(0, 17), "brows": range(17, 27), "nose": range(27, 36), "eyes": range(36, 48),
                "mouth": range(48, 68)}

#: Default CED thresholds: 0 to 0.15 in steps of 0.005 (31 values).
CED_THRESHOLDS = np.linspace(0.0, 0.15, 31)

#: {iBUG-68 index: MediaPipe Face Mesh index} for points with an unambiguous counterpart (see module docstring).
MEDIAPIPE_TO_IBUG = {
    36: 33,
    39: 133,
    42: 362,
    45: 263,
    30: 4,
    33: 2,
    48: 61,
    54: 291,
    51: 0,
    57: 17,
    8: 152,
}

#: The iBUG indices of :data:`MEDIAPIPE_TO_IBUG`, sorted: the point order of :func:`mediapipe_to_ibug`.
MEDIAPIPE_SUBSET = tuple(sorted(MEDIAPIPE_TO_IBUG))


def _points(array, name: str) -> np.ndarray:
    array = np.asarray(array, dtype=np.float64)
    if array.ndim < 2 or array.shape[-1] != 2:
        raise ValueError(f"{name}: expected shape (..., n_points, 2), got {array.shape}")
    return array


def eye_distance(points, *, left: int = IBUG_RIGHT_EYE_OUTER, right: int = IBUG_LEFT_EYE_OUTER) -> np.ndarray:
    """Distance between two points of each shape (by default the iBUG outer eye corners 36 and 45).

    Parameters
    ----------
    points : (..., n_points, 2) array
    left, right : int
        Point indices of the normaliser pair.

    Returns
    -------
    distance : (...) float64
    """
    points = _points(points, "points")
    return np.linalg.norm(points[..., right, :] - points[..., left, :], axis=-1)


def nme(pred, ref, *, left: int = IBUG_RIGHT_EYE_OUTER, right: int = IBUG_LEFT_EYE_OUTER) -> np.ndarray:
    """Normalised mean error per frame or image.

    Parameters
    ----------
    pred, ref : (..., n_points, 2) array
        Predicted and reference points in pixels, same shape. NaN in ``pred`` marks "nothing found".
    left, right : int
        Indices (into the point axis) of the reference points whose distance normalises the error; the iBUG
        outer eye corners 36 and 45 by default.

    Returns
    -------
    nme : (...) float64
        Mean over the points of ``|pred - ref|``, divided by ``|ref[right] - ref[left]|``; NaN where any
        coordinate of ``pred`` (or ``ref``) is NaN.
    """
    dist, norm = _distances(pred, ref, left=left, right=right)
    with np.errstate(divide="ignore", invalid="ignore"):
        return dist.mean(axis=-1) / norm


def _distances(pred, ref, **kw) -> tuple[np.ndarray, np.ndarray]:
    """(|pred - ref| per point (..., n_points), the reference's normalising distance (...)) of two point sets of
    one shape: :func:`nme`'s and :func:`nme_by_region`'s checks and parts."""
    pred = _points(pred, "pred")
    ref = _points(ref, "ref")
    if pred.shape != ref.shape:
        raise ValueError(f"pred has shape {pred.shape} but ref has shape {ref.shape}")
    return np.linalg.norm(pred - ref, axis=-1), eye_distance(ref, **kw)


def nme_by_region(pred, ref, regions=None, **kw) -> dict:
    """:func:`nme` over each region's points alone (default :data:`IBUG_REGIONS`), still normalised by the whole
    reference's outer eye-corner distance (``left``, ``right`` as :func:`nme`): {region: (...) float64}. The
    regions' means weighted by their point counts give the 68-point NME."""
    dist, norm = _distances(pred, ref, **kw)
    with np.errstate(divide="ignore", invalid="ignore"):
        return {name: dist[..., list(idx)].mean(axis=-1) / norm for name, idx in (regions or IBUG_REGIONS).items()}


def ced(errors, thresholds=None) -> np.ndarray:
    """Cumulative error distribution.

    Parameters
    ----------
    errors : (n_items,) array
        Per-item errors (e.g. from :func:`nme`); NaN marks a failed item.
    thresholds : (n_thresholds,) array, optional
        Default :data:`CED_THRESHOLDS` (0 to 0.15 in steps of 0.005).

    Returns
    -------
    share : (n_thresholds,) float64
        Share of all items with error <= each threshold; NaN items count as above every threshold. An empty
        ``errors`` gives NaN.
    """
    errors = np.asarray(errors, dtype=np.float64).ravel()
    thresholds = CED_THRESHOLDS if thresholds is None else np.asarray(thresholds, dtype=np.float64)
    if errors.size == 0:
        return np.full(thresholds.shape, np.nan)
    ok = np.sort(errors[~np.isnan(errors)])
    return np.searchsorted(ok, thresholds, side="right") / errors.size


def jitter(track, still_mask) -> float:
    """Mean frame-to-frame landmark motion in pixels over still frame pairs.

    Parameters
    ----------
    track : (n_frames, n_points, 2) array
        Landmarks per frame in pixels; NaN for frames with nothing found.
    still_mask : (n_frames,) bool array
        Frames where the reference is still (e.g. from :func:`still_frames`).

    Returns
    -------
    jitter : float
        Mean, over the pairs (t-1, t) with both frames in ``still_mask`` and both tracked (no NaN), of the mean
        over the points of ``|track[t] - track[t-1]|``. NaN when there is no such pair.
    """
    track = _points(track, "track")
    still = np.asarray(still_mask, dtype=bool)
    if track.ndim != 3 or still.shape != track.shape[:1]:
        raise ValueError(f"track {track.shape} and still_mask {still.shape} do not match (n_frames, n_points, 2)")
    motion = np.linalg.norm(np.diff(track, axis=0), axis=-1).mean(axis=-1)  # (n_frames - 1,)
    pairs = still[1:] & still[:-1] & ~np.isnan(motion)
    return float(motion[pairs].mean()) if pairs.any() else float("nan")


def _drop_short_runs(mask: np.ndarray, min_len: int) -> np.ndarray:
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    out = np.zeros_like(mask)
    for start, stop in zip(edges[::2], edges[1::2]):
        if stop - start >= min_len:
            out[start:stop] = True
    return out


def still_frames(
    ref,
    *,
    thresh: float = 0.01,
    min_len: int = 5,
    left: int = IBUG_RIGHT_EYE_OUTER,
    right: int = IBUG_LEFT_EYE_OUTER,
) -> np.ndarray:
    """Frames where a reference track is still.

    Parameters
    ----------
    ref : (n_frames, n_points, 2) array
        Reference landmarks in pixels.
    thresh : float
        Frame t is still when the mean point motion from frame t-1 to t is below ``thresh`` x the outer eye-corner
        distance at frame t. The default 0.01 (about 0.65 px on cap12) lies above the frame-to-frame noise of a
        detect-every-frame dlib track (median 0.0075) and marks about half of cap12's frames still.
    min_len : int
        Runs of still frames shorter than this are dropped, so every stretch has at least ``min_len`` frames.
    left, right : int
        Indices of the normaliser pair.

    Returns
    -------
    still : (n_frames,) bool
        Frame 0 (no predecessor) and frames next to a NaN are never still.
    """
    ref = _points(ref, "ref")
    if ref.ndim != 3:
        raise ValueError(f"ref: expected shape (n_frames, n_points, 2), got {ref.shape}")
    motion = np.linalg.norm(np.diff(ref, axis=0), axis=-1).mean(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = motion / eye_distance(ref[1:], left=left, right=right)
        still = np.concatenate([[False], rel < thresh])  # NaN compares False
    return _drop_short_runs(still, max(int(min_len), 1))


def mediapipe_to_ibug(points468, ibug_idx=None) -> np.ndarray:
    """MediaPipe Face Mesh points at the iBUG points they correspond to.

    Parameters
    ----------
    points468 : (..., 468, d) array, d >= 2
        MediaPipe points in pixels (x, y first; any z is dropped).
    ibug_idx : sequence of int, optional
        iBUG indices wanted, each a key of :data:`MEDIAPIPE_TO_IBUG`; default :data:`MEDIAPIPE_SUBSET`.

    Returns
    -------
    points : (..., len(ibug_idx), 2) float64
    """
    points468 = np.asarray(points468, dtype=np.float64)
    if points468.ndim < 2 or points468.shape[-2] != 468 or points468.shape[-1] < 2:
        raise ValueError(f"points468: expected shape (..., 468, 2 or 3), got {points468.shape}")
    ibug_idx = MEDIAPIPE_SUBSET if ibug_idx is None else tuple(int(i) for i in ibug_idx)
    missing = [i for i in ibug_idx if i not in MEDIAPIPE_TO_IBUG]
    if missing:
        raise ValueError(f"iBUG points {missing} have no MediaPipe counterpart in MEDIAPIPE_TO_IBUG")
    return points468[..., [MEDIAPIPE_TO_IBUG[i] for i in ibug_idx], :2]


def nme_subset(
    pred68,
    ref_points,
    ibug_idx=MEDIAPIPE_SUBSET,
    norm_pair=(IBUG_RIGHT_EYE_OUTER, IBUG_LEFT_EYE_OUTER),
) -> np.ndarray:
    """NME of 68-point predictions on a subset of iBUG points, against a reference that has only that subset.

    Typical use: score a 68-point tracker against MediaPipe, ``nme_subset(pred, mediapipe_to_ibug(mp468))``.

    Parameters
    ----------
    pred68 : (..., 68, 2) array
        Predictions in iBUG-68 order (points outside ``ibug_idx`` are ignored and may be NaN).
    ref_points : (..., len(ibug_idx), 2) array
        Reference points in the order of ``ibug_idx``.
    ibug_idx : sequence of int
        iBUG indices of the reference points; default :data:`MEDIAPIPE_SUBSET`.
    norm_pair : (int, int)
        iBUG indices, both in ``ibug_idx``, whose reference distance normalises the error (default the outer eye
        corners 36 and 45, i.e. MediaPipe's 33 and 263 for a MediaPipe reference).

    Returns
    -------
    nme : (...) float64
        NaN where the prediction is NaN on any of the subset points.
    """
    pred68 = _points(pred68, "pred68")
    if pred68.shape[-2] != 68:
        raise ValueError(f"pred68: expected shape (..., 68, 2), got {pred68.shape}")
    ibug_idx = [int(i) for i in ibug_idx]
    try:
        left, right = (ibug_idx.index(int(i)) for i in norm_pair)
    except ValueError:
        raise ValueError(f"norm_pair {tuple(norm_pair)} must both be in ibug_idx {ibug_idx}") from None
    return nme(pred68[..., ibug_idx, :], ref_points, left=left, right=right)
