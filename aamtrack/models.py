"""Where the shipped default models and the shared Candide mesh are found.

The repository keeps its trained models in ``models/`` (``3d.npz``, ``2d.npz``). The build maps that folder into
the package as ``aamtrack._models`` (setup.py), so the files are package data: read here with
:mod:`importlib.resources`, they are found wherever pip put the package (a venv, ``--user``, ``--target``, an
editable install). A source checkout used without installing (``PYTHONPATH=.``) falls back to ``models/`` next to
the package. ``AAMTRACK_MODEL_DIR`` overrides both.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

from .errors import ModelFileError

_REPO = Path(__file__).resolve().parents[1]
SHIPPED_KINDS = ("3d", "2d")


def _package_dir() -> Path | None:
    """The installed ``aamtrack._models`` folder, or None when the package data is not installed."""
    try:
        files = importlib.resources.files("aamtrack._models")
    except ModuleNotFoundError:
        return None
    # a regular package on disk (every way pip installs) gives a pathlib.Path; a zip import would not
    return files if isinstance(files, Path) and files.is_dir() else None


def model_dirs() -> list[Path]:
    """Folders searched for ``<kind>.npz``, in order."""
    dirs = []
    if os.environ.get("AAMTRACK_MODEL_DIR"):
        dirs.append(Path(os.environ["AAMTRACK_MODEL_DIR"]))
    pkg = _package_dir()
    if pkg is not None:
        dirs.append(pkg)
    if (_REPO / "models") not in dirs:
        dirs.append(_REPO / "models")
    return dirs


def default_model_path(kind: str = "3d") -> Path:
    """The shipped model of that kind; ModelFileError when none is installed."""
    if kind not in SHIPPED_KINDS:
        raise ModelFileError(f"no shipped model of kind {kind!r}; kinds: {', '.join(SHIPPED_KINDS)}")
    for d in model_dirs():
        if (d / f"{kind}.npz").is_file():
            return d / f"{kind}.npz"
    raise ModelFileError(f"no default {kind} model found in {', '.join(map(str, model_dirs()))}; "
                         f"pass --model PATH")


def shipped_model_paths() -> list[Path]:
    """Every shipped model file that exists (to refuse overwriting one)."""
    return [d / f"{k}.npz" for d in model_dirs() for k in SHIPPED_KINDS if (d / f"{k}.npz").is_file()]


def default_candide_path() -> Path | None:
    """../shared/data/candide3/candide3.wfm beside the repository or the working folder, if present."""
    for base in (_REPO.parent, Path.cwd().parent, Path.cwd()):
        p = base / "shared" / "data" / "candide3" / "candide3.wfm"
        if p.is_file():
            return p
    return None
