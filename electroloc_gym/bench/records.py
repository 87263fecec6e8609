"""The benchmark's output folder: checked before any work, locked while a run writes, records keyed.

A run holds an exclusive lock on ``OUT/.bench.lock`` (:func:`run_lock`) for its whole length.
:func:`load_records` decodes each line of ``trials.jsonl`` (or of a kept run's ``trials.jsonl.gz``,
:func:`compress_trials`, which a run never appends to) into the one schema
(:class:`~electroloc_gym.bench.schema.TrialRecord`) and checks it against the run
(:class:`~electroloc_gym.bench.schema.RecordRules`): a damaged or impossible line, or a second line for a
(condition, agent, trial) already read, is reported by file and line and *set aside* (moved to
``trials.rejected.jsonl`` by :func:`set_aside`, so its trial runs again); a record of another run's seeds or
settings is *foreign* (the runner refuses to resume). No record is counted twice; a kept record is returned
in the current key names.
"""

from __future__ import annotations

import gzip
import io
import os
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from electroloc_gym.bench.config import (
    IDENTITY_DEFAULTS,
    IDENTITY_KEYS,
    MAP_CONDITIONS,
    BenchConfig,
    trial_seeds,
)
from electroloc_gym.bench.schema import TIMING_KEYS, RecordRules, TrialRecord
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import (
    FolderBusyError,
    FolderLock,
    atomic_write_text,
    check_output_folder,
    naming_file,
    probe_write,
    strict_json,
)

__all__ = [
    "prepare_out_dir",
    "run_lock",
    "FolderBusyError",
    "LoadedRecords",
    "load_records",
    "read_trials",
    "CONFIG_FILE",
    "RecordWriter",
    "set_aside",
    "record_key",
    "validate_record",
    "foreign_reason",
    "TRIALS_FILE",
    "TRIALS_GZ_FILE",
    "stored_trials",
    "open_trials",
    "compress_trials",
    "REJECTED_FILE",
    "LOCK_FILE",
    "MAX_LINE_CHARS",
]

TRIALS_FILE = "trials.jsonl"
#: A kept run's records stored compressed (:func:`compress_trials`); read where ``trials.jsonl`` is absent.
TRIALS_GZ_FILE = TRIALS_FILE + ".gz"
CONFIG_FILE = "config.json"
REJECTED_FILE = "trials.rejected.jsonl"
LOCK_FILE = ".bench.lock"
#: Longest trials.jsonl line read (a record is about 700 characters): a longer one is set aside unparsed.
MAX_LINE_CHARS = 16_384


def prepare_out_dir(out: str | os.PathLike[str] | None, name: str = "out") -> Path:
    """Create the output folder (parents too) and check that files can be written in it; ``name``: the setting as
    the caller's front end spells it.

    Raises:
        ValueError: what :func:`~electroloc_gym.utils.fileio.check_output_folder` refuses, or a folder that
            cannot be created or written.
    """
    path = check_output_folder(name, out)
    text = os.fspath(out)  # type: ignore[arg-type]  # check_output_folder refused None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{name} {text!r} cannot be created: {exc.strerror or exc}") from exc
    try:
        probe_write(path)
    except OSError as exc:
        raise ValueError(f"{name} {text!r} is not writable: {exc.strerror or exc}") from exc
    return path


def run_lock(folder: str | os.PathLike[str], name: str = "out") -> FolderLock:
    """The exclusive lock a run holds on its output folder (``OUT/.bench.lock``, a :class:`FolderLock`); ``name``:
    the output setting as the caller's front end spells it.

    Raises:
        FolderBusyError: on ``acquire`` when another run holds it.
    """
    return FolderLock(
        folder,
        LOCK_FILE,
        f"{name} {os.fspath(folder)!r} is in use by another electroloc bench run; "
        f"wait for it to finish or choose another {name}",
    )


def record_key(rec: dict[str, Any]) -> tuple[str, str, int]:
    """(condition, agent, trial) of a validated record."""
    return (rec["condition"], rec["agent"], rec["trial"])


def validate_record(rec: Any, rules: RecordRules | None = None) -> str | None:
    """Why ``rec`` (a parsed line) is not a trial record — of the run ``rules`` describes, if given (None: it is)."""
    try:
        record = TrialRecord.from_json(rec)
    except ValueError as exc:
        return str(exc)
    return None if rules is None else record.problem(rules)


def foreign_reason(rec: dict[str, Any], config: BenchConfig) -> str | None:
    """Why a valid record does not belong to ``config``'s run (None: it does)."""
    mine = config.record_settings()
    for key in IDENTITY_KEYS:
        theirs = rec.get(key, IDENTITY_DEFAULTS.get(key))
        if theirs != mine[key]:
            return f"{key} {theirs!r}, this run {mine[key]!r}"
    own_map = env_entry(config.env_id).map_condition
    if (rec["condition"] != own_map) if own_map is not None else (rec["condition"] in MAP_CONDITIONS):
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

    @property
    def n_rejected(self) -> int:
        """Lines set aside: damaged, impossible, or a second line for a trial already read."""
        return len(self.rejected)

    @property
    def n_foreign(self) -> int:
        """Valid records that are not of the run (another seed or other settings)."""
        return len(self.foreign)


def stored_trials(path: str | os.PathLike[str]) -> Path:
    """The file holding a run's records: ``path`` (a ``trials.jsonl``), or, where it is absent, the
    ``trials.jsonl.gz`` beside it (a kept run stored compressed by :func:`compress_trials`).
    """
    plain = Path(path)
    if plain.name == TRIALS_FILE and not plain.exists():
        packed = plain.with_name(TRIALS_GZ_FILE)
        if packed.is_file():
            return packed
    return plain


