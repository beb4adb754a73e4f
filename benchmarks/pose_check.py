"""Head pose on synthetic renders of a textured face at known poses (the 3D model's pose check).

A real face (a helen_test image: held out from training, whose face profiling turns helen_train faces by the
same rasteriser) is fitted by the 3D model as a still (Haar detection + ``Tracker.fit_roi``), which picks the
near-frontal faces the model fits well, and the image becomes the mesh's texture (``--source``): by default
("warped") at the model's landmark fit to the photo's human labels (pose, animation units, shape units), the
photo's pixels moved by a thin-plate spline that takes each labelled point onto its fitted landmark, so the
render's 68 labelled features lie on the truth's landmarks (within a pixel, tests/test_pose_check.py) and the
pose error is the tracker's own; "labels": at that landmark fit, not moved (the features lie off the truth by
the fit's residual: 1.3 / 3.4 px on average on the first two faces, markers drawn at the labels); "search": at
the search's own fit (3.0 / 3.8 px; the check before the twenty-ninth session). The textured mesh is then
rendered at known poses (yaw, pitch, roll; with and without an expression) into a noise (or plain) background
by a painter's rasteriser: triangles sorted back to front by depth, back faces culled, each one an affine warp
of its source triangle (cv2.warpAffine + a triangle mask). Only the mesh region appears, with a band around its
jaw (``--band``, below; no ears or shoulders), and texture hidden or foreshortened in the source photo is
stretched: the renders are easier than real heads in that the background is plain, and harder in that the
head's edge is a hard cut.

The band: Candide's mesh ends inside the face, about a tenth of the face width inside the labelled jaw line, so
a render of the mesh alone puts the 17 jaw landmarks' truth on the background, past the drawn face's edge, and a
landmark detector reads the jaw at that edge instead (sample clip's tracker on frontal renders of two faces: jaw
points 4.6 px above their truth on average, 0.07 px with the band). ``--band B`` draws, with the mesh, a strip
out to a ring of vertices each jaw landmark pushed B of its distance from the landmarks' centroid away from it
(``aamtrack.mesh.skirt.with_skirt``, the model's own texture band, here round the whole jaw 0-16): the photo's
surroundings of the jaw (neck, hair, background) beyond it. 0 renders the mesh alone (the check before
2026-11-28). The figures depend on B by about a degree (video geodesic median, 2 faces, axes grid: 4.1 / 5.2 /
5.6 degrees at B = 0.12 / 0.25 / 0.4, 6.5 at 0): B = 0.25 was chosen before those were measured, for a jaw
line well inside the drawn head.

Measurements per pose (the first three are the check; the fourth is a diagnostic):
- fit: the render as ``aamtrack fit`` fits a still (``Tracker.fit_still``: Haar detection, several starts, the
  landmark pass; without the mirrored copy, whose fit changes the points, not the pose reported);
- still: one ``Searcher.fit`` from the true position and scale but a frontal pose (rotation 0, animation
  units and shape units 0; the shape units are searched);
- video: ~30 frames turning smoothly (smoothstep) from frontal to the pose, the expression ramping with it,
  tracked by ``Tracker.track`` from a Haar detection; error at the last frame (a lost last frame is counted
  apart, not in the error statistics);
- from truth: one ``Searcher.fit`` started at the true pose and expression with the shape units pinned to the
  source fit's: the error is how far the search's fixed point lies from the truth (its bias), apart from
  capture range.
Errors: per axis |estimated - true| (degrees; rx = pitch, ry = yaw, rz = roll, the model's R = Rz Ry Rx) and
the geodesic angle between R_est and R_true; median and p95 over the grid per condition.

A drift check tracks 100 identical frames of a frontal, neutral render and reports per axis the drift
max |angle - frame 0's| (degrees), and the geodesic error to the truth at the first and last frames.

    python benchmarks/pose_check.py --model models/3d.npz [--faces 3] [--grid axes|full] [--json OUT]
    python benchmarks/pose_check.py --model models/3d.npz --sweep 80 --frames 200 [--faces 3]   (turned faces)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_name, write_json  # noqa: E402

from aamtrack.mesh.render import orient_triangles, posed, render_mesh  # noqa: E402
from aamtrack.mesh.skirt import JAW, with_skirt  # noqa: E402

TARGET_MEDIAN_DEG = 2.0  # goal: median angle error <= 2 degrees over the pose grid
TARGET_P95_DEG = 5.0  # ... and p95 <= 5 degrees
YAWS = (-45, -30, -15, 0, 15, 30, 45)
PITCHES = (-30, -15, 0, 15, 30)
ROLLS = (-30, 0, 30)
EXPRESSION = {"jaw_drop": 0.5, "lip_stretcher": 0.5}
CANVAS = 360  # rendered frames are CANVAS x CANVAS
FACE_WIDTH_PX = 160.0  # frontal width of the mean mesh in the renders
METHODS = ("fit", "still", "video", "from_truth")  # the measurements per pose (module docstring)
LABEL_FIT_STEPS = 30  # Gauss-Newton steps of the texture's landmark fit to the labels (``source_faces``)
BAND = 0.25  # the drawn head reaches this share beyond the jaw landmarks (module docstring; 0: the mesh alone)


# -- geometry -----------------------------------------------------------------------------------------------
def rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    """(3, 3) R = Rz @ Ry @ Rx (radians), the model's convention."""
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def geodesic_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Angle (degrees) of the rotation R_a^T R_b."""
    c = (np.trace(R_a.T @ R_b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def angle_errors(est, true) -> dict:
    """Per-axis |est - true| (degrees, wrapped to 180) and the geodesic angle, from radians (rx, ry, rz)."""
    d = np.degrees(np.asarray(est[:3], float) - np.asarray(true[:3], float))
    d = np.abs((d + 180.0) % 360.0 - 180.0)
    return {"pitch": float(d[0]), "yaw": float(d[1]), "roll": float(d[2]),
            "geodesic": geodesic_deg(rotation(*est[:3]), rotation(*true[:3]))}


# -- rendering ----------------------------------------------------------------------------------------------
def make_background(kind: str, rng: np.random.Generator, shape=(CANVAS, CANVAS, 3)) -> np.ndarray:
    """uint8 background: "plain" mid grey, or "noise" (grey noise blurred to ~3 px blobs)."""
    if kind == "plain":
        return np.full(shape, 128, np.uint8)
    noise = rng.normal(128, 60, shape[:2]).astype(np.float32)
    noise = cv2.GaussianBlur(noise, (0, 0), 1.5)
    noise = (noise - noise.mean()) * (40.0 / max(noise.std(), 1e-6)) + 128
    return np.repeat(np.clip(noise, 0, 255).astype(np.uint8)[:, :, None], shape[2], axis=2)


# -- the face -----------------------------------------------------------------------------------------------
class TexturedFace:
    """One source photo fitted by the model: ``render(q)`` draws the textured mesh at q = [rx, ry, rz, s, tx,
    ty, anim coefficients] (the person's fitted shape units held)."""

    def __init__(self, model, image: np.ndarray, fit_p: np.ndarray, name: str, *, band: float = BAND,
                 points: np.ndarray | None = None):
        sm = model.shape
        self.image, self.name = image, name
        self.sigma = fit_p[sm.n_q:].copy()
        self.src_p = fit_p.copy()
        triangles = sm.triangles
        if band > 0:  # the ring's vertices come after the model's, so the model's landmark map still applies
            sm, strip = with_skirt(sm, sm.triangles, band, JAW)
            triangles = np.vstack([triangles, strip])
        self.sm = sm
        self.src_uv = self.view(fit_p[:model.shape.n_q])[0]  # where each vertex sits in the photo: the fit's projection
        if points is not None:  # moved so the photo's labelled points fall on the model's landmarks (``source_faces``)
            from scipy.interpolate import RBFInterpolator

            fitted = model.shape.landmarks(fit_p[:model.shape.n_q], self.sigma)
            move = RBFInterpolator(fitted, np.asarray(points, float) - fitted, kernel="thin_plate_spline")
            self.src_uv = self.src_uv + move(self.src_uv)
        self.triangles = orient_triangles(triangles, sm.mean)

    def view(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return posed(self.sm.shape3d(q, self.sigma), q)

    def render(self, q: np.ndarray, background: np.ndarray) -> np.ndarray:
        uv, z = self.view(q)
        return render_mesh(self.image, self.src_uv, uv, z, self.triangles, background)[0]


def source_faces(model, data: Path, n_faces: int, *, max_angle_deg: float = 10.0, max_nme: float = 0.06,
                 band: float = BAND, source: str = "warped") -> list:
    """The first ``n_faces`` photos of ``data`` (sorted by name) that the model fits confidently, near
    frontal (|rx|, |ry|, |rz| <= max_angle_deg) and close to the human labels (NME <= max_nme). The texture is
    taken at ``source`` (module docstring): "warped", the model's landmark fit (pose, coefficients, shape units)
    to the photo's human labels with the photo moved so the labels fall on the fitted landmarks; "labels", that
    fit alone; "search", the search's own fit (the check before the twenty-ninth session, 2026-11-28). None fitted
    so: one line (SystemExit), for the grid and the sweep alike."""
    from aamtrack.io.dataset import find_pairs, load_pair
    from aamtrack.mesh.landmark_fit import LandmarkFitter
    from aamtrack.metrics import PIXEL_ORIGIN, nme
    from aamtrack.track.tracker import Tracker

    tracker = Tracker(model)
    fitter = LandmarkFitter(model.shape)
    out = []
    for img_path, pts_path in find_pairs(data):
        img, pts = load_pair(img_path, pts_path)
        if img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        box = tracker.detector.detect(img)
        if box is None:
            continue
        # the mesh's own landmarks (no landmark cascade): the texture is taken where the mesh sits
        res, _ = tracker.fit_roi(img, tracker.detection_starts(box), landmarks=False)
        if (res.confidence < tracker.config.min_confidence or np.degrees(np.abs(res.p[:3])).max() > max_angle_deg
                or float(nme(res.landmarks, pts)) > max_nme):
            continue
        p, labels = res.p, pts - PIXEL_ORIGIN  # (the labels in OpenCV's pixels, as the model works)
        if source != "search":
            p = fitter.refit(p, labels, LABEL_FIT_STEPS, fit_sigma=True)
        out.append(TexturedFace(model, img, p, img_path.name, band=band,
                                points=labels if source == "warped" else None))
        if len(out) == n_faces:
            break
    if not out:
        raise SystemExit(f"no image in {data} was fitted near frontal to use as a texture")
    return out


def pose_grid(kind: str) -> list[tuple[int, int, int]]:
    """(pitch, yaw, roll) degrees. "full": the whole product; "axes": each axis alone, plus the corners of
    yaw +-30/pitch +-15 and yaw +-30/roll +-30 and two 3-axis combinations."""
    if kind == "full":
        return [(p, y, r) for y in YAWS for p in PITCHES for r in ROLLS]
    g = [(0, y, 0) for y in YAWS] + [(p, 0, 0) for p in PITCHES if p] + [(0, 0, r) for r in ROLLS if r]
    g += [(p, y, 0) for p in (-15, 15) for y in (-30, 30)] + [(0, y, r) for r in (-30, 30) for y in (-30, 30)]
    g += [(15, 30, 30), (-15, -30, -30)]
    return g


def true_q(model, face: TexturedFace, pose_deg, expression: bool, t: float = 1.0) -> np.ndarray:
    """Search-vector pose part [rx, ry, rz, s, tx, ty, anim] for pose_deg = (pitch, yaw, roll) at fraction t."""
    sm = model.shape
    q = np.zeros(sm.n_q)
    q[:3] = np.radians(pose_deg) * t
    q[3] = FACE_WIDTH_PX / sm.frontal_width()
    q[4], q[5] = CANVAS / 2, CANVAS / 2 + 0.05 * FACE_WIDTH_PX
    if expression:
        for name, v in EXPRESSION.items():
            q[6 + sm.coef_names.index(name)] = v * t
    return q


def run(model_path: Path, data: Path, *, n_faces: int, grid: str, n_frames: int, drift_frames: int,
        background: str, limit: int | None, seed: int = 0, band: float = BAND, source: str = "warped",
        progress=print) -> dict:
    from aamtrack.imaging import to_gray32
    from aamtrack.model import load_model
    from aamtrack.search import Searcher
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import Tracker

    model = load_model(model_path)
    sm = model.shape
    for name in EXPRESSION:
        if name not in sm.coef_names:
            raise SystemExit(f"{model_path}: no animation unit {name!r} for the expression")
    searcher = Searcher(model)
    tracker = Tracker(model)  # (a track's state lives in its generator: one tracker serves every fit and video)
    rng = np.random.default_rng(seed)
    faces = source_faces(model, data, n_faces, band=band, source=source)
    poses = pose_grid(grid)[:limit]
    rows = []
    t_start = time.perf_counter()
    for face in faces:
        for expression in (False, True):
            for pose in poses:
                bg = make_background(background, rng)
                q = true_q(model, face, pose, expression)
                img = face.render(np.r_[q], bg)
                p0 = np.zeros(searcher.n_params)
                p0[3:6] = q[3:6]
                res = searcher.fit(searcher.levels(to_gray32(img)), p0)
                row = {"face": face.name, "expression": expression, "pitch": pose[0], "yaw": pose[1],
                       "roll": pose[2], "still": angle_errors(res.p, q), "still_confidence": res.confidence,
                       "still_estimate_deg": np.degrees(res.p[:3]).tolist()}
                fit = tracker.fit_still(ReplayFrame(0, 0.0, img), mirror=False)
                row["fit"] = angle_errors(fit.rotation, q) if fit.success else None
                row["fit_estimate_deg"] = np.degrees(fit.rotation).tolist()
                # diagnostic: start at the truth, the person's shape units pinned: where the search's fixed point is
                res = searcher.fit(searcher.levels(to_gray32(img)), np.r_[q, face.sigma], face.sigma)
                row["from_truth"] = angle_errors(res.p, q)
                row["from_truth_estimate_deg"] = np.degrees(res.p[:3]).tolist()
                ts = 0.5 - 0.5 * np.cos(np.pi * np.linspace(0, 1, n_frames))  # smoothstep 0 -> 1
                frames = [ReplayFrame(i, i / 25.0, face.render(true_q(model, face, pose, expression, t), bg))
                          for i, t in enumerate(ts)]
                results = list(tracker.track(frames))
                last = results[-1]
                row["video_status"] = last.status
                row["video_lost_frames"] = sum(not r.success for r in results)
                row["video"] = angle_errors(last.rotation, q) if last.success else None
                row["video_estimate_deg"] = np.degrees(last.rotation).tolist()
                rows.append(row)
            progress(f"{face.name} expression={expression}: {len(poses)} poses, "
                     f"{time.perf_counter() - t_start:.0f} s so far")
    drift = []
    for face in faces:
        q = true_q(model, face, (0, 0, 0), False)
        img = face.render(q, make_background(background, rng))
        results = list(tracker.track(ReplayFrame(i, i / 25.0, img) for i in range(drift_frames)))
        ok = [r for r in results if r.success]
        rot = np.degrees(np.array([r.rotation for r in ok])) if ok else np.zeros((0, 3))
        d = np.abs(rot - rot[0]).max(0) if ok else np.full(3, np.nan)
        err0 = angle_errors(ok[0].rotation, q)["geodesic"] if ok else float("nan")
        err1 = angle_errors(ok[-1].rotation, q)["geodesic"] if ok else float("nan")
        drift.append({"face": face.name, "frames": drift_frames, "tracked": len(ok), "pitch_drift": float(d[0]),
                      "yaw_drift": float(d[1]), "roll_drift": float(d[2]), "first_frame_geodesic": err0,
                      "last_frame_geodesic": err1,
                      "pitch_yaw_roll_deg": rot.tolist()})
    return {"model": str(model_path), "machine": machine_name(), "grid": grid, "band": band, "source": source,
            "poses": len(poses),
            "faces": [f.name for f in faces], "n_frames": n_frames, "background": background, "rows": rows,
            "summary": summarise(rows), "bias": bias_by_angle(rows), "drift": drift}


SWEEP_BIN_DEG = 15  # the sweep's table: frames grouped by |true yaw| in bins this wide
SWEEP_WRONG = 0.10  # a tracked frame further off than this (frontal eye units) counts as wrong


def sweep(model_path: Path, data: Path, *, n_faces: int, amplitude: float, n_frames: int, background: str,
          seed: int = 0, band: float = BAND, source: str = "warped", progress=print) -> dict:
    """Turned faces (``--sweep``): each face's video turns its yaw as amplitude sin(2 pi t / n_frames), frontal to
    +amplitude, back, to -amplitude and back (no pitch, roll or expression), tracked by ``Tracker.track`` from a
    Haar detection. Per frame: status, confidence, the reported yaw and the landmarks' mean error against the
    render's own (the model's landmarks at the true pose) over the frontal render's outer eye-corner distance
    (the projected eye distance shrinks with cos(yaw), which would inflate a turned face's error 3x at 70
    degrees). The renders past about 60 degrees are harder than real heads (no ear, hair or back of the head:
    the mesh ends at the face's side, against the background), so the far bins say how the tracker fails, not
    how often it would on real footage."""
    from aamtrack.metrics import eye_distance
    from aamtrack.model import load_model
    from aamtrack.track.replay import ReplayFrame
    from aamtrack.track.tracker import Tracker

    model = load_model(model_path)
    if model.kind != "3d":  # (its shape has no depth: the renders would not turn, nor the truth's points)
        raise SystemExit(f"{model_path}: a {model.kind} model; the sweep turns the 3D model's mesh")
    tracker = Tracker(model)
    rng = np.random.default_rng(seed)
    faces = source_faces(model, data, n_faces, band=band, source=source)
    yaws = amplitude * np.sin(2 * np.pi * np.arange(n_frames) / n_frames)
    rows = []
    t_start = time.perf_counter()
    for face in faces:
        bg = make_background(background, rng)
        eye = float(eye_distance(model.shape.landmarks(true_q(model, face, (0, 0, 0), False), face.sigma)))
        qs = [true_q(model, face, (0, y, 0), False) for y in yaws]
        frames = [ReplayFrame(i, i / 25.0, face.render(q, bg)) for i, q in enumerate(qs)]
        for q, y, r in zip(qs, yaws, tracker.track(frames), strict=True):
            truth = model.shape.landmarks(q, face.sigma)
            rows.append({"face": face.name, "yaw": float(y), "status": r.status, "success": bool(r.success),
                         "confidence": float(r.confidence),
                         "yaw_estimate": float(np.degrees(r.rotation[1])) if r.success else None,
                         "error": float(np.linalg.norm(r.landmarks - truth, axis=1).mean() / eye)
                         if r.success else None})
        progress(f"{face.name}: {n_frames} frames, {time.perf_counter() - t_start:.0f} s so far")
    return {"model": str(model_path), "machine": machine_name(), "amplitude": amplitude, "frames": n_frames,
            "faces": [f.name for f in faces], "background": background, "band": band, "source": source,
            "rows": rows, "bins": sweep_bins(rows)}


def sweep_bins(rows: list[dict], width: float = SWEEP_BIN_DEG, wrong: float = SWEEP_WRONG) -> list[dict]:
    """The sweep's frames grouped by |true yaw| in bins ``width`` degrees wide: frames, tracked, the mean error
    and confidence over the tracked ones, how many of them are off by more than ``wrong`` (tracked, reported
    confident, and wrong) and the median |reported - true yaw| (degrees)."""
    out = []
    for k in sorted({int(abs(r["yaw"]) // width) for r in rows}):
        sel = [r for r in rows if int(abs(r["yaw"]) // width) == k]
        ok = [r for r in sel if r["success"]]
        err = np.array([r["error"] for r in ok])
        out.append({"from": k * width, "to": (k + 1) * width, "frames": len(sel), "tracked": len(ok),
                    "error_mean": float(err.mean()) if ok else None,
                    "wrong": int((err > wrong).sum()),
                    "confidence_mean": float(np.mean([r["confidence"] for r in ok])) if ok else None,
                    "yaw_error_median": float(np.median([abs(r["yaw_estimate"] - r["yaw"]) for r in ok]))
                    if ok else None})
    return out


def sweep_table(report: dict) -> str:
    def f(v, fmt):
        return "-" if v is None else format(v, fmt)

    lines = [f"| abs(yaw) degrees | frames | tracked | mean error (tracked) | tracked above {SWEEP_WRONG:g} "
             "| mean confidence (tracked) | median abs(yaw error) |", "|" + "---|" * 7]
    for b in report["bins"]:
        lines.append(f"| {b['from']:.0f}-{b['to']:.0f} | {b['frames']} | {b['tracked']} | {f(b['error_mean'], '.3f')} "
                     f"| {b['wrong']} | {f(b['confidence_mean'], '.2f')} | {f(b['yaw_error_median'], '.1f')} |")
    return "\n".join(lines)


def summarise(rows: list[dict]) -> list[dict]:
    """Median and p95 of each error per (method, expression), over the grid and faces."""
    out = []
    for method in METHODS:
        for expression in (False, True):
            sel = [r for r in rows if r["expression"] == expression]
            errs = [r[method] for r in sel if r[method] is not None]
            s = {"method": method, "expression": expression, "n": len(sel), "lost": len(sel) - len(errs)}
            for key in ("pitch", "yaw", "roll", "geodesic"):
                v = np.array([e[key] for e in errs]) if errs else np.full(1, np.nan)
                s[f"{key}_median"], s[f"{key}_p95"] = float(np.median(v)), float(np.percentile(v, 95))
            s["target_met"] = bool(s["geodesic_median"] <= TARGET_MEDIAN_DEG and s["geodesic_p95"] <= TARGET_P95_DEG
                                   and s["lost"] == 0)
            out.append(s)
    return out


def bias_by_angle(rows: list[dict]) -> list[dict]:
    """Median signed error (estimate - true, degrees) of each axis at each of its true values (over the other
    axes, faces and expressions), per method: shows whether an axis is under- or over-estimated."""
    out = []
    for axis, k in (("pitch", 0), ("yaw", 1), ("roll", 2)):
        for v in sorted({r[axis] for r in rows}):
            sel = [r for r in rows if r[axis] == v]
            s = {"axis": axis, "true": v, "n": len(sel)}
            for method in METHODS:
                d = [r[f"{method}_estimate_deg"][k] - v for r in sel if r[method] is not None]
                s[method] = float(np.median(d)) if d else float("nan")
            out.append(s)
    return out


def table(report: dict) -> str:
    lines = ["| method | expression | poses x faces | lost | pitch med / p95 | yaw med / p95 | roll med / p95 "
             "| geodesic med / p95 | target (<= 2 / 5) |", "|" + "---|" * 9]
    for s in report["summary"]:
        cells = [f"{s[k + '_median']:.2f} / {s[k + '_p95']:.2f}" for k in ("pitch", "yaw", "roll", "geodesic")]
        lines.append(f"| {s['method']} | {'yes' if s['expression'] else 'no'} | {s['n']} | {s['lost']} | "
                     + " | ".join(cells) + f" | {'met' if s['target_met'] else 'not met'} |")
    lines += ["", "| axis | true | n | median (est - true): fit | still | video | from truth |",
              "|---|---|---|---|---|---|---|"]
    for b in report["bias"]:
        lines.append(f"| {b['axis']} | {b['true']:+d} | {b['n']} | {b['fit']:+.2f} | {b['still']:+.2f} "
                     f"| {b['video']:+.2f} | {b['from_truth']:+.2f} |")
    lines += ["", "| drift: face | frames tracked | pitch drift | yaw drift | roll drift | geodesic error frame 0 "
              "| last frame |", "|---|---|---|---|---|---|---|"]
    for d in report["drift"]:
        lines.append(f"| {d['face']} | {d['tracked']}/{d['frames']} | {d['pitch_drift']:.2f} | {d['yaw_drift']:.2f} "
                     f"| {d['roll_drift']:.2f} | {d['first_frame_geodesic']:.2f} | {d['last_frame_geodesic']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=Path("models/3d.npz"))
    ap.add_argument("--data", type=Path, default=Path("../shared/data/300w/helen_test"))
    ap.add_argument("--faces", type=int, default=3, help="source photos (textures)")
    ap.add_argument("--grid", choices=("axes", "full"), default="axes")
    ap.add_argument("--frames", type=int, default=30, help="frames of each video, frontal to the pose")
    ap.add_argument("--drift-frames", type=int, default=100)
    ap.add_argument("--background", choices=("noise", "plain"), default="noise")
    ap.add_argument("--limit", type=int, help="first N poses of the grid only")
    ap.add_argument("--band", type=float, default=BAND,
                    help=f"the drawn head reaches this share beyond the jaw line (default {BAND}; 0: the mesh alone)")
    ap.add_argument("--source", choices=("warped", "labels", "search"), default="warped",
                    help="the texture: warped so the photo's labelled points sit on the model's landmarks (default), "
                         "at the model's landmark fit to the labels, or at the search's own fit")
    ap.add_argument("--sweep", type=float, metavar="DEGREES",
                    help="instead of the grid: each face turning its yaw to +-DEGREES and back over --frames "
                         "frames (turned faces: tracked share, error and confidence by yaw)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    if not 0 <= args.band <= 1:
        ap.error(f"--band {args.band}: between 0 and 1")
    from aamtrack.errors import AamtrackError

    if args.sweep is not None and not 0 < args.sweep < 90:
        ap.error(f"--sweep {args.sweep:g}: degrees between 0 and 90")

    def say(text):
        print(text, file=sys.stderr)

    try:
        if args.sweep is not None:
            report = sweep(args.model, args.data, n_faces=args.faces, amplitude=args.sweep, n_frames=args.frames,
                           background=args.background, band=args.band, source=args.source, progress=say)
        else:
            report = run(args.model, args.data, n_faces=args.faces, grid=args.grid, n_frames=args.frames,
                         drift_frames=args.drift_frames, background=args.background, limit=args.limit,
                         band=args.band, source=args.source, progress=say)
    except AamtrackError as e:  # unreadable model or data: one line, no traceback
        print(f"pose_check: {e}", file=sys.stderr)
        return 2
    if args.sweep is not None:
        print(f"model {report['model']}, yaw sweep to +-{report['amplitude']:g} degrees over {report['frames']} "
              f"frames x {len(report['faces'])} faces ({', '.join(report['faces'])}), {report['background']} "
              f"background; error: mean landmark distance to the render's / frontal outer eye-corner distance; "
              f"machine: {report['machine']}\n")
        print(sweep_table(report))
    else:
        print(f"model {report['model']}, {report['poses']} poses ({report['grid']} grid) x {len(report['faces'])} "
              f"faces ({', '.join(report['faces'])}), {report['background']} background, band {report['band']:g}; "
              f"machine: {report['machine']}")
        print("angle errors in degrees (pitch = rx, yaw = ry, roll = rz; geodesic = angle of R_est^T R_true)\n")
        print(table(report))
    if args.json:
        write_json(args.json, report)
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "pose_check")
