"""Replaying a recorded video as a live camera would deliver it (``aamtrack run --realtime``).

Frame i arrives at ``start + i / fps``. The filter is lazy, so "now" is when the tracker asks for its next frame:
a frame that has not arrived yet is waited for; a frame that has arrived while a newer one has also arrived is
dropped (a camera hands over its newest frame); otherwise it is processed. Every frame is still yielded, in
order, so the output keeps one row per frame; dropped ones carry ``dropped = True`` and no image.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator


@dataclass(frozen=True)
class ReplayFrame:
    index: int
    timestamp: float
    image: object
    dropped: bool = False


def realtime(frames: Iterable, fps: float, *, clock: Callable[[], float] = time.perf_counter,
             sleep: Callable[[float], None] = time.sleep) -> Iterator[ReplayFrame]:
    start = None
    for f in frames:
        now = clock()
        if start is None:
            start = now - f.index / fps
        arrival = start + f.index / fps
        if arrival > now:
            sleep(arrival - now)
            yield ReplayFrame(f.index, f.timestamp, f.image)
        elif start + (f.index + 1) / fps <= now:
            yield ReplayFrame(f.index, f.timestamp, None, dropped=True)
        else:
            yield ReplayFrame(f.index, f.timestamp, f.image)
