"""Per-frame timing helpers shared by ``aamtrack run``'s summary, ``aamtrack bench`` and the benchmarks."""

from __future__ import annotations

import time
from typing import Iterable, Iterator

import numpy as np


def timed(iterable: Iterable, seconds: list) -> Iterator:
    """Yield the items of ``iterable``, appending to ``seconds`` how long producing each one took (decoding a
    frame, or a tracker step when ``iterable`` is a tracker's generator)."""
    it = iter(iterable)
    while True:
        t = time.perf_counter()
        try:
            item = next(it)
        except StopIteration:
            return
        seconds.append(time.perf_counter() - t)
        yield item


def ms_stats(values) -> dict | None:
    """Median, p90 and max of durations in seconds, in milliseconds, with their count (None when empty)."""
    if len(values) == 0:
        return None
    v = 1e3 * np.asarray(values, dtype=float)
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "max": float(v.max()), "n": len(v)}
