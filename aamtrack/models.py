"""Where the shipped default models and the shared Candide mesh are found.

The repository keeps its trained models in ``models/`` (``3d.npz``, ``2d.npz``); ``pip install`` copies them to
``<prefix>/share/aamtrack/models``. ``AAMTRACK_MODEL_DIR`` overrides both.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from .errors import ModelFileError

_REPO = Path(__file__).resolve().parents[1]


def model_dirs() -> list[Path]:
    dirs = []
    if os.environ.get("AAMTRACK_MODEL_DIR"):
        dirs.append(Path(os.environ["AAMTRACK_MODEL_DIR"]))
    dirs += [Path(sys.prefix) / "share" / "aamtrack" / "models", _REPO / "models"]
    return dirs


def default_model_path(kind: str = "3d") -> Path:
    """The shipped model of that kind; ModelFileError when none is installed."""
    for d in model_dirs():
        if (d / f"{kind}.npz").is_file():
            return d / f"{kind}.npz"
    raise ModelFileError(f"no default {kind} model found in {', '.join(map(str, model_dirs()))}; "
                         f"pass --model PATH")


def default_candide_path() -> Path | None:
    """../shared/data/candide3/candide3.wfm beside the repository or the working folder, if present."""
    for base in (_REPO.parent, Path.cwd().parent, Path.cwd()):
        p = base / "shared" / "data" / "candide3" / "candide3.wfm"
        if p.is_file():
            return p
    return None
