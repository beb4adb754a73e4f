"""Training's per-image work on the machine's cores, with the results of one core.

The kernels release the GIL (``_kernels._flags.NJIT``: nogil) and so does OpenCV, so threads share the per-image
searches, landmark cascades and Haar searches of training: a validator's fit of a training photo (search, cascade)
ran 1.8 times as fast on two threads as on one (60 helen_train photos, 2-core VM, /tmp 2026-12-01). Whatever draws
random numbers stays in the calling thread, in the order it always drew them (``ordered_map``'s items are made
there, lazily); the threads get work that draws nothing, and its results come back in order. A model trained
with any number of workers is the one trained with one (``tests/train/test_workers.py``, bit for bit on a synthetic
3D model; helen_train's 3D model under ``OMP_NUM_THREADS=1``: every array, but two validators' weights 2e-11
apart, benchmarks/README "Training on both cores").
"""

from __future__ import annotations

import os
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Iterable, Iterator, TypeVar

T = TypeVar("T")
R = TypeVar("R")


def default_workers() -> int:
    """The cores this process may run on (``os.sched_getaffinity`` where there is one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def ordered_map(fn: Callable[[T], R], items: Iterable[T], workers: int) -> Iterator[R]:
    """fn(item) for each of items, in their order, on up to ``workers`` threads (1: in this thread, one by one).
    items is read in this thread, a few ahead of the results (twice ``workers``): a generator that draws random
    numbers to make them draws them as it would without threads, and holds few of them at once."""
    if workers <= 1:
        yield from map(fn, items)
        return
    with ThreadPoolExecutor(workers, thread_name_prefix="aamtrack-train") as pool:
        pending = deque()
        try:
            for item in items:
                pending.append(pool.submit(fn, item))
                if len(pending) >= 2 * workers:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:  # an error or an abandoned generator: drop what has not started
            for f in pending:
                f.cancel()


def for_each(fn: Callable[[T], object], items: Iterable[T], workers: int) -> None:
    """fn(item) for each of items, for what it writes (each item its own part of an output), as ``ordered_map``
    runs it; returns when all are done."""
    for _ in ordered_map(fn, items, workers):
        pass


def beside(fn: Callable[..., R], *args, workers: int) -> Callable[[], R]:
    """fn(*args) started on a thread of its own while the caller goes on (``workers`` > 1; 1: run when first asked
    for, in the caller's thread); returns what gives its result, the same object each time (waiting for it,
    raising its error). For work that draws no random numbers and mostly releases the GIL (OpenCV's Haar
    searches) beside work that holds it."""
    got = {}
    if workers <= 1:
        def when_asked() -> R:  # once
            if "result" not in got:
                got["result"] = fn(*args)
            return got["result"]

        return when_asked

    def run():
        try:
            got["result"] = fn(*args)
        except BaseException as exc:  # handed to the caller when it asks
            got["error"] = exc

    # a daemon: training that fails before it asks does not wait for the thread to end before it exits
    thread = threading.Thread(target=run, name="aamtrack-beside", daemon=True)
    thread.start()

    def result() -> R:
        thread.join()
        if "error" in got:
            raise got["error"]
        return got["result"]

    return result


class PerThread:
    """One object per thread, made by ``make()`` at its first ``get`` there: for what serves one thread at a time
    (a ``Searcher``'s scratch buffers, an OpenCV ``CascadeClassifier``)."""

    def __init__(self, make: Callable[[], T]):
        self._make, self._local = make, threading.local()

    def get(self) -> T:
        obj = getattr(self._local, "obj", None)
        if obj is None:
            obj = self._local.obj = self._make()
        return obj
