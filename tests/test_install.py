"""The shipped models are package data: found wherever pip installs the package (here: a --target folder)."""

import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _has_modern_setuptools() -> bool:
    try:
        import setuptools
    except ImportError:
        return False
    return int(setuptools.__version__.split(".")[0]) >= 77


def test_target_install_finds_the_shipped_models(tmp_path):
    src = tmp_path / "src"  # a copy, so the build leaves nothing (build/, *.egg-info) in the checkout
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy2(REPO / name, src / name)
    shutil.copytree(REPO / "aamtrack", src / "aamtrack", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO / "models", src / "models", ignore=shutil.ignore_patterns("__pycache__"))
    target = tmp_path / "target"
    cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-compile", "--target", str(target),
           str(src)]
    if _has_modern_setuptools():  # offline and quick; else pip fetches the build backend as CI's install does
        cmd.insert(4, "--no-build-isolation")
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (target / "aamtrack" / "_models" / "3d.npz").is_file()
    # a fresh interpreter that sees only the target (and the venv's dependencies), run away from the checkout
    code = ("import aamtrack.models as m, aamtrack.model as mm; p = m.default_model_path('3d'); "
            "print(p); print(mm.load_model(p).kind); print(mm.load_model(m.default_model_path('2d')).kind)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path,
                          env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    path, kind3, kind2 = proc.stdout.split()
    assert Path(path).is_relative_to(target)  # from the installed package data, not the checkout
    assert (kind3, kind2) == ("3d", "2d")
    assert (REPO / "models" / "3d.npz").read_bytes() == Path(path).read_bytes()
