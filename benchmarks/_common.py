"""Helpers shared by the benchmark scripts (stdlib only, so any of their environments can import it)."""

from __future__ import annotations

import json
import math
import os
import platform
import sys
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


def json_safe(value):
    """``value`` with NaN as None, tuples as lists and numpy scalars and arrays as Python numbers and lists."""
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalar or array, without importing numpy here
        return json_safe(value.tolist())
    return value


def write_json(path: Path, result, *, indent: int = 1) -> None:
    """Write ``json_safe(result)`` to ``path`` under a temporary name, renamed when complete."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(json_safe(result), indent=indent) + "\n")
    tmp.replace(path)


def run_script(main, name: str) -> None:
    """``sys.exit(main())`` for a benchmark script called ``name``, with the package's input errors (a missing or
    unreadable file, a bad model, ``AamtrackError``) and the system's (``OSError``) as one line on stderr and exit
    status 1 instead of a traceback; anything else (a bug) still shows its traceback."""
    from aamtrack.errors import AamtrackError

    try:
        code = main()
    except (AamtrackError, OSError) as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        code = 1
    sys.exit(code)
