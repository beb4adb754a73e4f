"""Loss reasons inferred from FrameResults, and the event log of ``aamtrack -v``."""

import logging

import numpy as np

from aamtrack.track.events import annotate, loss_reason
from aamtrack.result import FrameResult


def _r(i, status, conf=0.9, searched=True, reason=""):
    timings = {"search": 0.001} if searched else {"detect": 0.002}
    lm = np.zeros((68, 2)) if status in ("detected", "tracked") else np.full((68, 2), np.nan)
    return FrameResult(frame=i, timestamp=i / 25, status=status, confidence=conf, landmarks=lm, timings=timings,
                       reason=reason)


def test_loss_reasons():
    assert loss_reason(_r(0, "tracked")) == ""
    assert loss_reason(_r(0, "lost", 0.0, searched=False)) == "no face detected"
    assert loss_reason(_r(0, "lost", 0.31), min_confidence=0.5) == "low confidence 0.31 < 0.50"
    assert "implausible jump" in loss_reason(_r(0, "lost", 0.8))  # passed the confidence, rejected otherwise
    assert "decoded" in loss_reason(_r(0, "unreadable"))
    assert loss_reason(_r(0, "lost", reason="set by the tracker")) == "set by the tracker"


def test_annotate_fills_reasons_and_logs_changes_only(caplog):
    stream = [_r(0, "detected"), _r(1, "tracked"), _r(2, "lost", 0.2), _r(3, "lost", 0.0, searched=False),
              _r(4, "lost", 0.0, searched=False), _r(5, "dropped"), _r(6, "detected"), _r(7, "tracked")]
    with caplog.at_level(logging.INFO, logger="aamtrack.track"):
        out = list(annotate(stream, min_confidence=0.5))
    assert [r.reason for r in out][:5] == ["", "", "low confidence 0.20 < 0.50", "no face detected",
                                           "no face detected"]
    assert [r.status for r in out] == [r.status for r in stream]
    assert [r.getMessage() for r in caplog.records] == [
        "frame 0: face detected (confidence 0.90)",
        "frame 2: lost: low confidence 0.20 < 0.50",
        "frame 3: lost: no face detected",           # a new reason is logged, a repeated one is not
        "frame 6: face re-detected after 4 frames lost (confidence 0.90)",
    ]


def test_a_run_of_low_confidence_losses_is_logged_once(caplog):
    stream = [_r(0, "detected"), _r(1, "lost", 0.3), _r(2, "lost", 0.2), _r(3, "tracked"), _r(4, "lost", 0.1),
              _r(5, "detected")]
    with caplog.at_level(logging.INFO, logger="aamtrack.track"):
        list(annotate(stream))
    assert [r.getMessage() for r in caplog.records] == [
        "frame 0: face detected (confidence 0.90)",
        "frame 1: lost: low confidence 0.30 < 0.50",
        "frame 3: tracking again after 2 frames lost",
        "frame 4: lost: low confidence 0.10 < 0.50",
        "frame 5: face re-detected after 1 frame lost (confidence 0.90)",
    ]


def test_frames_tracked_back_from_a_detection_are_logged_as_such(caplog):
    back = "tracked back from frame {}"
    stream = [_r(0, "lost", 0.0, searched=False), _r(1, "tracked", reason=back.format(2)), _r(2, "detected"),
              _r(3, "lost", 0.1), _r(4, "tracked", reason=back.format(5)), _r(5, "detected")]
    with caplog.at_level(logging.INFO, logger="aamtrack.track"):
        out = list(annotate(stream))
    assert out[1].reason == back.format(2) and out[4].reason == back.format(5)  # kept on the tracked frames
    assert [r.getMessage() for r in caplog.records] == [
        "frame 0: no track: no face detected",
        "frame 1: face found (tracked back from frame 2)",
        "frame 2: face re-detected (confidence 0.90)",
        "frame 3: lost: low confidence 0.10 < 0.50",
        "frame 4: tracking again after 1 frame lost (tracked back from frame 5)",
        "frame 5: face re-detected (confidence 0.90)",
    ]
