"""Single-image active search from a displaced start.

For each test image: the ground-truth fit of the model to the human landmarks (pose, coefficients, and sigma
for 3D), displaced by 10% of the face width (random direction) and 10 degrees of roll (random sign); then one
multi-resolution search. Prints mean NME (68 points / outer eye-corner distance) before and after, and the share
of faces ending below NME 0.08, and the mean NME after by region (``metrics.IBUG_REGIONS``: jaw, brows, nose,
eyes, mouth, each over its own points, normalised as the whole).

    python benchmarks/search_accuracy.py --model models/3d.npz --data ../shared/data/300w/helen_test
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from aamtrack.io.dataset import find_pairs, load_pair
from aamtrack.metrics import IBUG_REGIONS, PIXEL_ORIGIN, nme, nme_by_region
from aamtrack.model import load_model
from aamtrack.imaging import to_gray32
from aamtrack.search import Searcher
from aamtrack.train.shape_fit import fit_landmarks


def displaced_start(q: np.ndarray, face_px: float, rng: np.random.Generator, *, shift: float = 0.10,
                    roll_deg: float = 10.0) -> np.ndarray:
    q0 = q.copy()
    ang = rng.uniform(0, 2 * np.pi)
    q0[4] += shift * face_px * np.cos(ang)
    q0[5] += shift * face_px * np.sin(ang)
    q0[2] += np.radians(roll_deg) * rng.choice([-1.0, 1.0])
    return q0


def evaluate(model_path: Path, data: Path, *, limit: int | None = None, seed: int = 0) -> dict:
    model = load_model(model_path)
    searcher = Searcher(model)
    sm = model.shape
    rng = np.random.default_rng(seed)
    pairs = find_pairs(data)[:limit]
    before, after, times, regions = [], [], [], []
    for img_path, pts_path in pairs:
        img, pts = load_pair(img_path, pts_path)
        pts = pts - PIXEL_ORIGIN  # the search works in OpenCV's pixels (``train_model``); the labels are 1-based
        gt = fit_landmarks(sm, pts)
        face_px = np.ptp(pts[:, 0])
        q0 = displaced_start(gt.q, face_px, rng)
        pyr = searcher.levels(to_gray32(img))
        sigma = gt.shape_params if sm.n_shape else None  # the person's shape held at the labels' fit
        t = time.perf_counter()
        res = searcher.fit(pyr, np.r_[q0, gt.shape_params], sigma)
        times.append(time.perf_counter() - t)
        before.append(nme(sm.landmarks(q0, gt.shape_params), pts))
        after.append(nme(res.landmarks, pts))
        regions.append(nme_by_region(res.landmarks, pts))
    before, after = np.array(before), np.array(after)
    return {"model": str(model_path), "kind": model.kind, "images": len(pairs),
            "nme_before_mean": float(before.mean()), "nme_after_mean": float(after.mean()),
            "nme_after_median": float(np.median(after)), "share_below_0.08": float((after < 0.08).mean()),
            "search_ms_median": 1e3 * float(np.median(times)),
            "nme_after_by_region": {k: float(np.mean([r[k] for r in regions])) for k in IBUG_REGIONS}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, action="append", required=True)
    ap.add_argument("--data", type=Path, default=Path("../shared/data/300w/helen_test"))
    ap.add_argument("--limit", type=int)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rows = [evaluate(m, args.data, limit=args.limit) for m in args.model]
    print(f"{'model':<20}{'images':>7}{'NME before':>12}{'NME after':>11}{'median':>9}{'<0.08':>8}{'ms':>8}"
          + "".join(f"{k:>8}" for k in IBUG_REGIONS))
    for r in rows:
        print(f"{Path(r['model']).name:<20}{r['images']:>7}{r['nme_before_mean']:>12.4f}{r['nme_after_mean']:>11.4f}"
              f"{r['nme_after_median']:>9.4f}{100 * r['share_below_0.08']:>7.1f}%{r['search_ms_median']:>8.2f}"
              + "".join(f"{r['nme_after_by_region'][k]:>8.4f}" for k in IBUG_REGIONS))
    print("(the regions' columns: NME after over each region's points, normalised as the whole)")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "search_accuracy")
