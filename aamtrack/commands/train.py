"""``aamtrack train --data DIR --kind 3d|2d --out PATH``: learn a model from images with iBUG .pts files."""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..errors import InputError
from ..io.atomic import atomic_write
from ..io.dataset import find_pairs, load_pair
from ..mesh.candide import read_wfm
from ..model import save_model
from ..models import default_candide_path
from ..train.pipeline import TrainConfig, train_model


def register(sub) -> None:
    p = sub.add_parser("train", help="train a 2D or 3D model from annotated images",
                       description="Learn shape, mean texture and update matrices from a folder of images, each "
                                   "with an iBUG .pts file (68 points) of the same name.",
                       epilog="examples:\n"
                              "  aamtrack train --data ../shared/data/300w/helen_train --kind 2d --out my2d.npz\n"
                              "  aamtrack train --data faces/ --kind 3d --candide candide3.wfm --out my3d.npz\n"
                              "  aamtrack run clip.mp4 --model my2d.npz            track with the new model\n\n"
                              "Without --out the model goes to ./aamtrack_<kind>.npz (never over an existing file,\n"
                              "so never over a shipped model).",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", required=True, type=Path, help="folder of images + .pts files")
    p.add_argument("--kind", choices=("3d", "2d"), default="3d", help="3D Candide-3 model or 2D 68-point model")
    p.add_argument("--out", type=Path, help="model file to write (default: aamtrack_<kind>.npz in the current folder, "
                   "numbered aamtrack_<kind>_2.npz, ... rather than overwrite a file)")
    p.add_argument("--candide", type=Path, help="Candide-3 .wfm file for --kind 3d (default: "
                   "../shared/data/candide3/candide3.wfm next to the project, if present)")
    p.add_argument("--couples", help="couples as FACE_PX:TEX_WIDTH,... coarse to fine (default 32:20,64:32,128:48)")
    p.add_argument("--report", type=Path, help="write each image's shape-fit residual (px) to this CSV")
    p.set_defaults(func=run)


def _parse_couples(text: str | None) -> tuple:
    if not text:
        return TrainConfig().couples
    try:
        couples = tuple(tuple(int(v) for v in item.split(":")) for item in text.split(","))
        if any(len(c) != 2 or c[1] > c[0] or c[1] < 4 for c in couples):
            raise ValueError
    except ValueError:
        raise InputError(f"--couples {text!r}: expected FACE_PX:TEX_WIDTH pairs with 4 <= TEX_WIDTH <= FACE_PX") from None
    return couples


def default_out(kind: str, folder: Path | None = None) -> Path:
    """``aamtrack_<kind>.npz`` in ``folder`` (default: the current one), numbered ``_2``, ``_3``, ... past existing
    files: a default can neither overwrite an earlier model nor a shipped one (named ``<kind>.npz``)."""
    folder = Path.cwd() if folder is None else folder
    out, n = folder / f"aamtrack_{kind}.npz", 1
    while out.exists():
        n += 1
        out = folder / f"aamtrack_{kind}_{n}.npz"
    return out


def run(args: argparse.Namespace) -> int:
    out = args.out or default_out(args.kind)
    if out.exists() and out.is_dir():
        raise InputError(f"{out}: is a folder, expected a model file name")
    if not out.parent.exists():
        raise InputError(f"{out.parent}: output folder does not exist")
    config = TrainConfig(couples=_parse_couples(args.couples))
    candide = None
    if args.kind == "3d":
        path = args.candide or default_candide_path()
        if path is None:
            raise InputError("--kind 3d needs the Candide-3 mesh: pass --candide path/to/candide3.wfm")
        candide = read_wfm(path)
    pairs = find_pairs(args.data)
    images, points = [], []
    for img_path, pts_path in tqdm(pairs, desc="read", unit="img", file=sys.stderr, disable=None):
        img, pts = load_pair(img_path, pts_path)
        images.append(img)
        points.append(pts)
    t0 = time.perf_counter()
    model, report = train_model(images, np.array(points), args.kind, candide=candide, config=config,
                                names=tuple(p[0].name for p in pairs),
                                progress=lambda it, **kw: tqdm(it, file=sys.stderr, disable=None, **kw))
    save_model(model, out)
    if args.report:
        with atomic_write(args.report, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["image", "fit_rms_px"])
            w.writerows((n, f"{r:.3f}") for n, r in zip(report.names, report.fit_rms_px, strict=True))
    r = report.fit_rms_px
    print(f"trained {args.kind} model on {len(images)} images in {time.perf_counter() - t0:.1f} s -> {out}\n"
          f"shape fit residual (px): mean {r.mean():.2f}, median {np.median(r):.2f}, max {r.max():.2f}")
    return 0
