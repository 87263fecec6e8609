"""The package's one I/O layer: output-path checks, atomic writes, strict JSON and exclusive folder locks.

* An output file or folder that cannot be written is refused before any work.
* Atomic writes: a temp file in the target's folder, fsync, then ``os.replace`` — a reader sees the old
  file or the new one, never half of one.
* Strict JSON: NaN and ±inf become ``null``, numpy scalars and arrays plain numbers and lists, so every JSON
  reader accepts what the package writes.
* :class:`FolderLock`: held while a run writes into a folder (``filelock``: POSIX and Windows alike).
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from stat import S_ISLNK
from typing import Any

import numpy as np
from filelock import FileLock, Timeout

__all__ = [
    "user_path",
    "check_output_path",
    "check_output_folder",
    "check_output_options",
    "probe_write",
    "naming_file",
    "atomic_write_bytes",
    "atomic_write_text",
    "save_figure_atomic",
    "to_json_data",
    "strict_json",
    "write_json_atomic",
    "os_error_line",
    "WRITE_ERRNOS",
    "FolderLock",
    "FolderBusyError",
]


#: Name lengths when the file system does not say (``os.pathconf`` unavailable): POSIX's usual limits, bytes.
FALLBACK_NAME_MAX = 255
FALLBACK_PATH_MAX = 4096
#: What :func:`atomic_write_bytes` adds to a file's name for its temporary file (``.NAME.XXXXXXXX.tmp``), bytes:
#: a file's name must leave room for it.
TEMP_NAME_EXTRA = len(".") + len(".") + 8 + len(".tmp")


def _pathconf(folder: Path, key: str, fallback: int) -> int:
    try:
        value = os.pathconf(folder, key)
    except (OSError, ValueError, AttributeError):  # Windows, or a file system that does not say
        return fallback
    return value if value > 0 else fallback


def _existing_folder(name: str, path: Path) -> tuple[Path, bool]:
    """The nearest folder of ``path`` that exists (``path`` itself if it is one), and whether ``path`` is an
    existing file; after refusing a symbolic link anywhere in ``path`` that leads nowhere (dangling, or a
    loop) and a component above the last that is a file.
    """
    parts = path.parts
    found = Path(parts[0]) if path.is_absolute() else Path(".")
    for i in range(1 if path.is_absolute() else 0, len(parts)):
        here = Path(*parts[: i + 1])
        try:
            st = os.lstat(here)
        except FileNotFoundError:
            return found, False
        except OSError as exc:
            if exc.errno == errno.ENAMETOOLONG:  # the name check says which name
                return found, False
            raise ValueError(f"{name}: cannot write {str(path)!r}: {exc.strerror or exc}") from None
        if S_ISLNK(st.st_mode) and not here.exists():
            raise ValueError(
                f"{name}: cannot write {str(path)!r}: {str(here)!r} is a symbolic link to {os.readlink(here)!r}, "
                f"which does not exist (a dangling link or a loop)"
            )
        if not here.is_dir():
            if i == len(parts) - 1:
                return found, True
            raise ValueError(f"{name} {str(path)!r} is under {str(here)!r}, which is a file, not a folder")
        found = here
    return found, False


def _check_names(name: str, path: Path, folder: Path, extra_last: int) -> None:
    """Every component of ``path`` within ``folder``'s file system's name limit (the last one ``extra_last``
    bytes shorter), the whole path within its path limit.
    """
    limit = _pathconf(folder, "PC_NAME_MAX", FALLBACK_NAME_MAX)
    parts = [p for p in path.parts if p not in (path.anchor, "", ".", "..")]
    for i, part in enumerate(parts):
        size = len(os.fsencode(part))
        allowed = limit - (extra_last if i == len(parts) - 1 else 0)
        if size > allowed:
            shown = part if len(part) <= 40 else part[:37] + "..."
            room = f" (the file system's {limit}, less {extra_last} for the temporary file)" if allowed < limit else ""
            raise ValueError(
                f"{name}: the name {shown!r} is {size} bytes long; at most {allowed} bytes{room} are allowed"
            )
    path_limit = _pathconf(folder, "PC_PATH_MAX", FALLBACK_PATH_MAX)
    size = len(os.fsencode(os.path.abspath(path)))
    if size >= path_limit:
        raise ValueError(f"{name}: the path is {size} bytes long; the file system allows fewer than {path_limit}")


def _probe(folder: Path, message: str) -> None:
    """:func:`probe_write` in ``folder``; refused: a ValueError of ``message`` and the system's reason."""
    try:
        probe_write(folder)
    except OSError as exc:
        raise ValueError(f"{message} ({exc.strerror or exc})") from None


def user_path(path: str | os.PathLike[str]) -> Path:
    """A folder or file path a user gave (a setting, a flag) as every command reads and writes it: ``~`` expanded
    (a shell leaves ``--out=~/runs`` as typed). The output checks below and the atomic writes take it from here.
    """
    return Path(os.fspath(path)).expanduser()


