"""``report.html``: one self-contained page on a tracking run (``aamtrack run --report``).

Contents: the summary table (frames read / tracked / lost, re-detections, speed, model, smoothing, outputs);
plots over time of the head pose (rotation in degrees, translation in pixels, scale), the animation units (3D
models) and the confidence, with lost frames shaded; and the lost and low-confidence stretches, each with the
overlay-drawn thumbnail of its first frame. Figures are matplotlib PNGs embedded as base64 ``data:`` URIs, so the
file needs nothing beside it. matplotlib is the optional ``plot`` extra: :func:`require_matplotlib` says so in
one line where it is missing.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import OutputError
from .atomic import atomic_write
from .overlay import draw_result

__all__ = ["ReportBuilder", "Stretch", "require_matplotlib", "LOW_CONFIDENCE"]

#: Tracked frames below this confidence are listed as low-confidence stretches (the tracker loses a frame
#: below its own ``min_confidence``, 0.5 by default).
LOW_CONFIDENCE = 0.7
MAX_THUMBNAILS = 24
THUMB_WIDTH = 200


def require_matplotlib():
    """matplotlib.pyplot on the file-only Agg backend; OutputError (one line) where it is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OutputError("--report needs matplotlib: pip install 'aamtrack[plot]' (or pip install matplotlib)") \
            from None
    return plt


@dataclass
class Stretch:
    """Consecutive frames without a result ("lost") or tracked with low confidence ("low confidence")."""

    kind: str
    start: int
    stop: int           # last frame, inclusive
    reason: str
    min_confidence: float
    thumbnail: str = ""  # base64 JPEG of the first frame with the overlay drawn, "" beyond MAX_THUMBNAILS

    @property
    def n_frames(self) -> int:
        return self.stop - self.start + 1


