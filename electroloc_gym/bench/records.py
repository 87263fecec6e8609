"""The benchmark's output folder: checked before any work, locked while a run writes, records keyed.

* :func:`prepare_out_dir` — ``--out`` must be a folder that can be created and written (an empty
  path, an existing file, a path under a file or an unwritable folder is one clear error).
* :class:`FolderLock` — an exclusive ``fcntl.flock`` on ``OUT/.bench.lock`` held for the whole run:
  a second run on the same folder refuses at once (the kernel releases the lock when a run dies).
* :func:`load_records` — reads ``trials.jsonl`` keyed by (condition, agent, trial): a damaged line
  (not UTF-8, not JSON, not an object, a missing key or a wrong type) and a second line for a key
  already present are reported by file and line and *set aside* (moved to ``trials.rejected.jsonl``,
  so those trials run again); a record whose seeds or settings are not the run's is *foreign* (the
  runner refuses to resume). No record is ever counted twice.
* :class:`RecordWriter` — appends one line per finished trial, flushed and fsync'ed at once (a killed
  run loses no finished trial).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from electroloc_gym.bench.config import GLOBAL_CONDITION, GLOBAL_ENV_ID, IDENTITY_KEYS, BenchConfig, trial_seeds
from electroloc_gym.bench.trials import OPTIONAL_RECORD_KEYS, RECORD_KEYS, TIMING_KEYS
from electroloc_gym.conditions import PRESET_NAMES
from electroloc_gym.fileio import atomic_write_text

__all__ = ["prepare_out_dir", "FolderLock", "FolderBusyError", "LoadedRecords", "load_records", "read_trials",
           "RecordWriter", "set_aside", "record_key", "validate_record", "foreign_reason", "TRIALS_FILE",
           "REJECTED_FILE", "LOCK_FILE"]

TRIALS_FILE = "trials.jsonl"
REJECTED_FILE = "trials.rejected.jsonl"
LOCK_FILE = ".bench.lock"
_CONDITIONS = (*PRESET_NAMES, GLOBAL_CONDITION)


def prepare_out_dir(out: str | os.PathLike | None) -> Path:
    """Create the output folder (parents too) and check that files can be written in it.

    Raises:
        ValueError: ``out`` empty, an existing file, under a file, not creatable or not writable.
    """
    text = "" if out is None else os.fspath(out)
    if not str(text).strip():
        raise ValueError(f"--out must name a folder, got {text!r}")
    path = Path(text).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {text!r} is a file, not a folder")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ValueError(f"--out {text!r} is under {str(parent)!r}, which is a file, not a folder")
            break
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--out {text!r} cannot be created: {exc.strerror or exc}") from exc
    try:
        fd, probe = tempfile.mkstemp(dir=path, prefix=".write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(f"--out {text!r} is not writable: {exc.strerror or exc}") from exc
    return path


class FolderBusyError(ValueError):
    """Another run holds the folder's lock."""


class FolderLock:
    """Exclusive, non-blocking ``flock`` on ``folder/.bench.lock`` (a context manager).

    Raises:
        FolderBusyError: on ``acquire`` when another process holds the lock.
    """

    def __init__(self, folder: str | os.PathLike) -> None:
        self.path = Path(folder) / LOCK_FILE
        self._fd: int | None = None

    def acquire(self) -> FolderLock:
        import fcntl

        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            try:
                holder = os.read(fd, 64).decode("ascii", "replace").strip()
            finally:
                os.close(fd)
            who = f" (pid {holder})" if holder.isdigit() else ""
            raise FolderBusyError(f"--out {str(self.path.parent)!r} is in use by another electroloc bench run{who}; "
                                  f"wait for it to finish or choose another --out") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()


def record_key(rec: dict[str, Any]) -> tuple[str, str, int]:
    """(condition, agent, trial) of a validated record."""
    return (rec["condition"], rec["agent"], rec["trial"])


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num_or_none(v: Any) -> bool:
    return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))