def check_output_path(name: str, path: str | os.PathLike[str], suffixes: tuple[str, ...] | None = None) -> None:
    """Refuse, before any work, an output path that cannot be written as a file (ValueError naming ``name``).

    The rule every command's output files follow: not empty, not a folder, no symbolic link in the path that
    leads nowhere, no component that is a file, every name within the file system's limit (the file's own
    name leaves room for the temporary file of :func:`atomic_write_bytes`), and a real write succeeds in the
    nearest existing folder. Nothing is created. ``suffixes``: the allowed suffixes without the dot (None:
    any; a path without one is refused too).
    """
    text = os.fspath(path)
    if not str(text).strip():
        raise ValueError(f"{name} must be a file path, got an empty string")
    p = user_path(text)
    folder, _ = _existing_folder(name, p)
    if folder == p or text.endswith(("/", os.sep)):
        raise ValueError(f"{name} must be a file path, got the directory {text!r}")
    _check_names(name, p, folder, TEMP_NAME_EXTRA)
    if suffixes is not None and p.suffix.lower().lstrip(".") not in suffixes:
        raise ValueError(
            f"{name} {str(p)!r}: the format {p.suffix or '(none)'!r} is not supported; "
            f"use one of {', '.join('.' + x for x in suffixes)}"
        )
    _probe(folder, f"{name}: cannot write {str(p)!r}: folder {str(folder)!r} is not writable")


def check_output_folder(name: str, folder: str | os.PathLike[str] | None) -> Path:
    """Refuse, before any work, an output folder that cannot be created or written (ValueError naming ``name``);
    return it as a path (``~`` expanded). The rule of :func:`check_output_path` for a folder (a real write in
    it, or in the nearest existing folder where it would be created). Nothing is created.
    """
    text = "" if folder is None else os.fspath(folder)
    if not str(text).strip():
        raise ValueError(f"{name} must name a folder, got {text!r}")
    p = user_path(text)
    existing, is_file = _existing_folder(name, p)
    if is_file:
        raise ValueError(f"{name} {text!r} is a file, not a folder")
    _check_names(name, p, existing, 0)
    if existing == p:
        _probe(p, f"{name} {text!r} is not writable")
    else:
        _probe(existing, f"{name} {text!r} cannot be created: folder {str(existing)!r} is not writable")
    return p


def check_output_options(
    parser: Any,
    files: Mapping[str, str | os.PathLike[str] | None] | None = None,
    folders: Mapping[str, str | os.PathLike[str] | None] | None = None,
    suffixes: Mapping[str, tuple[str, ...]] | None = None,
) -> None:
    """A script's output options (option → path; None: not given) checked by :func:`check_output_path` and
    :func:`check_output_folder`; a refusal is ``parser.error`` (argparse: one line, exit 2).
    """
    try:
        for option, path in (files or {}).items():
            if path is not None:
                check_output_path(option, path, (suffixes or {}).get(option))
        for option, folder in (folders or {}).items():
            if folder is not None:
                check_output_folder(option, folder)
    except ValueError as exc:
        parser.error(str(exc))


def probe_write(folder: str | os.PathLike[str]) -> None:
    """Create and remove a temporary file in ``folder``: a real write, since permission bits say nothing for
    root, a read-only file system or ``/proc``. Raises the ``OSError`` of a folder that cannot be written.
    """
    fd, probe = tempfile.mkstemp(dir=folder, prefix=".electroloc-probe-")
    os.close(fd)
    os.unlink(probe)


@contextmanager
def naming_file(path: str | os.PathLike[str]) -> Iterator[None]:
    """An ``OSError`` raised inside names ``path`` when it names no file (a full disk reported by a buffered
    write or an fsync carries none), so the one place that reports it can say which file it was.
    """
    try:
        yield
    except OSError as exc:
        if exc.filename is None:
            exc.filename = os.fspath(path)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, durable: bool = True) -> None:
    """Write ``data`` to ``path`` atomically (parent folders are created); an ``OSError`` names ``path``
    (rather than its temporary file). ``durable=False`` skips the fsync: only a crash of the machine, not a
    killed process, can then lose the write. ``path`` is read as :func:`user_path` reads it, as the checks do.
    """
    p = user_path(path)
    try:
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
    except OSError as exc:  # the target's name, not its temporary file's
        if exc.filename is None or Path(os.fspath(exc.filename)).name.startswith(f".{p.name}."):
            exc.filename, exc.filename2 = os.fspath(path), None
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


#: The errors of a write the file system refused (the others are reported as the system words them).
WRITE_ERRNOS = frozenset(
    getattr(errno, name) for name in ("ENOSPC", "EDQUOT", "EROFS", "EFBIG", "EIO") if hasattr(errno, name)
)


def os_error_line(command: str, exc: OSError, args: Any = None) -> str:
    """The one line of an ``OSError`` out of ``electroloc command`` (``args``: its parsed arguments): the file and
    the system's reason; for a command that keeps its records as it goes (``bench``: ``OUT/trials.jsonl``;
    ``dataset``: its episodes), that they are kept and how to continue once the cause is fixed: ``--resume``, or
    the same ``--force`` command (a dataset's replacement continues by ``--force``; ``--resume`` does not take it).
    """
    prog = f"electroloc {command}".strip()
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.filename is not None:
        where = f"{'cannot write ' if exc.errno in WRITE_ERRNOS else ''}{os.fsdecode(exc.filename)}: "
    else:
        where = "cannot write: " if exc.errno in WRITE_ERRNOS else ""
    kept = ""
    if command == "bench" and args is not None:
        records = user_path(args.out) / "trials.jsonl"
        kept = f"; the finished trials are kept in {records} (a line cut short is set aside)"
    elif command == "dataset":
        kept = "; the episodes collected so far are kept (one cut short is set aside)"
    if kept:
        again = "again" if getattr(args, "force", False) else "with --resume"
        kept += f": free space or fix the cause, then run the same command {again}"
    return f"{prog}: error: {where}{reason}{kept}"


class FolderBusyError(ValueError):
    """Another process holds the folder's lock."""


class FolderLock:
    """Exclusive, non-blocking lock on ``folder/name`` (a context manager; the folder is created if missing):
    :meth:`acquire` raises :class:`FolderBusyError` with ``busy_message`` when another process holds it.
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
