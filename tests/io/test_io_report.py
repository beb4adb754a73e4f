"""report.html: stretches found from a synthetic run, one self-contained file, and a real headless browser
rendering it (skipped where Chromium is not installed)."""

from __future__ import annotations

import base64
import re
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest
from conftest import SEED

from aamtrack.errors import OutputError
from aamtrack.io.report import ReportBuilder, require_matplotlib
from aamtrack.result import FrameResult

ANIM = ("jaw_drop", "lip_stretcher")
N = 60
LOST = range(20, 26)       # six frames without a face
LOW = range(40, 44)        # four tracked frames of confidence 0.6
DROPPED = 22               # a drop inside the loss does not split it


def _run(rng):
    """(results, images) of a made-up 60-frame run: a face sliding right, a loss, a low-confidence stretch."""
    base = np.column_stack([rng.uniform(120, 200, 68), rng.uniform(80, 170, 68)])
    results, images = [], []
    for i in range(N):
        image = np.full((240, 320, 3), 90, np.uint8)
        image[:, :, 1] = 60 + i  # frames differ
        if i == DROPPED:
            results.append(FrameResult(frame=i, timestamp=i / 25, status="dropped"))
            images.append(None)
            continue
        if i in LOST:
            results.append(FrameResult(frame=i, timestamp=i / 25, status="lost", reason="no face detected"))
        else:
            conf = 0.6 if i in LOW else 0.95
            lm = base + [i, 0.0]
            results.append(FrameResult(
                frame=i, timestamp=i / 25, status="detected" if i in (0, LOST[-1] + 1) else "tracked",
                confidence=conf, landmarks=lm, rotation=np.array([0.1, np.sin(i / 9), 0.02 * i]),
                translation=lm.mean(axis=0), scale=80.0 + i / 10, anim_params=np.array([np.sin(i / 5), 0.1])))
        images.append(image)
    return results, images


def _report(tmp_path):
    pytest.importorskip("matplotlib", reason="report.html needs the plot extra (matplotlib)")
    rng = np.random.default_rng(SEED)
    builder = ReportBuilder(model_kind="3d", anim_names=ANIM, min_confidence=0.5)
    for res, image in zip(*_run(rng), strict=True):
        builder.add(res, image)
    summary = {"input": "clip.mp4", "model": "m.npz", "model_kind": "3d", "frames_read": N, "frames_tracked": 49,
               "frames_lost": 6, "frames_dropped": 1, "frames_unreadable": 0, "re_detections": 1, "video_fps": 25.0,
               "timing_ms": {"track": {"median": 0.7}}, "fps_end_to_end": 300.0, "wall_s": 0.2,
               "smoothing": None, "outputs": {"csv": "clip.csv"}}
    path = tmp_path / "report.html"
    builder.write(path, summary)
    return builder, path


def test_stretches_and_a_self_contained_file(tmp_path):
    builder, path = _report(tmp_path)
    got = [(s.kind, s.start, s.stop, s.reason) for s in builder.stretches]
    assert got == [("lost", 20, 25, "no face detected"), ("low confidence", 40, 43, "confidence 0.60")]
    assert all(s.thumbnail for s in builder.stretches)
    text = path.read_text(encoding="utf-8")
    srcs = re.findall(r'src="([^"]*)"', text)
    assert len(srcs) == 3 + 2  # pose, animation units, confidence; two thumbnails
    assert all(s.startswith("data:image/") for s in srcs)  # nothing outside the file
    assert "http" not in text.replace("http-equiv", "")
    thumb = cv2.imdecode(np.frombuffer(base64.b64decode(builder.stretches[0].thumbnail), np.uint8), cv2.IMREAD_COLOR)
    assert thumb.shape[1] == 200 and (thumb[:10, :, 2] > 150).mean() > 0.5  # the red LOST banner on the thumbnail
    for needle in ("frames 20&ndash;25", "no face detected", "Animation units", "Head pose", "re-detections"):
        assert needle in text


def test_one_line_without_matplotlib(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib raises ImportError
    with pytest.raises(OutputError, match=r"pip install 'aamtrack\[plot\]'") as info:
        require_matplotlib()
    assert "\n" not in str(info.value)


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def test_renders_in_headless_chromium(tmp_path):
    browser = _chromium()
    if browser is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium)")
    _, path = _report(tmp_path)
    shot = tmp_path / "shot.png"
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
           "--window-size=1000,2600", f"--screenshot={shot}", path.as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and shot.exists(), proc.stderr[-1500:]
    img = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[:2] == (2600, 1000)
    # matplotlib's default blue (#1f77b4, BGR 180 119 31) and orange (#ff7f0e) lines: the figures were drawn
    blue = (np.abs(img.astype(int) - [180, 119, 31]).sum(axis=2) < 60).sum()
    orange = (np.abs(img.astype(int) - [14, 127, 255]).sum(axis=2) < 60).sum()
    assert blue > 100 and orange > 50, (blue, orange)  # (a page of text alone has none)
    # the LOST thumbnail's red banner
    red = ((img[..., 2] > 170) & (img[..., 1] < 80) & (img[..., 0] < 80)).sum()
    assert red > 500, red
    shutil.copy(shot, tmp_path.parent / "report_screenshot.png")  # kept in pytest's tmp folder for a look


def test_overlay_video_plays_in_chromium(tmp_path):
    """The overlay's codec is one a browser decodes (VP8 .webm with the pip OpenCV; H.264 .mp4 elsewhere)."""
    from aamtrack.io.overlay import OverlayWriter

    browser = _chromium()
    if browser is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium)")
    rng = np.random.default_rng(SEED)
    results, images = _run(rng)
    with OverlayWriter(tmp_path / "overlay.mp4", 25.0, (320, 240)) as writer:
        for res, image in zip(results, images, strict=True):
            writer.write(image, res)
    if writer.fourcc not in ("avc1", "VP80", "VP90"):
        pytest.skip(f"this OpenCV has no browser codec (wrote {writer.fourcc}, as its warning says)")
    page = tmp_path / "play.html"
    page.write_text(f"""<!DOCTYPE html><html><body><div id="r">pending</div>
<video id="v" src="{writer.path.name}" muted preload="auto"></video><script>
const v = document.getElementById('v'), r = document.getElementById('r');
v.addEventListener('loadeddata', () => {{ r.textContent = 'PLAYABLE ' + v.videoWidth + 'x' + v.videoHeight; }});
v.addEventListener('error', () => {{ r.textContent = 'ERROR ' + (v.error && v.error.code); }});
</script></body></html>""")
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=5000", "--dump-dom", page.as_uri()]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout
    assert "PLAYABLE 320x240" in dom, re.findall(r'<div id="r">[^<]*', dom)
