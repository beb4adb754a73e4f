"""The Python API in a few calls: ``load_model``, ``Tracker``, ``track_video``.

    import aamtrack

    for res in aamtrack.track_video("samples/cap12_first12s.mp4"):
        print(res.frame, res.status, res.landmarks[30])       # nose tip, pixels

Everything here is re-exported lazily by ``aamtrack/__init__.py``, so ``import aamtrack`` stays cheap (no numba,
no OpenCV) until one of these is used.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterator

from .model import Model
from .model import load_model as _load_model_file
from .models import SHIPPED_KINDS, default_model_path
from .track.events import annotate
from .result import FrameResult
from .track.smooth import SmoothConfig, smooth_results
from .track.tracker import Tracker, TrackerConfig

__all__ = ["load_model", "track_video", "Tracker", "TrackerConfig", "SmoothConfig", "FrameResult", "Model"]
# aamtrack.Frame (index, timestamp, image) is aamtrack.io.frames.Frame, re-exported by __init__


def load_model(model: str | os.PathLike | Model = "3d") -> Model:
    """A trained model: ``"3d"`` or ``"2d"`` (the shipped ones), or the path of a model ``.npz``.

    Raises
    ------
    ModelFileError
        A missing file, or one this package cannot read.
    """
    if isinstance(model, Model):
        return model
    if isinstance(model, str) and model in SHIPPED_KINDS:
        return _load_model_file(default_model_path(model))
    return _load_model_file(Path(model))


def track_video(path: str | os.PathLike, *, model: str | os.PathLike | Model = "3d",
                smooth: bool | SmoothConfig = True, fps: float | None = None,
                config: TrackerConfig | None = None) -> Iterator[FrameResult]:
    """Track the largest face in a video file, a folder of images or a glob: one FrameResult per frame.

    Parameters
    ----------
    path : str or PathLike
        Anything :func:`aamtrack.io.frames.open_frames` reads (video file, image folder, quoted glob).
    model : "3d", "2d", a model file path, or a loaded :class:`Model`
    smooth : bool or SmoothConfig
        One Euro smoothing of landmarks and pose (:mod:`aamtrack.track.smooth`); True uses the defaults.
    fps : float, optional
        Frame rate of an image folder (timestamps); default: the video's own, 25 for images.
    config : TrackerConfig, optional

    Returns
    -------
    iterator of FrameResult
        Lost frames have ``success`` False and a ``reason``. The source is opened (and bad input raises
        :class:`~aamtrack.errors.InputError`) at the call, before the first frame is asked for; it is closed
        when the iterator is exhausted or closed.
    """
    from .io.frames import open_frames

    tracker = Tracker(load_model(model), **({"config": config} if config is not None else {}))
    source = open_frames(path, fps=fps)
    cfg = smooth if isinstance(smooth, SmoothConfig) else (SmoothConfig() if smooth else None)

    def results():
        with source:
            stream = annotate(tracker.track(source), min_confidence=tracker.config.min_confidence)
            yield from (smooth_results(stream, cfg) if cfg is not None else stream)

    return results()
