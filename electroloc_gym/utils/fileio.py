"""The package's one I/O layer: atomic writes, strict JSON and exclusive folder locks.

* :func:`check_output_path`: an output path refused before any work when it cannot be written as a file.
* Atomic writes: a temp file in the target's folder, fsync, then ``os.replace`` — results, models and
  figures are never left half-written: a reader sees the old file or the new one.
* Strict JSON (:func:`to_json_data`, :func:`strict_json`, :func:`write_json_atomic`): NaN and ±inf
  become ``null``, numpy scalars and arrays become plain numbers and lists, so every JSON reader
  accepts what the package writes.
* :class:`FolderLock`: an exclusive, non-blocking lock on a file inside a folder (``filelock``, so it
  works on POSIX and Windows alike), held while a run writes into that folder.

Used by the benchmark, the training path, the figures and the CLI.
"""

from __future__ import annotations

import io
import json
import math
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from filelock import FileLock, Timeout

__all__ = [
    "check_output_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "save_figure_atomic",
    "to_json_data",
    "strict_json",
    "write_json_atomic",
    "FolderLock",
    "FolderBusyError",
]


def check_output_path(name: str, path: str | os.PathLike[str], suffixes: tuple[str, ...] | None = None) -> None:
    """Refuse, before any work, an output path that cannot be written as a file (ValueError naming ``name``).

    Args:
        name: the option or argument, for the message.
        path: the file to write.
        suffixes: the allowed suffixes without the dot (None: any); a path without a suffix is refused too.
    """
    p = Path(path)
    if not str(path).strip():
        raise ValueError(f"{name} must be a file path, got an empty string")
    if p.is_dir():
        raise ValueError(f"{name} must be a file path, got the directory {str(p)!r}")
    parent = p.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{name}: cannot create {str(p)!r}, {str(parent)!r} is a file")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ValueError(f"{name}: cannot write {str(p)!r}, folder {str(parent)!r} is not writable")
    if suffixes is not None and p.suffix.lower().lstrip(".") not in suffixes:
        raise ValueError(
            f"{name} {str(p)!r}: the format {p.suffix or '(none)'!r} is not supported; "
            f"use one of {', '.join('.' + x for x in suffixes)}"
        )


def probe_write(folder: str | os.PathLike[str]) -> None:
    """Create and remove a temporary file in ``folder``: a real write, since permission bits say nothing for
    root or a read-only file system. Raises the ``OSError`` of a folder that cannot be written.
    """
    fd, probe = tempfile.mkstemp(dir=folder, prefix=".electroloc-probe-")
    os.close(fd)
    os.unlink(probe)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, durable: bool = True) -> None:
    """Write ``data`` to ``path`` atomically (parent folders are created).

    ``durable=False`` skips the fsync: the replacement is as atomic for a killed process; only a crash of
    the machine can lose it.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            if durable:
                fh.flush()
                os.fsync(fh.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; results are meant to be shared like any file
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str, *, durable: bool = True) -> None:
    """UTF-8 text version of :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"), durable=durable)


def save_figure_atomic(fig: Any, path: str | os.PathLike[str], **kwargs: Any) -> None:
    """Save a matplotlib figure atomically; the format follows the suffix (default PNG)."""
    suffix = os.path.splitext(os.fspath(path))[1].lstrip(".") or "png"
    buf = io.BytesIO()
    fig.savefig(buf, format=suffix, **kwargs)
    atomic_write_bytes(path, buf.getvalue())


def to_json_data(obj: Any) -> Any:
    """``obj`` as plain JSON data: NaN/±inf → None, numpy scalars/arrays → numbers/lists, tuples → lists,
    mapping keys → str. Anything else that ``json`` cannot write is left for it to refuse.
    """
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.ndarray):
        return to_json_data(obj.tolist())
    if isinstance(obj, Mapping):
        return {str(k): to_json_data(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json_data(v) for v in obj]
    return obj


def strict_json(obj: Any, indent: int | None = 2) -> str:
    """Strict JSON text of ``obj`` (through :func:`to_json_data`; no NaN), ending in a newline."""
    return json.dumps(to_json_data(obj), indent=indent, allow_nan=False, ensure_ascii=False) + "\n"


def write_json_atomic(path: str | os.PathLike[str], obj: Any, indent: int | None = 2) -> None:
    """Write :func:`strict_json` of ``obj`` to ``path`` atomically."""
    atomic_write_text(path, strict_json(obj, indent=indent))


class FolderBusyError(ValueError):
    """Another process holds the folder's lock."""


class FolderLock:
    """Exclusive, non-blocking lock on ``folder/name`` (a context manager; ``filelock`` underneath).

    Args:
        folder: the folder the run writes into (created if missing).
        name: the lock file's name inside it.
        busy_message: the :class:`FolderBusyError` message when another process holds the lock.

    Raises:
        FolderBusyError: on :meth:`acquire` when another process holds the lock.
    """

    def __init__(self, folder: str | os.PathLike[str], name: str, busy_message: str) -> None:
        self.path = Path(folder) / name
        self._busy = busy_message
        self._lock: FileLock | None = None

    def acquire(self) -> FolderLock:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(self.path), timeout=0, is_singleton=False)
        try:
            lock.acquire()
        except Timeout:
            raise FolderBusyError(self._busy) from None
        self._lock = lock
        return self

    def release(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()