def _is_xy(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(_is_num_or_none(x) and x is not None for x in v)


_CHECKS: dict[str, tuple[Callable[[Any], bool], str]] = {
    "condition": (lambda v: v in _CONDITIONS, "a condition name"),
    "agent": (lambda v: isinstance(v, str) and bool(v.strip()), "a non-empty string"),
    "agent_label": (lambda v: isinstance(v, str), "a string"),
    "layout": (lambda v: v in ("table4", "table1"), "'table4' or 'table1'"),
    "trial": (lambda v: _is_int(v) and v >= 0, "an integer ≥ 0"),
    "seed": (lambda v: _is_int(v) and v >= 0, "an integer ≥ 0"),
    "agent_seed": (lambda v: _is_int(v) and v >= 0, "an integer ≥ 0"),
    "success": (lambda v: isinstance(v, bool), "true or false"),
    "ended_by": (lambda v: v in ("success", "cap", "agent"), "'success', 'cap' or 'agent'"),
    "observations": (lambda v: _is_int(v) and v >= 0, "an integer ≥ 0"),
    "error_mm": (_is_num_or_none, "a number or null"),
    "error_x_mm": (_is_num_or_none, "a number or null"),
    "error_y_mm": (_is_num_or_none, "a number or null"),
    "estimate": (lambda v: v is None or _is_xy(v), "[x, y] or null"),
    "target": (_is_xy, "[x, y]"),
    "start": (_is_xy, "[x, y]"),
    "spread_mm": (_is_num_or_none, "a number or null"),
    "decisions": (lambda v: _is_int(v) and v >= 0, "an integer ≥ 0"),
    "decision_ms_median": (_is_num_or_none, "a number or null"),
    "decision_ms_mean": (_is_num_or_none, "a number or null"),
    "sensor_model": (lambda v: isinstance(v, str), "a string"),
    "signal": (lambda v: isinstance(v, str), "a string"),
    "max_observations": (lambda v: _is_int(v) and v >= 1, "an integer ≥ 1"),
    "n_particles": (lambda v: _is_int(v) and v >= 1, "an integer ≥ 1"),
    "env_id": (lambda v: isinstance(v, str), "a string"),
    "wall_s": (_is_num_or_none, "a number or null"),
    "shape": (lambda v: v is None or isinstance(v, dict), "an object or null"),
    "gain_levels": (lambda v: v is None or (isinstance(v, list) and all(_is_num_or_none(g) for g in v)),
                    "a list of numbers or null"),
    "sensor_layout": (lambda v: v is None or isinstance(v, str), "a layout name or null"),
}
assert set(_CHECKS) == set(RECORD_KEYS)


def validate_record(rec: Any) -> str | None:
    """Why ``rec`` is not a trial record (None: it is one)."""
    if not isinstance(rec, dict):
        return f"not a JSON object ({type(rec).__name__})"
    missing = [k for k in RECORD_KEYS if k not in rec and k not in OPTIONAL_RECORD_KEYS]
    if missing:
        return f"missing key(s) {missing}"
    for key, (ok, what) in _CHECKS.items():
        if not ok(rec.get(key)):
            return f"{key!r} must be {what}, got {rec[key]!r}"
    return None


def _plain(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def foreign_reason(rec: dict[str, Any], config: BenchConfig) -> str | None:
    """Why a valid record does not belong to ``config``'s run (None: it does)."""
    for key in IDENTITY_KEYS:
        mine, theirs = _plain(getattr(config, key)), _plain(rec.get(key))  # JSON: tuples come back as lists
        if theirs != mine:
            return f"{key} {theirs!r}, this run {mine!r}"
    if (rec["condition"] == GLOBAL_CONDITION) != (config.env_id == GLOBAL_ENV_ID):
        return f"condition {rec['condition']!r} does not belong to env {config.env_id}"
    env_seed, agent_seed = trial_seeds(config.seed, rec["condition"], rec["trial"])
    if (rec["seed"], rec["agent_seed"]) != (env_seed, agent_seed):
        return f"its seeds are not those of trial {rec['trial']} under --seed {config.seed} (another --seed)"
    return None


def _same_result(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return {k: v for k, v in a.items() if k not in TIMING_KEYS} == {k: v for k, v in b.items() if k not in TIMING_KEYS}


@dataclass
class LoadedRecords:
    """What :func:`load_records` found.

    Attributes:
        records: valid records by (condition, agent, trial), first line wins.
        rejected: (line number, reason, raw line) of every line set aside.
        foreign: (line number, reason) of valid records that are not the run's (only with a config).
    """

    path: Path
    records: dict[tuple[str, str, int], dict[str, Any]] = field(default_factory=dict)
    rejected: list[tuple[int, str, bytes]] = field(default_factory=list)
    foreign: list[tuple[int, str]] = field(default_factory=list)

    def messages(self) -> list[str]:
        """One line per set-aside line: ``FILE:LINE: reason``."""
        return [f"{self.path}:{n}: {why}" for n, why, _ in self.rejected]


def load_records(path: str | os.PathLike, config: BenchConfig | None = None) -> LoadedRecords:
    """Read a trials.jsonl (missing file: no records), keyed by (condition, agent, trial).

    Args:
        path: the file.
        config: if given, every valid record is also checked against the run (seeds, settings);
            those that do not match are listed in ``foreign`` (and not in ``records``).
    """
    out = LoadedRecords(Path(path))
    if not out.path.exists():
        return out
    seen: dict[tuple[str, str, int], tuple[int, dict[str, Any]]] = {}
    with open(out.path, "rb") as fh:
        for n, raw in enumerate(fh, start=1):
            if not raw.strip():
                continue
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                out.rejected.append((n, f"not UTF-8 ({exc.reason} at byte {exc.start})", raw))
                continue
            try:
                rec = json.loads(text)
            except json.JSONDecodeError as exc:
                torn = "" if raw.endswith(b"\n") else ", the last line torn (a run killed mid-write)"
                out.rejected.append((n, f"not JSON ({exc.msg}){torn}", raw))
                continue
            why = validate_record(rec)
            if why is not None:
                out.rejected.append((n, why, raw))
                continue
            key = record_key(rec)
            if key in seen:
                first, kept = seen[key]
                what = "duplicate" if _same_result(rec, kept) else "a second, different result"
                out.rejected.append((n, f"{what} of line {first} (same condition, agent, trial {list(key)})", raw))
                continue
            seen[key] = (n, rec)
            if config is not None:
                why = foreign_reason(rec, config)
                if why is not None:
                    out.foreign.append((n, f"{list(key)}: {why}"))
                    continue
            out.records[key] = rec
    return out


def read_trials(path: str | os.PathLike) -> list[dict[str, Any]]:
    """The valid records of a trials.jsonl, each (condition, agent, trial) once, in file order."""
    return list(load_records(path).records.values())


def set_aside(loaded: LoadedRecords) -> Path | None:
    """Move the rejected lines of ``loaded.path`` to trials.rejected.jsonl beside it; keep the valid records.

    The rejected lines are appended (and fsync'ed) first, then trials.jsonl is replaced atomically by its
    valid records, so a run killed in between loses nothing. Returns the rejected file (None: nothing to do).
    """
    if not loaded.rejected:
        return None
    rejected = loaded.path.with_name(REJECTED_FILE)
    with open(rejected, "ab") as fh:
        for _, _, raw in loaded.rejected:
            fh.write(raw if raw.endswith(b"\n") else raw + b"\n")
        fh.flush()
        os.fsync(fh.fileno())
    atomic_write_text(loaded.path, "".join(json.dumps(r, allow_nan=False) + "\n" for r in loaded.records.values()))
    return rejected


class RecordWriter:
    """Append records to trials.jsonl, one line each, flushed and fsync'ed before the next."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._fh = open(self.path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()/__exit__

    def write(self, rec: dict[str, Any]) -> None:
        self._fh.write(json.dumps(rec, allow_nan=False) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
