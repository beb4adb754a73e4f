"""``track.benchmark.warmup``: after it, tracking a video or fitting a noisy still loads no kernel it has not
loaded (a first run compiled the tracked frames' landmark fit and shape check on the video's first tracked frame,
about 6 s there, and a noisy face's noise estimate on the first such still)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# In a fresh interpreter: in the test process other tests may have loaded every kernel already. Prints the
# compiled functions that gained a signature while tracking, after the warm-up.
_CHILD = """
import dataclasses, importlib, itertools, pkgutil, sys
import numba
import numpy as np
from aamtrack import _kernels
from aamtrack.io.frames import open_frames
from aamtrack.model import load_model
from aamtrack.track.benchmark import warmup
from aamtrack.track.tracker import Tracker

def loaded():
    out = {}
    for m in pkgutil.iter_modules(_kernels.__path__):
        mod = importlib.import_module(f"aamtrack._kernels.{m.name}")
        for name, f in vars(mod).items():
            if isinstance(f, numba.core.registry.CPUDispatcher):
                out[f"{m.name}.{name}"] = len(f.signatures)
    return out

tracker = Tracker(load_model(sys.argv[1]))
warmup(tracker)
before = loaded()
with open_frames(sys.argv[2]) as src:
    frames = list(itertools.islice(src, 6))
results = list(tracker.track(frames))
noisy = frames[0].image + np.random.default_rng(0).normal(0, 12, frames[0].image.shape)  # a noisy still's path
still = tracker.fit_still(dataclasses.replace(frames[0], image=np.clip(noisy, 0, 255).astype(np.uint8)))
print(sum(r.status == "tracked" for r in results) + still.success)
after = loaded()
print(" ".join(sorted(k for k in after if after[k] > before.get(k, 0))))
"""


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_tracking_after_the_warm_up_loads_no_new_kernel(kind):
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(ROOT / "models" / f"{kind}.npz"),
                           str(ROOT / "samples" / "cap12_first12s.mp4")],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    tracked, new = (proc.stdout.splitlines() + [""])[:2]
    assert int(tracked) >= 5  # the tracked frames' path ran, and the still was fitted
    assert new == "", f"compiled on the first frames, not in the warm-up: {new}"
