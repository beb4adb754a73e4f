"""Atomic file output: write to a temporary name in the destination folder, rename when complete.

A reader never sees a half-written output, and a failed run leaves an existing file untouched and no temporary
file behind. The rename is ``os.replace``, atomic on POSIX and Windows when both names are on one file system
(always the case here: the temporary file sits next to the destination).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import secrets
import shutil
import stat
from pathlib import Path
from typing import IO, Iterator

import numpy as np

from ..errors import OutputError

__all__ = ["atomic_write", "save_npz", "temporary_path", "commit_temporary", "discard_temporary",
           "check_replaceable", "output_error", "OutputSet"]

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


def _shown(path) -> str:
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def output_error(path: str | os.PathLike, exc: OSError) -> OutputError:
    """The one-line :class:`OutputError` for an OSError met while writing ``path`` (disk full, read-only...)."""
    reason = exc.strerror or str(exc)
    if exc.errno == errno.ENOSPC:
        reason = "no space left on the device"
    return OutputError(f"{_shown(path)}: cannot write ({reason})")


def check_replaceable(path: str | os.PathLike, *, folder: bool = False) -> None:
    """Raise :class:`OutputError` unless ``path`` is absent or a regular file (with ``folder``: a folder).

    Outputs only ever replace regular files: never a device node (``/dev/null``), a pipe, a socket or a
    symbolic link, which a rename would silently swap for a plain file.
    """
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise output_error(path, exc) from None
    if folder and stat.S_ISDIR(st.st_mode):
        return
    if not stat.S_ISREG(st.st_mode):
        what = ("a folder" if stat.S_ISDIR(st.st_mode) else "a symbolic link" if stat.S_ISLNK(st.st_mode)
                else "a device or special file")
        raise OutputError(f"{_shown(path)}: exists and is {what}; outputs only replace regular files")


def commit_temporary(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    """Rename the finished temporary file ``tmp`` to ``path``, keeping the mode of a file it replaces.

    Raises :class:`OutputError` (and leaves ``tmp`` in place for the caller to discard) when ``path`` exists
    and is not a regular file.
    """
    tmp, path = Path(tmp), Path(path)
    check_replaceable(path)
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
    check_replaceable(path)
    tmp = temporary_path(path, keep_suffix=False)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    except OSError as exc:
        raise output_error(path, exc) from None
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
    except OSError as exc:
        discard_temporary(tmp)
        raise output_error(path, exc) from None
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

    def _finish(self) -> None:
        """Check the released temporary file before it is renamed (raise to refuse it)."""

    def _closed(self) -> None:
        pass

    def close(self) -> None:
        """Finish: release the resource and rename the temporary file to ``path``. Idempotent."""
        if self._handle is None:
            return
        try:
            self._release()
            self._finish()
            commit_temporary(self._tmp, self.path)
        except OSError as exc:
            discard_temporary(self._tmp)
            raise output_error(self.path, exc) from None
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
        except OSError as exc:  # e.g. a flush into a full disk: the file is being thrown away anyway
            logger.debug("%s: %s while aborting", self.path, exc)
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


class OutputSet:
    """All outputs of one run, built under temporary names in ``folder`` and committed together at the end.

    ``prepare()`` creates the folder if needed and checks it is writable, before any work. Each output is
    written to the temporary name :meth:`file` or :meth:`folder_output` hands out; :meth:`commit` then renames them
    all to their final names, or, if any rename fails, puts back what was there before: all or none. Used as a
    context manager, any exception (including KeyboardInterrupt and the signals the CLI turns into one)
    discards the temporaries and removes a folder ``prepare()`` created, so a failed run leaves nothing behind.

    Outputs only replace regular files (and a folder output an earlier run's folder of regular files).
    """

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)
        self._entries: list[tuple[Path, Path, bool]] = []  # (temporary, final, is_folder)
        self._created: list[Path] = []
        self._done = False

    def prepare(self) -> OutputSet:
        """Create the output folder (and missing parents) and check a file can be created in it."""
        missing = []
        p = self.folder
        while not os.path.lexists(p) and p != p.parent:
            missing.append(p)
            p = p.parent
        if os.path.lexists(p) and not p.is_dir():
            raise OutputError(f"{_shown(p)}: exists and is not a folder")
        for d in reversed(missing):
            try:
                d.mkdir()
            except FileExistsError:
                continue
            except OSError as exc:
                self._remove_created()
                raise output_error(d, exc) from None
            self._created.append(d)
        probe = temporary_path(self.folder / "probe", keep_suffix=False)
        try:
            os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            os.unlink(probe)
        except OSError as exc:
            self._remove_created()
            raise OutputError(f"{_shown(self.folder)}: output folder is not writable "
                              f"({exc.strerror or exc})") from None
        return self

    def file(self, name: str, *, keep_suffix: bool = True) -> Path:
        """A temporary path for the output file ``folder/name`` (only the name is chosen)."""
        final = self.folder / name
        check_replaceable(final)
        tmp = temporary_path(final, keep_suffix=keep_suffix)
        self._entries.append((tmp, final, False))
        return tmp

    def folder_output(self, name: str) -> Path:
        """A temporary folder, created now, that becomes the output folder ``folder/name`` on commit."""
        final = self.folder / name
        check_replaceable(final, folder=True)
        if final.is_dir() and any(not (c.is_file() and not c.is_symlink()) for c in final.iterdir()):
            raise OutputError(f"{_shown(final)}: exists and holds more than files; not replaced")
        tmp = temporary_path(final, keep_suffix=False)
        try:
            tmp.mkdir()
        except OSError as exc:
            raise output_error(final, exc) from None
        self._entries.append((tmp, final, True))
        return tmp

    def written(self, tmp: Path, actual: Path) -> Path:
        """The output planned at ``tmp`` was written to ``actual`` (a writer may change the suffix, as the
        overlay's fallback to .avi does); returns its final path, with that suffix."""
        for k, (t, final, is_dir) in enumerate(self._entries):
            if t == Path(tmp):
                final = final.with_suffix(Path(actual).suffix)
                check_replaceable(final)
                self._entries[k] = (Path(actual), final, is_dir)
                return final
        raise KeyError(tmp)

    def commit(self) -> None:
        """Rename every temporary to its final name; on failure restore what stood there and raise."""
        backups, committed = [], []
        try:
            for tmp, final, is_dir in self._entries:
                if not os.path.lexists(tmp):
                    raise OutputError(f"{_shown(final)}: output was not written")
                check_replaceable(final, folder=is_dir)
                if os.path.lexists(final):
                    if not is_dir:
                        with contextlib.suppress(OSError):
                            os.chmod(tmp, os.stat(final).st_mode & 0o7777)
                    backup = temporary_path(final, keep_suffix=False)
                    os.replace(final, backup)
                    backups.append((backup, final))
                os.replace(tmp, final)
                committed.append(final)
        except BaseException as exc:
            for final in committed:
                _remove(final)
            for backup, final in backups:
                with contextlib.suppress(OSError):
                    os.replace(backup, final)
            self.discard()
            if isinstance(exc, OSError):
                raise output_error(self.folder, exc) from None
            raise
        for backup, _ in backups:
            _remove(backup)
        self._done = True
        self._entries = []
        self._created = []

    def discard(self) -> None:
        """Delete every temporary and the folders ``prepare()`` created (if empty). Idempotent."""
        for tmp, _, _ in self._entries:
            _remove(tmp)
        self._entries = []
        self._remove_created()

    def _remove_created(self) -> None:
        for d in reversed(self._created):
            with contextlib.suppress(OSError):
                d.rmdir()
        self._created = []

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._done:
            return
        entries = list(self._entries)
        self.discard()
        if isinstance(exc, OSError) and exc.filename is not None:  # an output's own write failed
            names = [str(t) for t, _, _ in entries]
            if any(os.fsdecode(exc.filename).startswith(n) for n in names):
                exc = output_error(exc.filename, exc)
        if isinstance(exc, OutputError):  # name the output, not its temporary file
            text = str(exc)
            for tmp, final, _ in entries:
                text = text.replace(_shown(tmp), _shown(final))
            raise OutputError(text) from None


def _remove(path: Path) -> None:
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path)
        else:
            os.unlink(path)
    except FileNotFoundError:
        pass
    except OSError as exc:  # pragma: no cover - e.g. a read-only folder
        logger.warning("could not remove %s: %s", _shown(path), exc)
