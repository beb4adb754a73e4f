"""Why a frame has no result, and a log of the track's events (detections, losses, re-detections).

The tracker yields a "lost" FrameResult without saying why. :func:`annotate` fills ``FrameResult.reason`` from
what the result shows, and logs each change of the track at INFO level (``aamtrack -v``):

- no search ran on the frame (only the detector, in ``timings``): "no face detected";
- the search ran and the confidence is below the tracker's ``min_confidence``: "low confidence 0.31 < 0.50";
- the search ran with enough confidence: the fit was rejected by the tracker's other checks, "landmarks outside
  the frame or an implausible jump" (the result does not say which: a lost FrameResult carries no landmarks).

A reason the tracker sets itself is kept as it is.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from typing import Iterable, Iterator

from ..result import FrameResult

__all__ = ["annotate", "loss_reason", "reason_kind"]

log = logging.getLogger("aamtrack.track")

_OTHER = {"dropped": "dropped: arrived while the tracker was busy (realtime replay)",
          "unreadable": "the frame could not be decoded or read"}


def loss_reason(res: FrameResult, *, min_confidence: float = 0.5) -> str:
    """Why ``res`` has no landmarks ("" when it has)."""
    if res.success:
        return ""
    if res.reason:
        return res.reason
    if res.status in _OTHER:
        return _OTHER[res.status]
    if "search" not in res.timings:
        return "no face detected"
    if res.confidence < min_confidence:
        return f"low confidence {res.confidence:.2f} < {min_confidence:.2f}"
    return "fit rejected: landmarks outside the frame or an implausible jump"


def reason_kind(reason: str) -> str:
    """A loss reason with its numbers as "#" ("low confidence # < #"): what the events log and the run's summary
    (``frames_lost_by_reason``) group frames by."""
    return re.sub(r"\d+(\.\d+)?", "#", reason)



def _frames(n: int) -> str:
    return f"{n} frame" if n == 1 else f"{n} frames"


def annotate(results: Iterable[FrameResult], *, min_confidence: float = 0.5) -> Iterator[FrameResult]:
    """Yield ``results`` with ``reason`` filled on frames without a result, logging the track's events.

    Parameters
    ----------
    results : iterable of FrameResult, in frame order
    min_confidence : float
        The tracker's ``TrackerConfig.min_confidence`` (to tell a low-confidence loss from a rejected fit).
    """
    tracked_before = False     # some frame had a face before
    lost_since = None          # first frame of the current run without a result
    last_reason = None
    for res in results:
        if res.success:
            if res.status == "detected":
                if not tracked_before:
                    log.info("frame %d: face detected (confidence %.2f)", res.frame, res.confidence)
                else:
                    gap = f" after {_frames(res.frame - lost_since)} lost" if lost_since is not None else ""
                    log.info("frame %d: face re-detected%s (confidence %.2f)", res.frame, gap, res.confidence)
            elif not tracked_before and res.reason:  # the first face, tracked back from a later detection
                log.info("frame %d: face found (%s)", res.frame, res.reason)
            elif lost_since is not None:
                back = f" ({res.reason})" if res.reason else ""  # tracked back from a later detection
                log.info("frame %d: tracking again after %s lost%s", res.frame, _frames(res.frame - lost_since), back)
            tracked_before = True
            lost_since = last_reason = None
            yield res
            continue
        reason = loss_reason(res, min_confidence=min_confidence)
        if res.status == "dropped":  # a replay's drop is not a loss of the face
            yield dataclasses.replace(res, reason=reason) if reason != res.reason else res
            continue
        if lost_since is None:
            lost_since = res.frame
        if reason_kind(reason) != last_reason:  # a new kind of reason; not every new confidence value
            log.info("frame %d: %s: %s", res.frame, "lost" if tracked_before else "no track", reason)
            last_reason = reason_kind(reason)
        yield dataclasses.replace(res, reason=reason) if reason != res.reason else res