def open_trials(path: str | os.PathLike[str]) -> io.BufferedIOBase:
    """A run's records opened for reading, as bytes: the file :func:`stored_trials` names (a ``.gz`` decompressed)."""
    found = stored_trials(path)
    return gzip.open(found, "rb") if found.name.endswith(".gz") else open(found, "rb")  # noqa: SIM115


def compress_trials(folder: str | os.PathLike[str]) -> Path:
    """Store ``folder/trials.jsonl`` as ``folder/trials.jsonl.gz`` and remove the plain file.

    gzip at level 9 with mtime 0 and no file name in the header, so the same records give the same
    bytes on every machine. The compressed file is written atomically and read back before the plain
    one is removed: its records must equal the plain file's.

    Raises:
        ValueError: no ``trials.jsonl`` in ``folder``, or a ``trials.jsonl.gz`` already there.
    """
    plain, packed = Path(folder) / TRIALS_FILE, Path(folder) / TRIALS_GZ_FILE
    if not plain.is_file():
        raise ValueError(f"{plain}: missing (nothing to compress)")
    if packed.exists():
        raise ValueError(f"{packed} already exists (a run keeps one of trials.jsonl and trials.jsonl.gz)")
    data = plain.read_bytes()
    buf = io.BytesIO()
    with gzip.GzipFile(filename="", mode="wb", fileobj=buf, compresslevel=9, mtime=0) as gz:
        gz.write(data)
    fd, tmp = tempfile.mkstemp(dir=plain.parent, prefix=".trials-", suffix=".gz")
    try:
        os.chmod(tmp, plain.stat().st_mode & 0o777)  # the plain file's permissions, not mkstemp's 0600
        with os.fdopen(fd, "wb") as fh:
            fh.write(buf.getvalue())
            fh.flush()
            os.fsync(fh.fileno())
        if gzip.decompress(Path(tmp).read_bytes()) != data:
            raise ValueError(f"{tmp}: the compressed records do not read back equal")
        os.replace(tmp, packed)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    plain.unlink()
    return packed


def load_records(
    path: str | os.PathLike[str], config: BenchConfig | None = None, rules: RecordRules | None = None
) -> LoadedRecords:
    """Read a trials.jsonl (missing file: no records), keyed by (condition, agent, trial).

    Args:
        path: the file; where it is absent, the ``trials.jsonl.gz`` beside it (:func:`stored_trials`).
        config: if given, a valid record of other seeds or settings (:func:`foreign_reason`) is listed in
            ``foreign`` (and not in ``records``).
        rules: if given, a record that breaks them (:meth:`TrialRecord.problem`) is rejected like a damaged line.
    """
    out = LoadedRecords(stored_trials(path))
    if not out.path.exists():
        return out
    try:
        fh = open_trials(out.path)
    except OSError as exc:
        raise ValueError(f"cannot read {out.path}: {exc.strerror or exc}") from None
    try:
        with fh:
            _read_lines(fh, out, config, rules)
    except (OSError, EOFError, zlib.error) as exc:  # e.g. a damaged .gz: the stream itself cannot be read
        raise ValueError(f"cannot read {out.path}: {exc}") from None
    return out


def _read_lines(fh: Any, out: LoadedRecords, config: BenchConfig | None, rules: RecordRules | None) -> None:
    """:func:`load_records`' loop over the lines of an open (binary) records file, filling ``out``."""
    seen: dict[tuple[str, str, int], tuple[int, dict[str, Any]]] = {}
    for n, raw in enumerate(iter(lambda: fh.readline(MAX_LINE_CHARS * 4 + 2), b""), start=1):
        if len(raw) > MAX_LINE_CHARS * 4 + 1:  # a line longer than any record: read it to its end, reject it
            while raw[-1:] != b"\n":
                more = fh.readline(1 << 20)
                if not more:
                    break
                raw = raw[:64] + more[-1:]
            out.rejected.append((n, f"a line longer than {MAX_LINE_CHARS} characters", raw[:64] + b"...\n"))
            continue
        if not raw.strip():
            continue
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            out.rejected.append((n, f"not UTF-8 ({exc.reason} at byte {exc.start})", raw))
            continue
        try:
            record = TrialRecord.from_line(raw)
        except ValueError as exc:
            torn = "" if raw.endswith(b"\n") else ", the last line torn (a run killed mid-write)"
            out.rejected.append((n, f"{exc}{torn}", raw))
            continue
        why = None if rules is None else record.problem(rules)
        if why is not None:
            out.rejected.append((n, why, raw))
            continue
        rec = record.to_json()
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


def read_trials(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
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
    atomic_write_text(loaded.path, "".join(strict_json(r, indent=None) for r in loaded.records.values()))
    return rejected


class RecordWriter:
    """Append records to trials.jsonl, one line each, flushed and fsync'ed before the next (a kill loses none)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self._fh = open(self.path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()/__exit__

    def write(self, rec: dict[str, Any]) -> None:
        with naming_file(self.path):  # a full disk names the file (the CLI reports it in one line)
            self._fh.write(strict_json(rec, indent=None))
            self._fh.flush()
            os.fsync(self._fh.fileno())

    def close(self) -> None:
        with naming_file(self.path):
            self._fh.close()

    def __enter__(self) -> RecordWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
