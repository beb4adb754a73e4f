"""Atomic file output: write to a temporary name in the destination folder, rename when complete.

A reader never sees a half-written output, and a failed run leaves an existing file untouched and no temporary
file behind. The rename is ``os.replace``, atomic on POSIX and Windows when both names are on one file system
(always the case here: the temporary file sits next to the destination).
"""

from __future__ import annotations

import contextlib
import logging
import os
import secrets
from pathlib import Path
from typing import IO, Iterator

import numpy as np

__all__ = ["atomic_write", "save_npz", "temporary_path", "commit_temporary", "discard_temporary"]

logger = logging.getLogger(__name__)

_MODES = ("w", "wt", "wb")


def temporary_path(path: str | os.PathLike, *, keep_suffix: bool = True) -> Path:
    """A fresh, unused temporary name next to ``path``.

    ``dir/name.mp4`` becomes ``dir/.name.<random>.tmp.mp4`` (with ``keep_suffix``, so that libraries that pick a
    format from the extension, like OpenCV's VideoWriter, still see it) or ``dir/.name.mp4.<random>.tmp``.
    The name is only chosen, not created.
    """
    path = Path(path)
    token = secrets.token_hex(4)
    if keep_suffix and path.suffix:
        return path.with_name(f".{path.stem}.{token}.tmp{path.suffix}")
    return path.with_name(f".{path.name}.{token}.tmp")


def commit_temporary(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    """Rename the finished temporary file ``tmp`` to ``path``, keeping the mode of a file it replaces."""
    tmp, path = Path(tmp), Path(path)
    with contextlib.suppress(OSError):
        os.chmod(tmp, os.stat(path).st_mode & 0o7777)
    os.replace(tmp, path)
    logger.debug("wrote %s", path)


def discard_temporary(tmp: str | os.PathLike) -> None:
    """Delete the temporary file ``tmp`` if it exists (errors are logged, never raised)."""
    try:
        Path(tmp).unlink(missing_ok=True)
    except OSError as exc:  # pragma: no cover - e.g. a read-only folder
        logger.warning("could not remove temporary file %s: %s", tmp, exc)


@contextlib.contextmanager
def atomic_write(
    path: str | os.PathLike,
    mode: str = "w",
    *,
    encoding: str = "utf-8",
    newline: str | None = None,
    fsync: bool = False,
) -> Iterator[IO]:
    """Open a temporary file next to ``path`` for writing; rename it to ``path`` when the block ends normally.

    Parameters
    ----------
    path : str or PathLike
        Destination. Its folder must exist.
    mode : {"w", "wt", "wb"}
        Text or binary.
    encoding, newline : str
        As for :func:`open`, text mode only (``newline=""`` for the csv module).
    fsync : bool
        Flush the data to disk before the rename (survives a power cut, costs a disk sync per file).

    Yields
    ------
    file object
        Open on the temporary file.

    Notes
    -----
    If the block raises, the temporary file is deleted, ``path`` is left as it was (absent or the old
    content), and the exception propagates. The new file gets the mode of the file it replaces, else the usual
    ``0o666 & ~umask``.

    Examples
    --------
    >>> with atomic_write(tmp / "out.txt") as f:  # doctest: +SKIP
    ...     f.write("done\\n")
    """
    if mode not in _MODES:
        raise ValueError(f"atomic_write mode must be one of {_MODES}, got {mode!r}")
    path = Path(path)
    tmp = temporary_path(path, keep_suffix=False)
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        if "b" in mode:
            f = os.fdopen(fd, "wb")
        else:
            f = os.fdopen(fd, "w", encoding=encoding, newline=newline)
    except BaseException:
        os.close(fd)
        discard_temporary(tmp)
        raise
    try:
        with f:
            yield f
            f.flush()
            if fsync:
                os.fsync(f.fileno())
        commit_temporary(tmp, path)
    except BaseException:
        discard_temporary(tmp)
        raise


def save_npz(path: str | os.PathLike, /, **arrays: np.ndarray) -> None:
    """Save ``arrays`` with :func:`numpy.savez_compressed` to exactly ``path``, atomically.

    Unlike ``np.savez_compressed(str_path, ...)`` no ``.npz`` is appended to the name. Load with
    ``np.load(path, allow_pickle=False)``.
    """
    with atomic_write(path, "wb") as f:
        np.savez_compressed(f, **arrays)


class TemporaryOutput:
    """Base of writers that build their file under a temporary name (``self._tmp``) and rename it to
    ``self.path`` on ``close()``; ``abort()``, an exception leaving a ``with`` block, or garbage collection of
    an unclosed writer delete the temporary instead, so nothing half-written ever stands at ``path``.

    Subclasses keep the open resource in ``self._handle`` (None once finished) and define ``_release()``
    (flush and close it) and optionally ``_closed()`` (called after a successful rename).
    """

    _handle = None

    def _release(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _closed(self) -> None:
        pass

    def close(self) -> None:
        """Finish: release the resource and rename the temporary file to ``path``. Idempotent."""
        if self._handle is None:
            return
        try:
            self._release()
            commit_temporary(self._tmp, self.path)
        except BaseException:
            discard_temporary(self._tmp)
            raise
        finally:
            self._handle = None
        self._closed()

    def abort(self) -> None:
        """Give up: delete the temporary file; nothing is written to ``path``. Idempotent."""
        if self._handle is None:
            return
        try:
            self._release()
        finally:
            self._handle = None
            discard_temporary(self._tmp)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def __del__(self):  # an unclosed writer must not leave its temporary file behind
        if getattr(self, "_handle", None) is not None:
            self.abort()