class ReportBuilder:
    """Collects what the report needs, frame by frame, then writes it.

    Parameters
    ----------
    model_kind : "3d" or "2d"
    anim_names : names of the animation units (empty for 2D)
    min_confidence : the tracker's threshold (drawn on the confidence plot)
    edges : (n_edges, 2) mesh edges for the thumbnails' overlay, optional
    """

    def __init__(self, *, model_kind: str, anim_names=(), min_confidence: float = 0.5, edges=None,
                 low_confidence: float = LOW_CONFIDENCE):
        self.model_kind = model_kind
        self.anim_names = tuple(anim_names)
        self.min_confidence = min_confidence
        self.low_confidence = low_confidence
        self.edges = edges
        self.frames, self.times, self.status, self.confidence = [], [], [], []
        self.rotation, self.translation, self.scale, self.anim = [], [], [], []
        self.stretches: list[Stretch] = []

    def add(self, result, image: np.ndarray | None) -> None:
        """Record one FrameResult; ``image`` (BGR, optional) gives the thumbnail when a stretch starts here."""
        self.frames.append(result.frame)
        self.times.append(result.timestamp)
        self.status.append(result.status)
        self.confidence.append(result.confidence)
        ok = result.success
        self.rotation.append(np.asarray(result.rotation, float) if ok else np.full(3, np.nan))
        self.translation.append(np.asarray(result.translation, float) if ok else np.full(2, np.nan))
        self.scale.append(float(result.scale) if ok else math.nan)
        n = len(self.anim_names)
        anim = np.asarray(result.anim_params, float)
        self.anim.append(anim if ok and anim.shape == (n,) else np.full(n, np.nan))
        if result.status == "dropped":
            return  # a realtime replay's drop: neither a loss nor a low-confidence frame
        kind = None if ok and result.confidence >= self.low_confidence else ("lost" if not ok else "low confidence")
        last = self.stretches[-1] if self.stretches else None
        if kind is None:
            return
        if last is not None and last.kind == kind and last.stop == self._previous_frame(result.frame):
            last.stop = result.frame
            last.min_confidence = min(last.min_confidence, result.confidence)
            return
        reason = getattr(result, "reason", "") or ("" if not ok else f"confidence {result.confidence:.2f}")
        thumb = self._thumbnail(image, result) if len(self.stretches) < MAX_THUMBNAILS else ""
        self.stretches.append(Stretch(kind, result.frame, result.frame, reason, result.confidence, thumb))

    def _previous_frame(self, frame: int) -> int:
        """The last non-dropped frame before ``frame`` (a drop inside a loss does not split it)."""
        for f, s in zip(reversed(self.frames[:-1]), reversed(self.status[:-1]), strict=True):
            if s != "dropped":
                return f
        return frame - 1

    def _thumbnail(self, image, result) -> str:
        if image is None:
            return ""
        canvas = image.copy() if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        draw_result(canvas, result, self.edges)
        h, w = canvas.shape[:2]
        small = cv2.resize(canvas, (THUMB_WIDTH, max(1, round(h * THUMB_WIDTH / w))), interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 80])
        return base64.b64encode(buf.tobytes()).decode("ascii") if ok else ""

    # -- output ---------------------------------------------------------------------------------------
    def figures(self) -> list[tuple[str, str]]:
        """(title, base64 PNG) of each plot."""
        plt = require_matplotlib()
        t = np.asarray(self.times, float)
        status = np.asarray(self.status)
        lost = ~np.isin(status, ("detected", "tracked"))
        figs = []

        def shade(ax):
            for start, stop in _runs(lost):
                ax.axvspan(t[start], t[min(stop, len(t) - 1)], color="#f3b5b5", lw=0, zorder=0)

        rot = np.degrees(np.asarray(self.rotation).reshape(-1, 3))
        tr = np.asarray(self.translation).reshape(-1, 2)
        fig, axes = plt.subplots(3, 1, figsize=(10, 6.6), sharex=True)
        labels = ("Rx (pitch)", "Ry (yaw)", "Rz (roll)") if self.model_kind == "3d" else ("", "", "Rz (roll)")
        for k, label in enumerate(labels):
            if label:
                axes[0].plot(t, rot[:, k], lw=1, label=label)
        axes[0].set_ylabel("rotation (deg)")
        axes[1].plot(t, tr[:, 0], lw=1, label="Tx")
        axes[1].plot(t, tr[:, 1], lw=1, label="Ty")
        axes[1].set_ylabel("translation (px)")
        axes[2].plot(t, self.scale, lw=1, color="0.3", label="scale")
        axes[2].set_ylabel("scale (px / unit)")
        axes[2].set_xlabel("time (s); red: frames without a result")
        for ax in axes:
            shade(ax)
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", fontsize=8, ncol=3)
        figs.append(("Head pose", _png(plt, fig)))

        if self.anim_names:
            anim = np.asarray(self.anim).reshape(-1, len(self.anim_names))
            fig, ax = plt.subplots(figsize=(10, 3.6))
            for k, name in enumerate(self.anim_names):
                ax.plot(t, anim[:, k], lw=1, label=name)
            shade(ax)
            ax.set(xlabel="time (s)", ylabel="animation unit")
            ax.grid(alpha=0.3)
            ax.legend(loc="upper right", fontsize=7, ncol=4)
            figs.append(("Animation units", _png(plt, fig)))

        conf = np.asarray(self.confidence, float)
        fig, ax = plt.subplots(figsize=(10, 2.8))
        ax.plot(t, conf, lw=1, color="#1f77b4", label="confidence")
        ax.axhline(self.min_confidence, color="#c33", lw=0.8, ls="--", label=f"lost below {self.min_confidence:g}")
        ax.axhline(self.low_confidence, color="#e90", lw=0.8, ls=":", label=f"low below {self.low_confidence:g}")
        shade(ax)
        ax.set(xlabel="time (s)", ylabel="confidence", ylim=(-0.02, 1.02))
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=8, ncol=3)
        figs.append(("Confidence", _png(plt, fig)))
        return figs

    def html(self, summary: dict) -> str:
        figs = self.figures()
        name = html.escape(os.path.basename(str(summary.get("input", ""))))
        parts = [_HEAD.format(title=f"aamtrack report: {name}"), f"<h1>aamtrack report: {name}</h1>",
                 "<h2>Summary</h2>", _summary_table(summary)]
        for title, png in figs:
            parts.append(f"<h2>{html.escape(title)}</h2>")
            parts.append(f'<img class="plot" alt="{html.escape(title)}" src="data:image/png;base64,{png}">')
        lost = [s for s in self.stretches if s.kind == "lost"]
        low = [s for s in self.stretches if s.kind != "lost"]
        parts.append(f"<h2>Lost and low-confidence stretches</h2><p>{len(lost)} lost, {len(low)} with confidence "
                     f"below {self.low_confidence:g} (tracked, but less sure); first frame of each shown"
                     f"{f' (thumbnails for the first {MAX_THUMBNAILS})' if len(self.stretches) > MAX_THUMBNAILS else ''}"
                     ".</p>")
        if not self.stretches:
            parts.append("<p>None: every frame tracked with confidence above the threshold.</p>")
        else:
            parts.append('<div class="stretches">')
            fps = summary.get("video_fps") or 25.0
            for s in self.stretches:
                img = (f'<img alt="frame {s.start}" src="data:image/jpeg;base64,{s.thumbnail}">' if s.thumbnail
                       else '<div class="nothumb">no thumbnail</div>')
                span = f"frame {s.start}" if s.n_frames == 1 else f"frames {s.start}&ndash;{s.stop}"
                detail = s.reason if s.kind == "lost" else f"lowest confidence {s.min_confidence:.2f}"
                count = "1 frame" if s.n_frames == 1 else f"{s.n_frames} frames"
                parts.append(f'<figure class="{"lost" if s.kind == "lost" else "low"}">{img}<figcaption>'
                             f"<b>{html.escape(s.kind)}</b>: {span} ({count}, at "
                             f"{s.start / fps:.2f} s)<br>{html.escape(detail)}</figcaption></figure>")
            parts.append("</div>")
        parts.append("</body></html>\n")
        return "\n".join(parts)

    def write(self, path: str | os.PathLike, summary: dict) -> None:
        """Write the report to ``path`` atomically."""
        text = self.html(summary)
        with atomic_write(path, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    padded = np.concatenate([[0], np.asarray(mask, dtype=np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2], edges[1::2], strict=True))


def _png(plt, fig) -> str:
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _summary_table(s: dict) -> str:
    timing = s.get("timing_ms") or {}
    track = timing.get("track") or {}
    smooth = s.get("smoothing")
    rows = [
        ("input", s.get("input")), ("model", f"{s.get('model')} ({s.get('model_kind')})"),
        ("frames read", s.get("frames_read")), ("tracked", s.get("frames_tracked")),
        ("lost", s.get("frames_lost")), ("dropped (realtime replay)", s.get("frames_dropped")),
        ("unreadable", s.get("frames_unreadable")), ("re-detections", s.get("re_detections")),
        ("video frame rate", f"{s.get('video_fps', 0):g} fps"),
        ("tracking time per frame (median)", f"{track['median']:.2f} ms" if track else "-"),
        ("end to end", f"{s.get('fps_end_to_end', 0):.0f} fps, {s.get('wall_s', 0):.1f} s"),
        ("smoothing", "off" if not smooth else f"One Euro, min_cutoff {smooth['min_cutoff_hz']:g} Hz, "
                                               f"beta {smooth['beta']:g}, d_cutoff {smooth['d_cutoff_hz']:g} Hz"),
    ]
    rows += [(f"output: {k}", v) for k, v in (s.get("outputs") or {}).items()]
    body = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in rows)
    return f'<table class="summary">{body}</table>'


_HEAD = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 960px; color: #222; }}
h1 {{ font-size: 1.4em; }} h2 {{ font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }}
table.summary {{ border-collapse: collapse; }}
table.summary th {{ text-align: left; font-weight: normal; color: #555; padding: 2px 1.2em 2px 0; }}
table.summary td {{ font-variant-numeric: tabular-nums; padding: 2px 0; word-break: break-all; }}
img.plot {{ width: 100%; }}
.stretches {{ display: flex; flex-wrap: wrap; gap: 10px; }}
figure {{ margin: 0; width: 200px; font-size: 0.8em; border-top: 4px solid #c33; }}
figure.low {{ border-top-color: #e90; }}
figure img {{ width: 200px; display: block; }}
.nothumb {{ width: 200px; height: 60px; background: #eee; color: #888; text-align: center; line-height: 60px; }}
</style></head><body>"""
