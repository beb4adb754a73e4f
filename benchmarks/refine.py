"""Benchmark of key point refinement and facial transfer on ICT FaceKit sequences (Akagi et al.).

    python benchmarks/refine.py [--frames N] [--identities K] [--json OUT]

Reports, in millimetres, per identity: the tracking error mean |D^t(F^0) - F^t| over all vertices and frames
1..T with the 68 landmarks as key points and after refinement, also over the face only (ICT vertices 0..9408,
without head and neck), and with the key points left where the registration's prior puts them (an ablation:
how much the GMM registration adds); the number of key points, the time per frame; the
transfer error to another identity against ground truth (identity B with the same expression weights; the source
is a shuffled random half of its vertices so only the 68 landmarks correspond); and the time of one GMM
registration of 10,000 points on one core (median of repeats; with the default GmmConfig the steps use a random
3,000 of the moving points per scale, so the figure with every point in every step is reported too). Compile
time is reported apart.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core: before numpy loads its BLAS
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aamtrack.refine import gmm  # noqa: E402
from aamtrack.refine.rbf import rbf_system  # noqa: E402
from aamtrack.refine.sampler import KeyPoints, SamplerConfig, deform_frames, mesh_spacing  # noqa: E402
from aamtrack.refine.sampler import refine_key_points  # noqa: E402
from aamtrack.refine.sequences import apply_weights, load_face_model, make_sequence  # noqa: E402
from aamtrack.refine.sequences import neutral_face, random_identity  # noqa: E402
from aamtrack.refine.transfer import transfer  # noqa: E402

ICT = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_face_light_head11248.npz"
CM_TO_MM = 10.0
N_FACE = 9409  # ICT FaceKit: vertices 0..9408 are the face, the rest head and neck (README_ICT.md)


def machine() -> dict:
    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"platform": platform.platform(), "cpu": cpu, "logical_cpus": os.cpu_count(),
            "python": platform.python_version(), "threads": os.environ.get("OMP_NUM_THREADS")}


def tracking(model, seed: int, n_frames: int) -> dict:
    seq = make_sequence(model, n_frames=n_frames, seed=seed)
    frames = seq.frames.astype(np.float64)
    lm = seq.landmark68
    rng = np.random.default_rng(seed)
    scans = [rng.permutation(f) for f in frames]  # point clouds: vertex order is not used
    only_landmarks = KeyPoints(lm, frames[:, lm], len(lm))
    err68 = np.linalg.norm(deform_frames(frames[0], only_landmarks)[1:] - frames[1:], axis=2)
    start = time.perf_counter()
    keys = refine_key_points(frames[0], scans, frames[:, lm], lm, config=SamplerConfig(seed=seed))
    elapsed = time.perf_counter() - start
    err = np.linalg.norm(deform_frames(frames[0], keys)[1:] - frames[1:], axis=2)
    # the prior alone (no registration): key points where the prediction/rigid-motion prior puts them
    prior_cfg = SamplerConfig(seed=seed, gmm=dataclasses.replace(SamplerConfig().gmm, anchor=1e6))
    keys_prior = refine_key_points(frames[0], scans, frames[:, lm], lm, config=prior_cfg)
    err_prior = np.linalg.norm(deform_frames(frames[0], keys_prior)[1:] - frames[1:], axis=2)
    moving = np.linalg.norm(frames - frames[0], axis=2).max(0) > 0.01  # vertices that move > 0.1 mm
    face = np.arange(frames.shape[1]) < N_FACE
    return {
        "seed": seed,
        "frames": n_frames,
        "motion_mean_mm": float(np.linalg.norm(frames[1:] - frames[0], axis=2).mean() * CM_TO_MM),
        "error_68_mm": float(err68.mean() * CM_TO_MM),
        "error_refined_mm": float(err.mean() * CM_TO_MM),
        "error_68_face_mm": float(err68[:, face].mean() * CM_TO_MM),
        "error_refined_face_mm": float(err[:, face].mean() * CM_TO_MM),
        "error_refined_head_neck_mm": float(err[:, ~face].mean() * CM_TO_MM),
        "error_prior_only_mm": float(err_prior.mean() * CM_TO_MM),
        "error_prior_only_face_mm": float(err_prior[:, face].mean() * CM_TO_MM),
        "error_68_moving_vertices_mm": float(err68[:, moving].mean() * CM_TO_MM),
        "error_refined_moving_vertices_mm": float(err[:, moving].mean() * CM_TO_MM),
        "error_refined_p95_mm": float(np.percentile(err, 95) * CM_TO_MM),
        "n_key_points": int(len(keys.index)),
        "rounds_accepted": len(keys.errors) - 1,
        "surface_errors_mm": [e * CM_TO_MM for e in keys.errors],
        "seconds_per_frame": elapsed / n_frames,
    }, seq


def transfer_case(model, seq, target_seed: int) -> dict:
    id_b = random_identity(model, np.random.default_rng(1000 + target_seed))
    target = neutral_face(model, id_b)
    rng = np.random.default_rng(target_seed)
    n = len(model.neutral)
    subset = rng.permutation(np.union1d(rng.choice(n, n // 2, replace=False), model.landmark68))
    where = {int(v): i for i, v in enumerate(subset)}
    s_lm = np.array([where[int(v)] for v in model.landmark68])
    start = time.perf_counter()
    result = transfer(seq.frames[:, subset], s_lm, target, model.landmark68)
    elapsed = time.perf_counter() - start
    truth = apply_weights(model, id_b, seq.weights)
    err = np.linalg.norm(result.frames[1:] - truth[1:], axis=2)
    naive = np.linalg.norm(target[None] - truth[1:], axis=2)  # leaving the target neutral
    return {"error_mm": float(err.mean() * CM_TO_MM), "error_p95_mm": float(np.percentile(err, 95) * CM_TO_MM),
            "error_if_not_moved_mm": float(naive.mean() * CM_TO_MM), "n_key_points": int(len(result.key_index)),
            "source_vertices": int(len(subset)), "seconds": elapsed, "seconds_per_frame": elapsed / len(truth)}


def gmm_10k(model, repeats: int = 11) -> dict:
    """Register 10,000 points of a neutral face (68 fixed + 100 free RBF control points) to 10,000 other points
    of an expressive frame of the same identity."""
    seq = make_sequence(model, n_frames=60, seed=7)
    motion = np.linalg.norm(seq.frames - seq.frames[0], axis=2).mean(1)
    t = int(np.argmax(motion))
    rng = np.random.default_rng(7)
    n = len(model.neutral)
    moving = rng.choice(n, 10_000, replace=False)
    scene = seq.frames[t][rng.choice(n, 10_000, replace=False)].astype(np.float64)
    neutral = seq.frames[0].astype(np.float64)
    free_keys = rng.choice(np.setdiff1d(np.arange(n), model.landmark68), 100, replace=False)
    keys = np.concatenate([model.landmark68, free_keys])
    operator = rbf_system(neutral[keys]).operator(neutral[moving])
    # start from the deformation the 68 landmarks give
    controls0 = rbf_system(neutral[model.landmark68]).operator(neutral[keys]) @ seq.frames[t][model.landmark68]
    free = np.arange(len(keys)) >= len(model.landmark68)
    spacing = mesh_spacing(neutral[moving])
    truth = seq.frames[t][moving]
    times, res = [], None
    gmm.register(operator, controls0, scene, spacing=spacing, free=free)  # untimed first run
    for _ in range(repeats):
        start = time.perf_counter()
        res = gmm.register(operator, controls0, scene, spacing=spacing, free=free)
        times.append(time.perf_counter() - start)
    truth = seq.frames[t][moving]
    full = gmm.GmmConfig(max_points=None)
    start = time.perf_counter()
    res_full = gmm.register(operator, controls0, scene, spacing=spacing, free=free, config=full)
    full_ms = (time.perf_counter() - start) * 1e3
    return {"points": 10_000, "control_points": len(keys), "median_ms": float(np.median(times) * 1e3),
            "config": repr(gmm.GmmConfig()), "repeats": repeats,
            "all_points_every_step_ms": full_ms,
            "all_points_every_step_error_after_mm": float(np.linalg.norm(res_full.moved - truth, axis=1).mean() * 10),
            "min_ms": float(np.min(times) * 1e3), "evaluations": res.n_evals,
            "error_before_mm": float(np.linalg.norm(operator @ controls0 - truth, axis=1).mean() * CM_TO_MM),
            "error_after_mm": float(np.linalg.norm(res.moved - truth, axis=1).mean() * CM_TO_MM)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=101, help="frames per sequence, F^0..F^{N-1} (default 101)")
    parser.add_argument("--identities", type=int, default=2, help="identities to track (default 2)")
    parser.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    if not ICT.exists():
        print(f"needs {ICT} (absent)", file=sys.stderr)
        return 2
    model = load_face_model(ICT)
    report = {"machine": machine()}
    start = time.perf_counter()
    gmm.warmup()
    report["compile_seconds"] = time.perf_counter() - start
    report["gmm_10k"] = gmm_10k(model)
    print(f"GMM registration of 10,000 points: {report['gmm_10k']['median_ms']:.0f} ms (median), "
          f"{report['gmm_10k']['error_before_mm']:.2f} -> {report['gmm_10k']['error_after_mm']:.2f} mm", flush=True)
    report["tracking"], report["transfer"] = [], []
    for i in range(args.identities):
        track, seq = tracking(model, seed=i, n_frames=args.frames)
        report["tracking"].append(track)
        print(f"identity {i}: tracking error {track['error_68_mm']:.3f} mm (68 landmarks) -> "
              f"{track['error_refined_mm']:.3f} mm ({track['n_key_points']} key points); face only "
              f"{track['error_68_face_mm']:.3f} -> {track['error_refined_face_mm']:.3f} mm; prior alone "
              f"{track['error_prior_only_mm']:.3f} mm, "
              f"{track['seconds_per_frame']:.2f} s/frame", flush=True)
        trans = transfer_case(model, seq, target_seed=i + 1)
        report["transfer"].append(trans)
        print(f"identity {i} -> other identity: transfer error {trans['error_mm']:.3f} mm "
              f"(not moving the target: {trans['error_if_not_moved_mm']:.3f} mm), {trans['seconds']:.1f} s",
              flush=True)
    report["summary"] = {
        "tracking_error_68_mm": float(np.mean([t["error_68_mm"] for t in report["tracking"]])),
        "tracking_error_refined_mm": float(np.mean([t["error_refined_mm"] for t in report["tracking"]])),
        "tracking_error_68_face_mm": float(np.mean([t["error_68_face_mm"] for t in report["tracking"]])),
        "tracking_error_refined_face_mm": float(np.mean([t["error_refined_face_mm"] for t in report["tracking"]])),
        "tracking_error_prior_only_mm": float(np.mean([t["error_prior_only_mm"] for t in report["tracking"]])),
        "n_key_points": [t["n_key_points"] for t in report["tracking"]],
        "seconds_per_frame": float(np.mean([t["seconds_per_frame"] for t in report["tracking"]])),
        "gmm_10k_median_ms": report["gmm_10k"]["median_ms"],
        "transfer_error_mm": float(np.mean([t["error_mm"] for t in report["transfer"]])),
        "goal_tracking_below_1mm": bool(np.mean([t["error_refined_mm"] for t in report["tracking"]]) < 1.0),
        "goal_transfer_below_1mm": bool(np.mean([t["error_mm"] for t in report["transfer"]]) < 1.0),
        "goal_gmm_10k_below_100ms": bool(report["gmm_10k"]["median_ms"] < 100.0),
    }
    print(json.dumps({"machine": report["machine"], "summary": report["summary"]}, indent=2))
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
