"""aamtrack: real-time face tracking with Active Appearance Models (2D and 3D) and facial motion transfer.

Python API (imported on first use, so ``import aamtrack`` itself loads neither numba nor OpenCV)::

    aamtrack.load_model("3d")                      # or "2d", or a path to a model .npz
    aamtrack.Tracker(model).track(frames)          # a generator of FrameResult (frames: aamtrack.Frame)
    aamtrack.track_video("clip.mp4")               # the same for a file, folder or glob, smoothed
"""

__version__ = "0.1.0"

_LAZY = {
    "load_model": "aamtrack.api",
    "track_video": "aamtrack.api",
    "Tracker": "aamtrack.track.tracker",
    "TrackerConfig": "aamtrack.track.tracker",
    "FrameResult": "aamtrack.result",
    "SmoothConfig": "aamtrack.track.smooth",
    "smooth_results": "aamtrack.track.smooth",
    "Model": "aamtrack.model",
    "Frame": "aamtrack.io.frames",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'aamtrack' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
