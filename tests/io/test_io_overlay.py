"""Overlay video: a readable video with one frame per write, drawn where the face is, written atomically."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SEED
from iohelpers import HEIGHT, WIDTH, index_image, make_results

from aamtrack.io import OverlayWriter, draw_result, mesh_edges, open_frames
from aamtrack.result import FrameResult


def test_mesh_edges():
    edges = mesh_edges(np.array([[0, 1, 2], [2, 1, 3]]))  # two triangles share the edge 1-2
    np.testing.assert_array_equal(edges, [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]])


def _result(rng, status="tracked"):
    landmarks = np.column_stack([rng.uniform(20, 100, 68), rng.uniform(10, 55, 68)])
    return FrameResult(frame=0, timestamp=0.0, status=status, confidence=0.9, landmarks=landmarks,
                       vertices=landmarks)


def test_draw_result_marks_the_face():
    rng = np.random.default_rng(SEED)
    triangles = np.array([[i, i + 1, i + 2] for i in range(66)])
    blank = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    drawn = draw_result(blank.copy(), _result(rng), mesh_edges(triangles))
    assert (drawn.sum(axis=2) > 0).mean() > 0.05  # mesh and dots cover part of the frame
    lost = draw_result(blank.copy(), FrameResult(frame=1, timestamp=0.1, status="lost", reason="no face detected"))
    banner = lost[:max(24, round(0.13 * HEIGHT))]
    assert (banner[..., 2] > 150).mean() > 0.7  # a red band across the whole width (white text on it)
    assert (lost[HEIGHT // 2, :, 2] > 150).sum() >= 2  # the red border reaches down the sides
    assert not lost[50:-4, 8:-8].any()  # below the banner and the status box the picture stays uncovered


@pytest.mark.parametrize("suffix", [".mp4", ".avi"])
def test_writes_readable_video(tmp_path, suffix):
    rng = np.random.default_rng(SEED)
    results = make_results(11, rng, fps=25.0)
    triangles = np.array([[i, i + 1, i + 2] for i in range(100)])
    path = tmp_path / f"overlay{suffix}"
    with OverlayWriter(path, 25.0, (WIDTH, HEIGHT), triangles=triangles) as writer:
        for i, r in enumerate(results):
            image = None if r.status == "unreadable" else index_image(i, rng, size=(2 * WIDTH, 2 * HEIGHT))
            writer.write(image, r)  # other-size images are resized; None gives a black frame
    # .mp4 asks for a browser-playable codec: H.264 where OpenCV has it, else VP8 in .webm, else mp4v
    expected = {".mp4": {("overlay.mp4", "avc1"), ("overlay.webm", "VP80"), ("overlay.mp4", "mp4v")},
                ".avi": {("overlay.avi", "MJPG")}}[suffix]
    assert (writer.path.name, writer.fourcc) in expected and writer.n_frames == 11
    assert list(tmp_path.iterdir()) == [writer.path]  # temporary renamed
    with open_frames(writer.path) as source:
        assert (source.width, source.height, source.fps) == (WIDTH, HEIGHT, 25.0)
        frames = list(source)
    assert len(frames) == 11 and all(f.image is not None for f in frames)


def test_fast_writes_mp4v(tmp_path):
    """``fast``: mp4v in .mp4 whatever the suffix asked, no browser codec tried first."""
    from aamtrack.io.overlay import codec_attempts

    assert codec_attempts(tmp_path / "o.webm", fast=True) == [(tmp_path / "o.mp4", "mp4v"), (tmp_path / "o.avi", "MJPG")]
    rng = np.random.default_rng(SEED)
    results = make_results(7, rng, fps=25.0)
    with OverlayWriter(tmp_path / "overlay.mp4", 25.0, (WIDTH, HEIGHT), fast=True) as writer:
        for i, r in enumerate(results):
            writer.write(None if r.status == "unreadable" else index_image(i, rng), r)
    assert (writer.path.name, writer.fourcc, writer.n_frames) == ("overlay.mp4", "mp4v", 7)
    with open_frames(writer.path) as source:
        assert len(list(source)) == 7


def test_exception_leaves_nothing(tmp_path):
    rng = np.random.default_rng(SEED)
    with pytest.raises(RuntimeError):
        with OverlayWriter(tmp_path / "o.mp4", 25.0, (WIDTH, HEIGHT)) as writer:
            writer.write(index_image(0, rng), _result(rng))
            raise RuntimeError("stop")
    assert not list(tmp_path.iterdir())
    with pytest.raises(ValueError, match="closed"):
        writer.write(index_image(1, rng), _result(rng))


def test_pose_axes_follow_the_model_rotation():
    from aamtrack.io.overlay import axes_endpoints

    rng = np.random.default_rng(SEED)
    landmarks = np.column_stack([rng.uniform(100, 200, 68), rng.uniform(50, 150, 68)])
    ends = axes_endpoints(landmarks, np.zeros(3))  # frontal: x right, y up (image y down), z towards the camera
    half = 0.5 * np.ptp(landmarks[:, 0])
    assert np.allclose(ends[0], landmarks[30])
    assert np.allclose(ends[1:] - ends[0], [[half, 0], [0, -half], [0, 0]])
    ends = axes_endpoints(landmarks, np.array([0.0, 0.0, np.pi / 2]))  # rolled 90 degrees: x points up
    assert np.allclose(ends[1] - ends[0], [0, -half])
    assert axes_endpoints(np.full((68, 2), np.nan), np.zeros(3)) is None


@pytest.mark.parametrize("suffix,fourcc", [(".webm", "VP80"), (".mp4", "avc1")])
def test_pyav_writes_the_browser_codecs_and_opencv_reads_every_frame_back(tmp_path, suffix, fourcc):
    """With PyAV installed (the ``video`` extra; the ``test`` extra has it) .webm and .mp4 overlays go through its
    VP8 and H.264 encoders; OpenCV reads them back frame for frame, each frame's picture where it was written."""
    pytest.importorskip("av", reason="PyAV (the video extra) is not installed")
    levels = [30 * i for i in range(8)]
    w, h = 320, 240  # (at 128 x 64 both encoders' rate control lags flat frames by tens of grey levels)
    with OverlayWriter(tmp_path / f"overlay{suffix}", 25.0, (w, h)) as writer:
        for i, level in enumerate(levels):
            writer.write(np.full((h, w, 3), level, np.uint8),
                         FrameResult(frame=i, timestamp=i / 25.0, status="dropped"))
    assert (writer.backend, writer.fourcc, writer.path.name) == ("pyav", fourcc, f"overlay{suffix}")
    assert list(tmp_path.iterdir()) == [writer.path]
    with open_frames(writer.path) as source:
        assert (source.width, source.height, source.fps) == (w, h, 25.0)
        frames = [f.image for f in source]
    assert len(frames) == len(levels)
    for image, level in zip(frames, levels, strict=True):  # below the banner, inside the border: the grey levels,
        assert abs(float(np.median(image[h // 2:h - 12, w // 4:3 * w // 4])) - level) < 6  # lossy (3 levels written)


def test_odd_sizes_and_a_missing_pyav_take_opencvs_writer(tmp_path, monkeypatch):
    """4:2:0 video needs even sides (x264 refuses odd ones): an odd-sized overlay is OpenCV's; and without PyAV,
    a .webm overlay is OpenCV's VP8 as before the video extra."""
    from aamtrack.io import overlay

    rng = np.random.default_rng(SEED)
    with OverlayWriter(tmp_path / "odd.webm", 25.0, (WIDTH + 1, HEIGHT)) as writer:
        writer.write(index_image(0, rng), _result(rng))
    assert writer.backend == "opencv" and writer.n_frames == 1
    monkeypatch.setattr(overlay, "_pyav", lambda: None)
    with OverlayWriter(tmp_path / "plain.webm", 25.0, (WIDTH, HEIGHT)) as writer:
        writer.write(index_image(1, rng), _result(rng))
    assert (writer.backend, writer.fourcc) == ("opencv", "VP80")
    with open_frames(writer.path) as source:
        assert len(list(source)) == 1


def test_a_slow_vp8_overlay_says_what_is_faster(tmp_path, monkeypatch, caplog):
    """OpenCV's VP8 (no PyAV) from 1280x720 up writes slower than the tracker tracks: one warning naming the video
    extra; not below that size, and not through PyAV."""
    from aamtrack.io import overlay

    def write(name, size):
        with OverlayWriter(tmp_path / name, 25.0, size) as writer:
            writer.write(None, FrameResult(frame=0, timestamp=0.0, status="lost", reason="no face detected"))
        return writer

    monkeypatch.setattr(overlay, "_pyav", lambda: None)
    with caplog.at_level("WARNING", logger="aamtrack.io.overlay"):
        assert write("big.webm", (1280, 720)).fourcc == "VP80"
    assert [r.getMessage() for r in caplog.records] == [
        "overlay video: OpenCV's VP8 writes about 8 frames a second at 1280x720, slower than the tracker; pip "
        "install \"aamtrack[video]\" writes H.264 several times faster (or use --fast-video)"]
    caplog.clear()
    with caplog.at_level("WARNING", logger="aamtrack.io.overlay"):
        write("small.webm", (640, 480))
    assert not caplog.records
    monkeypatch.undo()
    if overlay._pyav() is not None:
        with caplog.at_level("WARNING", logger="aamtrack.io.overlay"):
            assert write("fast.webm", (1280, 720)).backend == "pyav"
        assert not caplog.records
