"""Helpers shared by the benchmark scripts (stdlib only, so any of their environments can import it)."""

from __future__ import annotations

import os
import platform
from pathlib import Path


def machine_name() -> str:
    """CPU model name (from /proc/cpuinfo where there is one) and core count."""
    name = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{name}, {os.cpu_count()} logical CPUs"
