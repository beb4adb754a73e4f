"""Input and output: video / image-sequence frame sources, iBUG .pts files, tracking CSV, overlay video and run
summary writers. All of them write atomically (temporary name, renamed when complete); cv2 I/O lives here."""

from .atomic import atomic_write, save_npz
from .csvout import TrackingCsvWriter, csv_columns, read_tracking_csv
from .frames import Frame, FrameSource, ImageFrames, VideoFrames, gray, open_frames
from .overlay import OverlayWriter, draw_result, mesh_edges
from .pts import read_pts, write_pts, write_pts_per_frame
from .summary import to_jsonable, write_summary_json

__all__ = [
    "Frame",
    "FrameSource",
    "ImageFrames",
    "OverlayWriter",
    "TrackingCsvWriter",
    "VideoFrames",
    "atomic_write",
    "csv_columns",
    "draw_result",
    "gray",
    "mesh_edges",
    "open_frames",
    "read_pts",
    "read_tracking_csv",
    "save_npz",
    "to_jsonable",
    "write_pts",
    "write_pts_per_frame",
    "write_summary_json",
]
