"""``aamtrack train --data DIR --kind 3d|2d --out PATH``: learn a model from images with iBUG .pts files."""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..errors import InputError, OutputError
from ..io.atomic import OutputSet, atomic_write
from ..io.dataset import find_pairs, load_pair
from ..io.frames import display_name
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
    p.add_argument("--seed", type=_seed, default=0,
                   help="seed of training's random draws (default 0: the shipped models'); the same data and seed "
                        "give the same model up to floating-point rounding, and another seed shows how much a "
                        "result owes to them")
    p.add_argument("--workers", type=_workers, default=None,
                   help="threads for the per-image work (default: every core this process may use); any number "
                        "gives the same model up to floating-point rounding")
    p.set_defaults(func=run)


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1  # not a whole number: the same answer as a negative one
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}")
    return value


def _workers(text: str) -> int:
    """--workers: a whole number of threads, 1 or more."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of threads (1 or more)")
    return n


def _parse_couples(text: str | None) -> tuple:
    if not text:
        return TrainConfig().couples
    try:
        couples = tuple(tuple(int(v) for v in item.split(":")) for item in text.split(","))
        if any(len(c) != 2 or c[1] > c[0] or c[1] < 4 or c[1] > 256 or c[0] > 4096 for c in couples):
            raise ValueError
    except ValueError:
        raise InputError(f"--couples {text!r}: expected FACE_PX:TEX_WIDTH pairs with "
                         "4 <= TEX_WIDTH <= FACE_PX <= 4096 and TEX_WIDTH <= 256") from None
    return couples


def model_bytes_bound(config: TrainConfig) -> int:
    """An upper bound of a model file's size: every array uncompressed (a texture frame has fewer than
    tex_width^2 pixels of at most 2 feature channels, a couple (and its soft twin) fewer than 64 parameters, each
    stage of its cascade (or its update matrix) one number per parameter and texture value; 8 bytes a number)."""
    n_px = sum(tex * tex for _, tex in config.couples)
    sets = 2 if config.soft_search_share > 0 else 1
    per_px = 8 * (2 + 3 + 3 + 2 * (1 + config.n_appearance + 64 * sets * max(config.n_stages, 1)))
    return n_px * per_px + (1 << 20)  # + mesh, maps and metadata


def check_free_space(folder: Path, need: int) -> None:
    """OutputError before the work when ``folder``'s file system has less than ``need`` bytes free."""
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return  # cannot tell: the atomic write still leaves nothing half-written
    if free < need:
        raise OutputError(f"{display_name(folder)}: {free / 1e6:.1f} MB free, the model may need up to "
                          f"{need / 1e6:.1f} MB")


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
    if out.is_dir():
        raise InputError(f"{display_name(out)}: is a folder, expected a model file name")
    config = TrainConfig(couples=_parse_couples(args.couples), seed=args.seed)
    pairs = find_pairs(args.data)
    # Output checks before the work: the model and the report are committed together at the end.
    outputs = OutputSet(out.parent)
    targets = (out, args.report) if args.report else (out,)
    for path in targets:
        if not path.parent.is_dir():
            raise InputError(f"{display_name(path.parent)}: output folder does not exist"
                             + (" (the default --out is models/<kind>.npz here)" if args.out is None else ""))
    if args.report and args.report.resolve() == out.resolve():
        raise InputError("--report and --out name the same file")
    model_tmp = outputs.file(out.name, keep_suffix=False)  # refuses a name taken by a folder or a device
    report_tmp = outputs.file(args.report.resolve(), keep_suffix=False) if args.report else None
    for path in targets:
        OutputSet(path.parent).prepare()  # writable?
    check_free_space(out.parent, model_bytes_bound(config))
    candide = None
    if args.kind == "3d":
        path = args.candide or default_candide_path()
        if path is None:
            raise InputError("--kind 3d needs the Candide-3 mesh: pass --candide path/to/candide3.wfm")
        candide = read_wfm(path)
    images, points = [], []
    for img_path, pts_path in tqdm(pairs, desc="read", unit="img", file=sys.stderr, disable=None):
        img, pts = load_pair(img_path, pts_path)
        images.append(img)
        points.append(pts)
    t0 = time.perf_counter()
    try:
        model, report = train_model(images, np.array(points), args.kind, candide=candide, config=config,
                                    names=tuple(p[0].name for p in pairs),
                                    progress=lambda it, **kw: tqdm(it, file=sys.stderr, disable=None, **kw),
                                    workers=args.workers)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
        raise InputError(f"{display_name(args.data)}: training failed on these landmarks ({exc}); "
                         "check the .pts files (degenerate or mismatched points?)") from None
    with outputs:
        save_model(model, model_tmp)
        if report_tmp is not None:
            with atomic_write(report_tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["image", "fit_rms_px"])
                w.writerows((n, f"{r:.3f}") for n, r in zip(report.names, report.fit_rms_px, strict=True))
        outputs.commit()
    r = report.fit_rms_px
    print(f"trained {args.kind} model on {len(images)} images in {time.perf_counter() - t0:.1f} s -> "
          f"{display_name(out)}\nshape fit residual (px): mean {r.mean():.2f}, median {np.median(r):.2f}, "
          f"max {r.max():.2f}")
    return 0
