"""A pipelined tracking run: decoding ahead in one thread, tracking in the caller's thread, smoothing and writing
in another, joined by bounded queues (``aamtrack run``, and ``aamtrack bench``'s end-to-end figure).

    source ──► [decode thread] ──queue──► tracker (caller's thread) ──queue──► [writer thread]: smooth, write

Order is kept (one producer and one consumer per FIFO queue), so every frame gets its row, in frame order. The
numba kernels and OpenCV release the GIL, so the three stages overlap on a multi-core machine; the queues are
bounded (``depth`` frames), so memory stays flat whatever the video's length.

Errors: an exception in any stage stops the others and is raised in the caller's thread (the decoder's or the
writer's own exception, not a secondary one), after both threads have ended. The caller's ``OutputSet`` then
discards every temporary output, so nothing half-written remains. KeyboardInterrupt (Ctrl-C, or a signal the
CLI turns into one) reaches the caller's thread and is handled the same way.
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Iterator

from ..imaging import thumbnail
from ..io.frames import Frame, gray
from .timing import timed

__all__ = ["read_ahead", "ResultWriter", "run_pipeline", "PipelineTimes", "grey_frames", "keep_freed_memory"]

_END = object()
_POLL = 0.1  # seconds between checks of the other side while a queue is full or empty


class _Failure:
    def __init__(self, exc: BaseException):
        self.exc = exc


def _put(q: queue.Queue, item, stop: threading.Event) -> bool:
    """Put ``item`` unless ``stop`` is set meanwhile; False when stopped."""
    while not stop.is_set():
        try:
            q.put(item, timeout=_POLL)
            return True
        except queue.Full:
            continue
    return False


def _wait(done: threading.Event) -> None:
    """Wait until ``done`` is set. (Not ``Thread.join``: a join interrupted by a signal's exception can take the
    thread for ended while it still runs, and the caller would then close what the thread still uses.)"""
    while not done.wait(_POLL):
        pass


def read_ahead(iterable: Iterable, *, depth: int = 32, chunk: int = 8, name: str = "aamtrack-decode") -> Iterator:
    """Yield the items of ``iterable``, produced ahead in a thread (at most about ``depth`` waiting).

    Items cross in lists of ``chunk``: one hand-over (a lock and a wake-up, each taking the GIL) per chunk
    rather than per item. An exception raised while producing an item is raised here, at that item's place in
    the sequence. Closing the generator (or an exception in the consumer) stops the thread and waits for it.
    """
    chunk = max(1, chunk)
    q: queue.Queue = queue.Queue(maxsize=max(1, depth // chunk))
    stop, ended = threading.Event(), threading.Event()

    def produce():
        items = []
        try:
            for item in iterable:
                items.append(item)
                if len(items) >= chunk:
                    if not _put(q, items, stop):
                        return
                    items = []
            if items and not _put(q, items, stop):
                return
            _put(q, _END, stop)
        except BaseException as exc:  # handed to the consumer, raised there
            if not items or _put(q, items, stop):
                _put(q, _Failure(exc), stop)
        finally:
            ended.set()

    thread = threading.Thread(target=produce, name=name, daemon=True)
    thread.start()
    try:
        while True:
            try:
                item = q.get(timeout=_POLL)
            except queue.Empty:
                if ended.is_set() and q.empty():  # pragma: no cover - the producer always says why it ended
                    raise RuntimeError("frame reader ended without a reason") from None
                continue
            if item is _END:
                return
            if isinstance(item, _Failure):
                raise item.exc
            yield from item
    finally:
        stop.set()
        _wait(ended)


class ResultWriter:
    """Hands results to ``consume`` in a thread, in order (a bounded queue of ``depth`` items between).

    ``put(item)`` raises the writer's exception as soon as the writer has failed; ``finish()`` waits for every
    item to be consumed and raises it too; ``stop()`` (on the caller's own failure) ends the thread without
    consuming what is left. ``consume_all`` receives the whole stream as an iterator (so a stateful filter such as
    smoothing can sit in the writer thread) and is called once.
    """

    def __init__(self, consume_all: Callable[[Iterator], None], *, depth: int = 64, chunk: int = 8,
                 name: str = "aamtrack-write"):
        self._chunk = max(1, chunk)
        self._buf: list = []
        self._q: queue.Queue = queue.Queue(maxsize=max(1, depth // self._chunk))
        self._stop, self._ended = threading.Event(), threading.Event()
        self._error: BaseException | None = None
        self._consume_all = consume_all
        self._thread = threading.Thread(target=self._main, name=name, daemon=True)
        self._thread.start()

    def _items(self) -> Iterator:
        while not self._stop.is_set():
            try:
                item = self._q.get(timeout=_POLL)
            except queue.Empty:
                continue
            if item is _END:
                return
            yield from item

    def _main(self) -> None:
        try:
            self._consume_all(self._items())
        except BaseException as exc:  # raised in the caller's thread by put()/finish()
            self._error = exc
            self._stop.set()
        finally:
            self._ended.set()

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def put(self, item) -> None:
        self._buf.append(item)
        if len(self._buf) >= self._chunk:
            self._flush()

    def _flush(self) -> None:
        self._raise()
        items, self._buf = self._buf, []
        if items and not _put(self._q, items, self._stop):
            self._raise()
            raise RuntimeError("result writer stopped")  # pragma: no cover - stop() is only called on failure

    def finish(self) -> None:
        """Wait until everything put has been consumed; raise the writer's exception if it failed."""
        self._flush()
        _put(self._q, _END, self._stop)
        _wait(self._ended)
        self._raise()

    def stop(self) -> None:
        """End the thread now, dropping what it has not consumed (the run failed elsewhere)."""
        self._stop.set()
        _wait(self._ended)


def keep_freed_memory(*, trim_mb: int = 256, mmap_mb: int = 32) -> bool:
    """Ask glibc's allocator to keep freed memory for reuse instead of giving it back to the system at once.

    Every frame allocates and frees the same few arrays (the crop, its feature levels, the search's
    temporaries: hundreds of kB each). glibc may return such blocks to the system (``munmap``, or a trim of the
    heap's top) as soon as they are freed, and the next frame then faults the pages in again. Measured on this
    project's shared VM (cap12 at 640x480, 8022 frames, ``track_file`` in one thread, 3 pairs of runs): 21.1,
    20.9, 18.5 s without, 13.5, 16.0, 13.1 s with, system time 3.8-5.8 s against 0.7-3.2 s; the gain depends
    on the machine's load and was not seen in every comparison (see benchmarks/throughput.py). With this, up
    to ``trim_mb`` MB of freed heap are kept, and blocks below ``mmap_mb`` MB come from the heap. Process-wide,
    so the command line calls it, not the library; a no-op (False) where the C library has no ``mallopt``
    (not glibc)."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError, TypeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's malloc.h
    return bool(mallopt(m_trim_threshold, int(trim_mb) << 20)) and bool(mallopt(m_mmap_threshold, int(mmap_mb) << 20))


def grey_frames(frames: Iterable) -> Iterator:
    """The frames with their images turned grey ((H, W) uint8; the tracker and the detector take grey images and
    give the same results: they convert BGR to grey themselves, pixel by pixel), each with its thumbnail for the
    tracker's shot-change test (``imaging.thumbnail``). Run in the decoding thread, this takes the conversion and
    the thumbnail off the tracker's thread (and the detector converts once instead of once per try)."""
    for f in frames:
        g = None if f.image is None else gray(f.image)
        yield Frame(f.index, f.timestamp, g, None if g is None else thumbnail(g))


@dataclass
class PipelineTimes:
    """Per-frame seconds of each stage (decode in the reader thread, output in the writer thread)."""

    decode: list = field(default_factory=list)
    output: list = field(default_factory=list)
    n_frames: int = 0
    t_first: float | None = None
    cpu_s: dict = field(default_factory=dict)  # CPU seconds of each thread: decode, track, write


def _cpu_timed(items: Iterable, cpu: dict, key: str) -> Iterator:
    """Yield ``items``, adding to ``cpu[key]`` the CPU time of the thread that iterates (time.thread_time)."""
    t = time.thread_time()
    try:
        yield from items
    finally:
        cpu[key] = cpu.get(key, 0.0) + time.thread_time() - t


def run_pipeline(frames: Iterable, results_of: Callable[[Iterable], Iterable], write: Callable,
                 *, smooth: Callable[[Iterable], Iterable] | None = None, on_result: Callable | None = None,
                 replay: Callable[[Iterable], Iterable] | None = None, depth: int = 32,
                 write_depth: int = 64, pipelined: bool = True) -> PipelineTimes:
    """Run ``results_of(frames)`` (the tracker) in this thread between a reader and a writer thread.

    Parameters
    ----------
    frames : iterable of frames (a FrameSource), read ahead in a thread
    results_of : frames -> iterable of FrameResult (the tracker's generator, annotated)
    write : called with each (smoothed) FrameResult, in frame order, in the writer thread
    smooth : optional stream filter applied in the writer thread (One Euro smoothing)
    on_result : called in this thread with each raw result (counts, progress bar)
    replay : optional filter on the frames in this thread (``--realtime``: its clock is the tracker's demand)
    depth : frames decoded ahead at most (about: they cross in chunks of up to 8, a quarter of ``depth``)
    write_depth : results waiting for the writer at most (about; keep it small when each holds an image)
    pipelined : False runs every stage in this thread (the single-thread reference; same outputs)
    """
    times = PipelineTimes()
    decoded = _cpu_timed(timed(frames, times.decode), times.cpu_s, "decode")

    def consume_all(results):
        t_cpu = time.thread_time()
        stream = smooth(results) if smooth is not None else results
        try:
            for res in stream:
                t = time.perf_counter()
                write(res)
                times.output.append(time.perf_counter() - t)
        finally:
            times.cpu_s["write"] = times.cpu_s.get("write", 0.0) + time.thread_time() - t_cpu

    if not pipelined:
        stream = decoded if replay is None else replay(decoded)

        def counted(results):
            for res in results:
                times.t_first = times.t_first or time.perf_counter()
                times.n_frames += 1
                if on_result is not None:
                    on_result(res)
                yield res

        consume_all(counted(results_of(stream)))
        return times

    t_cpu = time.thread_time()
    ahead = read_ahead(decoded, depth=depth, chunk=max(1, min(8, depth // 4)))
    writer = ResultWriter(consume_all, depth=write_depth, chunk=max(1, min(8, write_depth // 4)))
    try:
        stream = ahead if replay is None else replay(ahead)
        for res in results_of(stream):
            times.t_first = times.t_first or time.perf_counter()
            times.n_frames += 1
            if on_result is not None:
                on_result(res)
            writer.put(res)
        writer.finish()
    except BaseException:
        writer.stop()
        raise
    finally:
        ahead.close()
        times.cpu_s["track"] = time.thread_time() - t_cpu
    return times
