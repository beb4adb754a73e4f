"""The pipelined run's plumbing (aamtrack.track.pipeline): order kept through the threads and bounded queues, and
a failure in any stage raised in the caller's thread with every thread ended."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from aamtrack.track.pipeline import ResultWriter, read_ahead, run_pipeline

SEED = 20261121


def _threads() -> set:
    return {t.name for t in threading.enumerate() if t.name.startswith("aamtrack-")}


def test_read_ahead_keeps_order_through_a_tiny_queue():
    items = list(np.random.default_rng(SEED).integers(0, 1000, 500))
    assert list(read_ahead(iter(items), depth=1)) == items
    assert not _threads()


def test_read_ahead_raises_the_producers_exception_at_its_place():
    def frames():
        yield from range(5)
        raise OSError("decoder failed at frame 5")

    got = []
    with pytest.raises(OSError, match="frame 5"):
        for x in read_ahead(frames(), depth=2):
            got.append(x)
    assert got == [0, 1, 2, 3, 4]
    assert not _threads()


def test_read_ahead_stops_its_thread_when_the_consumer_gives_up():
    produced = []

    def frames():
        for k in range(10_000):
            produced.append(k)
            yield k

    it = read_ahead(frames(), depth=4)
    assert [next(it) for _ in range(3)] == [0, 1, 2]
    it.close()
    assert not _threads()
    assert len(produced) < 40  # bounded: the producer ran at most a queue and a few chunks of 8 ahead


def _fake_tracker(frames):
    for f in frames:
        yield ("result", f)


@pytest.mark.parametrize("pipelined", [True, False])
def test_pipeline_writes_every_result_in_order(pipelined):
    frames = list(range(1000))
    written, seen = [], []
    times = run_pipeline(iter(frames), _fake_tracker, written.append, on_result=seen.append, depth=2,
                         smooth=lambda s: ((tag, 2 * f) for tag, f in s), pipelined=pipelined)
    assert written == [("result", 2 * f) for f in frames]  # smoothing (writer thread) saw the stream in order
    assert seen == [("result", f) for f in frames]
    assert times.n_frames == 1000 and len(times.decode) == 1000 and len(times.output) == 1000
    assert not _threads()


def test_decoder_failing_mid_video_stops_the_run():
    def frames():
        yield from range(7)
        raise RuntimeError("decoder broke")

    written = []
    with pytest.raises(RuntimeError, match="decoder broke"):
        run_pipeline(frames(), _fake_tracker, written.append, depth=2)
    assert [f for _, f in written] == list(range(len(written)))  # what was written is a prefix, in order
    assert len(written) <= 7
    assert not _threads()


def test_writer_failing_stops_the_run_with_the_writers_exception():
    produced = []

    def frames():
        for k in range(100_000):
            produced.append(k)
            yield k

    def write(res):
        if res[1] == 10:
            raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        run_pipeline(frames(), _fake_tracker, write, depth=4)
    assert not _threads()
    assert len(produced) < 1000  # the decoder was stopped, not run to the end


def test_tracker_failing_stops_both_threads():
    def tracker(frames):
        for f in frames:
            if f == 50:
                raise ValueError("tracker broke")
            yield f

    with pytest.raises(ValueError, match="tracker broke"):
        run_pipeline(iter(range(1000)), tracker, lambda r: None, depth=4)
    assert not _threads()


def test_result_writer_reports_its_failure_on_put():
    def consume(items):
        for x in items:
            if x == 3:
                raise KeyError("bad row")

    w = ResultWriter(consume, depth=1)
    with pytest.raises(KeyError, match="bad row"):
        for k in range(10_000):
            w.put(k)
    w.stop()
    assert not _threads()


def test_keep_freed_memory_takes_on_glibc():
    import platform

    from aamtrack.track.pipeline import keep_freed_memory

    if platform.libc_ver()[0] != "glibc":
        pytest.skip("mallopt is glibc's")
    assert keep_freed_memory() is True  # both settings accepted by mallopt
