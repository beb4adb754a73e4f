"""Run summary as JSON, written atomically, with numpy values turned into plain Python."""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import os
from pathlib import PurePath
from typing import Any

import numpy as np

from .atomic import atomic_write

__all__ = ["write_summary_json", "to_jsonable"]


def to_jsonable(value: Any) -> Any:
    """Convert ``value`` recursively to what :func:`json.dump` writes as standard JSON.

    numpy scalars become int/float/bool, arrays nested lists, tuples and sets lists, paths strings, dataclasses
    dicts, enums their value, dict keys strings. NaN and infinities become None (JSON has no NaN).
    """
    if isinstance(value, dict):
        return {str(to_jsonable(k)) if not isinstance(k, str) else _text(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return [to_jsonable(v) for v in sorted(value, key=repr)]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, np.generic):
        return to_jsonable(value.item())
    if isinstance(value, PurePath):
        return _text(str(value))
    if isinstance(value, enum.Enum):
        return to_jsonable(value.value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_jsonable(dataclasses.asdict(value))
    if isinstance(value, str):
        return _text(value)
    if value is None:
        return value
    raise TypeError(f"cannot write {type(value).__name__} to JSON: {value!r:.60}")


def _text(value: str) -> str:
    """``value``, with bytes of a file name that are not UTF-8 (surrogates in Python) shown as ``\\xff``."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        try:
            return value.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
        except UnicodeEncodeError:
            return value.encode("utf-8", "backslashreplace").decode("utf-8")
    return value


def write_summary_json(path: str | os.PathLike, data: dict) -> None:
    """Write ``data`` to ``path`` as JSON (indent 2, UTF-8, trailing newline), atomically.

    Parameters
    ----------
    path : str or PathLike
        Destination; its folder must exist.
    data : dict
        Anything :func:`to_jsonable` converts (numpy scalars and arrays included).

    Raises
    ------
    TypeError
        A value that has no JSON form; nothing is written then.
    """
    text = json.dumps(to_jsonable(data), indent=2, ensure_ascii=False, allow_nan=False)
    with atomic_write(path, "w", newline="\n") as f:
        f.write(text + "\n")
