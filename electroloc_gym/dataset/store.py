"""A dataset's folder on disk while it is written.

Its ids, the datasets root, the atomic header, the checksum journal, the check of every kept episode, the
set-aside folder and the replacement of a dataset.

Layout, under the datasets root (``MINARI_DATASETS_PATH``, Minari's default ``~/.minari/datasets`` when
unset; :func:`datasets_root`)::

    <namespace>/<name>-vN/                      the dataset (what the id names; Minari reads data/)
        data/metadata.json                      Minari's header and the "electroloc" block
        data/<k>/part-0.arrow, data/<k>/metadata.json    episode k, Minari's arrow storage
        checksums.jsonl                         the journal: the settings, then one line per episode
        quarantine/<n>/...                      what the n-th resume set aside (moved, never deleted)
    <namespace>/.<name>-vN.electroloc-new/      a --force replacement while it is built
    <namespace>/.<name>-vN.electroloc-old/      the replaced dataset during the swap
    .electroloc-locks/<id>.lock                 one writer per id

**Writes.** Nothing of a dataset is rewritten in place. ``data/metadata.json`` is replaced atomically (a
temporary file in the same folder, then ``os.replace``: :func:`electroloc_gym.utils.fileio.atomic_write_text`)
after every episode, fsynced when the dataset is created and when it is complete. An episode is written by
Minari's own arrow storage into a staging folder (``<dataset>/.staging``), its files' sha256 appended to the
journal, and then moved into ``data/`` whole (one ``rename``). A SIGKILL at any moment therefore leaves old
or new files, never torn ones, except a half-appended last journal line (its episode is then re-collected);
a torn file left by a crash of the machine is caught by the checksums. Before the header says ``complete``
every file is fsynced.

**Resume** (:func:`inspect_dataset`, :func:`set_aside`) checks every episode folder against the journal:
both files present and nothing else, their sha256 the recorded ones, the episode's own metadata naming
its index, its seed and its length, the arrow file readable with one row per observation. A damaged
episode is moved to ``quarantine/<n>/`` and re-collected (the same seed, so the same episode); an
unreadable or altered header is moved there too and rebuilt from the settings and the kept episodes.

**Replacement** (``--force``): the new dataset is built beside the old one (``.<name>-vN.electroloc-new``)
and swapped in only when complete (two renames, the old one deleted last); a run killed between the
renames is finished by the next run on that id (:func:`recover_swap`). Only a folder that is exactly a
dataset (``data/`` and this module's own files) is ever replaced.

**Kill points** (tests only): ``ELECTROLOC_DATASET_KILL_AT=<point>[:<n>]`` makes the process SIGKILL
itself the n-th time (default 1) it reaches ``<point>``, one of :data:`KILL_POINTS`, so a test can stop a
run at each step of a write and check that ``--resume`` continues it. Unset, it costs one dict lookup.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import signal
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from electroloc_gym.utils.fileio import FolderLock, atomic_write_text, check_output_folder, probe_write

__all__ = [
    "MAX_ID_CHARS",
    "KILL_POINTS",
    "KILL_ENV",
    "JOURNAL",
    "QUARANTINE",
    "EPISODE_FILES",
    "STAGING",
    "check_dataset_id",
    "datasets_root",
    "DatasetFolder",
    "Inspection",
    "inspect_dataset",
    "set_aside",
    "recover_swap",
    "kill_point",
]

#: Longest dataset id (characters): the folder name plus this module's suffixes stays within a file
#: system's 255-byte name limit.
MAX_ID_CHARS = 200
#: The checksum journal, beside ``data/``.
JOURNAL = "checksums.jsonl"
#: Where a resume sets damaged files aside, beside ``data/``.
QUARANTINE = "quarantine"
#: The files of one episode folder (Minari's arrow storage).
EPISODE_FILES = ("metadata.json", "part-0.arrow")
#: The test hook's environment variable and its points, in the order a run reaches them.
KILL_ENV = "ELECTROLOC_DATASET_KILL_AT"
KILL_POINTS = (
    "quarantined",  # a resume moved its first damaged file aside
    "created",  # the header and journal of a new dataset exist, not yet in place
    "staged",  # an episode's files are in the staging folder
    "journaled",  # its checksums are in the journal, the episode not yet in data/
    "moved",  # the episode is in data/, the header not yet updated
    "header",  # the header counts the episode
    "final",  # every episode is written, the header not yet complete
    "swap",  # --force: the old dataset moved aside, the new one not yet in place
    "swapped",  # --force: the new one in place, the old one not yet deleted
)
#: Where episodes are written before they are moved into ``data/``, beside it.
STAGING = ".staging"
_HEADER_REL = "data/metadata.json"
_NEW, _OLD = ".electroloc-new", ".electroloc-old"
_LOCKS = ".electroloc-locks"
_ID_RE = re.compile(r"(?P<namespace>[A-Za-z0-9_-]+(?:/[A-Za-z0-9_-]+)*)/(?P<name>[A-Za-z0-9_-]+)-v(?P<version>[0-9]+)")
_SETTINGS = ("agent", "env_id", "env_kwargs", "seed")
_kill_counts: Counter[str] = Counter()


def kill_point(name: str) -> None:
    """The test hook: SIGKILL this process at the n-th arrival at ``name`` when :data:`KILL_ENV` asks."""
    spec = os.environ.get(KILL_ENV)
    if not spec:
        return
    point, _, count = spec.partition(":")
    if point != name:
        return
    _kill_counts[name] += 1
    if _kill_counts[name] >= int(count or 1):
        os.kill(os.getpid(), getattr(signal, "SIGKILL", signal.SIGTERM))


def check_dataset_id(text: Any) -> str:
    """``text`` if it is a dataset id this package writes: ``NAMESPACE/NAME-vN`` in ASCII letters, digits,
    ``_`` and ``-``, '/'-separated, at most :data:`MAX_ID_CHARS` characters (and Minari's own form).

    Raises:
        ValueError: anything else — one line.
    """
    shown = repr(text) if not isinstance(text, str) or len(text) <= 60 else repr(text[:57] + "...")
    if isinstance(text, str) and len(text) > MAX_ID_CHARS:
        raise ValueError(f"dataset id must be at most {MAX_ID_CHARS} characters, got {shown} ({len(text)} characters)")
    match = _ID_RE.fullmatch(text) if isinstance(text, str) else None
    if match is None or len(match["namespace"]) < 2:
        raise ValueError(
            "dataset id must be NAMESPACE/NAME-vN (ASCII letters, digits, '_' and '-', '/'-separated, a "
            f"namespace of 2 or more characters, a version number after -v; e.g. mine/lookahead-v0), got {shown}"
        )
    try:
        from minari.dataset.minari_dataset import DATASET_ID_RE
    except ImportError:  # the extra is checked where a dataset is written
        return text
    minari_match = DATASET_ID_RE.fullmatch(text)
    if minari_match is None or minari_match["version"] is None:  # pragma: no cover - the form above is narrower
        raise ValueError(f"dataset id {shown} is not of Minari's form NAMESPACE/NAME-vN")
    return text


def datasets_root() -> Path:
    """The datasets root: ``MINARI_DATASETS_PATH``, or Minari's default when unset; writable.

    A set but empty ``MINARI_DATASETS_PATH`` is refused (Minari's loaders cannot use it either); a missing
    folder is created when its parent folder exists (Minari's default is created with its parents).

    Raises:
        ValueError: set to an empty string, a file, a folder whose parent does not exist, or a place
            this process cannot write — one line naming the variable.
    """
    raw = os.environ.get("MINARI_DATASETS_PATH")
    if raw is None:
        root = Path.home() / ".minari" / "datasets"  # Minari's default (minari.storage.get_dataset_path)
        what = f"Minari's datasets folder {str(root)!r} (MINARI_DATASETS_PATH unset)"
        try:
            root.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"{what} cannot be created: {exc.strerror or exc}") from None
    else:
        what = f"MINARI_DATASETS_PATH={raw!r}"
        if not raw.strip():
            raise ValueError(
                "MINARI_DATASETS_PATH is set but empty: unset it (Minari's default ~/.minari/datasets) or set "
                "it to a folder"
            )
        root = Path(raw).absolute()  # Minari's storage mislays episodes under a relative folder
        try:
            _check_datasets_folder(what, root)
        except OSError:  # a name too long, a link that leads nowhere: the output folders' one rule names it
            check_output_folder("MINARI_DATASETS_PATH", root)
            raise
    try:
        probe_write(root)
    except OSError as exc:
        raise ValueError(f"{what} is not writable: {exc.strerror or exc}") from None
    return root


def _check_datasets_folder(what: str, root: Path) -> None:
    """A set ``MINARI_DATASETS_PATH`` (``what``): a folder, or one that can be created in an existing folder
    (created here). A path the file system refuses to look at (a name too long) raises its ``OSError``.
    """
    if root.exists() and not root.is_dir():
        raise ValueError(f"{what} is not a folder")
    if not root.exists():
        parent = root.parent
        if not parent.is_dir():
            tilde = " (a leading ~ is not expanded: give the full path)" if "~" in root.parts else ""
            raise ValueError(f"{what} does not exist and neither does its parent folder {str(parent)!r}{tilde}")
        try:
            root.mkdir()
        except OSError as exc:
            check_output_folder("MINARI_DATASETS_PATH", root)  # a link that leads nowhere: named by the one rule
            raise ValueError(f"{what} does not exist and cannot be created: {exc.strerror or exc}") from None


def _is_dataset(folder: Path) -> bool:
    return (folder / "data").is_dir()


@dataclass(frozen=True)
class DatasetFolder:
    """The folders of dataset ``ds_id`` under ``root``: the dataset, its replacement, the swap's old copy."""

    root: Path
    ds_id: str

    @property
    def path(self) -> Path:
        return self.root.joinpath(*self.ds_id.split("/"))

    @property
    def new(self) -> Path:
        return self.path.with_name("." + self.path.name + _NEW)

    @property
    def old(self) -> Path:
        return self.path.with_name("." + self.path.name + _OLD)

    def lock(self) -> FolderLock:
        """The id's write lock (a file under the root's ``.electroloc-locks``)."""
        return FolderLock(
            self.root / _LOCKS,
            self.ds_id.replace("/", "--") + ".lock",
            f"dataset {self.ds_id!r} is being written by another process; wait for it to finish",
        )

    def check_location(self) -> None:
        """Refuse an id whose folder is not exactly a dataset's (before anything is written or deleted).

        Raises:
            ValueError: a namespace or other folder at the id, an id inside another dataset's folder, a
                file on the way, a dataset folder holding files this package did not write, an id that a
                case-insensitive file system finds under another spelling — one line.
        """
        parts = self.ds_id.split("/")
        for i in range(1, len(parts)):
            folder = self.root.joinpath(*parts[:i])
            prefix = "/".join(parts[:i])
            if folder.exists() and not folder.is_dir():
                raise ValueError(f"dataset id {self.ds_id!r}: {str(folder)!r} is a file, not a namespace folder")
            if _is_dataset(folder):
                raise ValueError(
                    f"dataset id {self.ds_id!r} lies inside the dataset {prefix!r} ({folder}); choose another id"
                )
        spelled = self._spelling_on_disk()
        if spelled is not None:
            raise ValueError(
                f"dataset id {self.ds_id!r}: this file system does not tell upper from lower case, and "
                f"{spelled!r} exists ({self.root.joinpath(*spelled.split('/'))}); nothing was changed: use "
                "that spelling or another id"
            )
        path = self.path
        if not path.exists():
            return
        if not path.is_dir():
            raise ValueError(f"dataset id {self.ds_id!r}: {str(path)!r} is a file, not a dataset")
        if (path / "namespace_metadata.json").exists() or not _is_dataset(path):
            kind = "a namespace folder" if (path / "namespace_metadata.json").exists() else "a folder"
            raise ValueError(
                f"dataset id {self.ds_id!r} names {kind} ({path}), not a dataset; nothing was changed: "
                f"give the id of one dataset, NAMESPACE/NAME-vN"
            )
        if (path / QUARANTINE).exists() and not (path / QUARANTINE).is_dir():
            raise ValueError(
                f"dataset folder {path} holds a file {QUARANTINE!r} where its set-aside folder goes; nothing was "
                "changed: move it out first"
            )
        own = {"data", JOURNAL, QUARANTINE, STAGING}
        others = sorted(p.name for p in path.iterdir() if p.name not in own and not _is_temporary(p.name, JOURNAL))
        if others:
            raise ValueError(
                f"dataset folder {path} holds {others[:3]} besides the dataset; nothing was changed: move "
                f"{'them' if len(others) > 1 else 'it'} out first"
            )

    def _spelling_on_disk(self) -> str | None:
        """The existing part of the id's path as the folder listings spell it, where that differs from the id
        (a case-insensitive file system finds ``Mine/X-v0`` at ``mine/x-v0``); None where it does not.
        """
        folder, spelled = self.root, []
        for part in self.ds_id.split("/"):
            if not os.path.lexists(folder / part):
                break
            try:
                names = os.listdir(folder)
            except OSError:
                return None
            if part not in names:
                same = [n for n in names if n.casefold() == part.casefold()]
                return "/".join([*spelled, same[0] if same else part])
            spelled.append(part)
            folder = folder / part
        return None


def _is_temporary(name: str, of: str) -> bool:
    """``name`` is a temporary file of an atomic write of ``of`` (:func:`electroloc_gym.utils.fileio.atomic_write_bytes`
    and :func:`write_header` name them ``.<of>.<random>.tmp``) that a kill left behind.
    """
    return name.startswith(f".{of}.") and name.endswith(".tmp")


def header_path(folder: Path) -> Path:
    return folder / "data" / "metadata.json"


def read_header(folder: Path) -> tuple[dict[str, Any] | None, str | None]:
    """(the header, None) or (None, why it is unreadable)."""
    path = header_path(folder)
    try:
        header = json.loads(path.read_bytes())
    except FileNotFoundError:
        return None, "missing"
    except (OSError, ValueError, RecursionError) as exc:
        return None, f"unreadable ({type(exc).__name__})"
    if not isinstance(header, dict):
        return None, "not a JSON object"
    return header, None


def write_header(folder: Path, header: Mapping[str, Any], *, durable: bool = True) -> None:
    """Replace ``data/metadata.json`` atomically (Minari's JSON: sets written as lists).

    ``durable=False`` (the count after each episode) skips the fsync: the replacement is as atomic for a
    killed process, and a header a machine crash loses is rebuilt on resume.
    """
    text = json.dumps(header, default=_json_default, allow_nan=False)
    atomic_write_text(header_path(folder), text, durable=durable)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, (set, frozenset)):
        return sorted(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON data")


def settings_of(block: Any) -> dict[str, Any] | None:
    """The settings an episode depends on (agent, env, its kwargs, root seed) from a block, or None."""
    if not isinstance(block, dict) or not all(k in block for k in _SETTINGS):
        return None
    return {k: block[k] for k in _SETTINGS}


def write_journal(folder: Path, ds_id: str, settings: Mapping[str, Any], records: Iterable[Mapping[str, Any]]) -> None:
    """Write the journal afresh (atomically): the settings line, then ``records`` (one per episode)."""
    lines = [json.dumps({"dataset_id": ds_id, "settings": dict(settings)}, sort_keys=True)]
    lines += [json.dumps(dict(r), sort_keys=True) for r in records]
    atomic_write_text(folder / JOURNAL, "\n".join(lines) + "\n")


def append_journal(folder: Path, record: Mapping[str, Any]) -> None:
    """Append one episode's record (one ``write``; a line torn by a kill is ignored on resume)."""
    with open(folder / JOURNAL, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(dict(record), sort_keys=True) + "\n")


def read_journal(folder: Path) -> tuple[dict[str, Any] | None, dict[int, dict[str, Any]], int]:
    """(its settings or None, the last good record of each episode, unreadable lines)."""
    try:
        text = (folder / JOURNAL).read_bytes().decode("utf-8", errors="replace")
    except OSError:
        return None, {}, 0
    settings, records, bad = None, {}, 0
    for i, line in enumerate(text.splitlines()):
        try:
            row = json.loads(line)
        except (ValueError, RecursionError):
            bad += 1
            continue
        if i == 0 and isinstance(row, dict) and isinstance(row.get("settings"), dict):
            settings = row["settings"]
        elif _good_record(row):
            records[row["episode"]] = row
        else:
            bad += 1
    return settings, records, bad


def _good_record(row: Any) -> bool:
    return (
        isinstance(row, dict)
        and type(row.get("episode")) is int
        and type(row.get("steps")) is int
        and type(row.get("seed")) is int
        and isinstance(row.get("sha256"), dict)
        and all(isinstance(row["sha256"].get(name), str) for name in EPISODE_FILES)
    )


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def episode_record(folder: Path, k: int, seed: int, steps: int) -> dict[str, Any]:
    """The journal record of episode folder ``folder`` (episode ``k``)."""
    return {
        "episode": k,
        "seed": seed,
        "steps": steps,
        "sha256": {name: file_sha256(folder / name) for name in EPISODE_FILES},
    }


def _episode_problem(folder: Path, k: int, seed: int, record: dict[str, Any] | None) -> str | None:
    """Why episode folder ``folder`` cannot be kept (None: it can)."""
    for name in EPISODE_FILES:
        if not (folder / name).is_file():
            return f"no {name}"
    if record is None:
        return "no recorded checksum"
    for name in EPISODE_FILES:
        try:
            digest = file_sha256(folder / name)
        except OSError as exc:
            return f"{name} unreadable ({exc.strerror or type(exc).__name__})"
        if digest != record["sha256"][name]:
            return f"{name} does not match its checksum"
    try:
        meta = json.loads((folder / "metadata.json").read_bytes())
    except (OSError, ValueError, RecursionError):
        return "metadata.json unreadable"
    if not isinstance(meta, dict) or (meta.get("id"), meta.get("seed"), meta.get("total_steps")) != (
        k,
        seed,
        record["steps"],
    ):
        return "metadata.json names another episode"
    if record["seed"] != seed:
        return "recorded with another seed"
    try:
        import pyarrow.ipc as ipc

        with ipc.open_file(folder / "part-0.arrow") as reader:
            rows = sum(reader.get_batch(i).num_rows for i in range(reader.num_record_batches))
    except Exception as exc:  # noqa: BLE001 - any arrow failure means the file cannot be read
        return f"part-0.arrow unreadable ({type(exc).__name__})"
    if rows != record["steps"] + 1:
        return f"part-0.arrow holds {rows} rows, not {record['steps'] + 1}"
    return None


@dataclass
class Inspection:
    """What a resume found in a dataset folder, before anything is moved.

    Attributes:
        header: the readable header, or None.
        header_problem: why the header is set aside and rebuilt (None: kept).
        kept: episode index → its journal record, for the episodes that pass every check.
        damaged: (path relative to the dataset folder, why) of what is set aside.
        temporaries: this module's own leftovers of a killed run (deleted).
        missing: episodes the header counted that are not there.
        journal_lines_bad: unreadable journal lines.
        complete: the (kept) header says the dataset is complete.
    """

    header: dict[str, Any] | None
    header_problem: str | None
    kept: dict[int, dict[str, Any]] = field(default_factory=dict)
    damaged: list[tuple[str, str]] = field(default_factory=list)
    temporaries: list[Path] = field(default_factory=list)
    missing: list[int] = field(default_factory=list)
    journal_lines_bad: int = 0
    complete: bool = False

    def intact(self, planned: int) -> bool:
        """Nothing to set aside, rebuild or collect: every one of ``planned`` episodes kept, header and journal good."""
        return (
            not self.damaged
            and not self.temporaries
            and not self.missing
            and not self.journal_lines_bad
            and self.header_problem is None
            and sorted(self.kept) == list(range(planned))
        )

    def report(self, moved_to: Path | None, recollect: int) -> str | None:
        """One line saying what was set aside, where, and what is re-collected (None: nothing to say)."""
        parts = []
        episodes = [(rel.split("/")[1], why) for rel, why in self.damaged if _is_episode_path(rel)]
        others = [(rel, why) for rel, why in self.damaged if not _is_episode_path(rel) and rel != _HEADER_REL]
        if episodes:
            n = len(episodes)
            shown = "; ".join(f"{k}: {why}" for k, why in episodes)
            parts.append(f"{n} damaged episode{'s' if n > 1 else ''} ({_clip(shown)})")
        if others:
            shown = "; ".join(f"{rel}: {why}" for rel, why in others[:3])
            parts.append(f"{len(others)} other file{'s' if len(others) > 1 else ''} ({_clip(shown)})")
        if self.header_problem is not None and moved_to is not None and not parts:
            parts.append(f"{_HEADER_REL}")
        line = f"set aside {' and '.join(parts)} in {moved_to}" if parts else ""
        extra = []
        if self.missing:
            extra.append(f"episode{'s' if len(self.missing) > 1 else ''} {_ranges(self.missing)} missing")
        if self.journal_lines_bad:
            extra.append(f"{self.journal_lines_bad} unreadable line(s) in {JOURNAL}")
        if self.header_problem is not None:
            extra.append(f"{_HEADER_REL} {self.header_problem}: rebuilt from the settings and the kept episodes")
        if not line and not extra:
            return None
        tail = f"{len(self.kept)} episode{'s' if len(self.kept) != 1 else ''} kept, {recollect} to collect"
        return "; ".join([p for p in (line, *extra) if p] + [tail])


def _is_episode_path(rel: str) -> bool:
    parts = rel.split("/")
    return len(parts) == 2 and parts[0] == "data" and _episode_index(parts[1]) is not None


def _clip(text: str, limit: int = 240) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _ranges(values: list[int]) -> str:
    shown = ", ".join(str(v) for v in values[:8])
    return shown + (f" … ({len(values)} in all)" if len(values) > 8 else "")


def _episode_index(name: str) -> int | None:
    return int(name) if name.isascii() and name.isdigit() and str(int(name)) == name else None


def inspect_dataset(
    ds_id: str,
    folder: Path,
    settings: Mapping[str, Any],
    episode_seeds: list[int],
    expected_header: Mapping[str, Any],
) -> Inspection:
    """Check a dataset folder for resuming with ``settings`` and ``len(episode_seeds)`` episodes (read only).

    Args:
        ds_id: its id.
        folder: the dataset folder.
        settings: agent, env_id, env_kwargs, seed of the run.
        episode_seeds: reset seed of each planned episode.
        expected_header: the header these settings give, without counts; a readable header whose
            fields differ from it is set aside and rebuilt.

    A complete dataset is checked the same way (a resume repairs it: its damaged episodes are re-collected).

    Raises:
        ValueError: a dataset of other settings, one not written by this package, or one holding episodes
            beyond ``len(episode_seeds)`` — one line; nothing is moved.
    """
    header, problem = read_header(folder)
    if header is not None:
        block = header.get("electroloc")
        old = settings_of(block)
        if old is None:
            raise ValueError(
                f"dataset {ds_id!r} ({folder}) was not written by electroloc dataset (its metadata has no "
                f"'electroloc' block); pass --force to replace it"
            )
        if old != dict(settings):
            raise ValueError(f"dataset {ds_id!r} was started with other settings {old}; pass --force to replace it")
        fixed = {k: v for k, v in header.items() if k not in _COUNTED}
        want = {k: v for k, v in expected_header.items() if k not in _COUNTED}
        # what a run may change: the reference, planned count, counts
        if {k: v for k, v in fixed.items() if k not in _REFERENCE} != {
            k: v for k, v in want.items() if k not in _REFERENCE
        }:
            problem = "differs from the header of these settings"
    journal_settings, records, bad = read_journal(folder)
    if journal_settings is not None and journal_settings != dict(settings):
        if header is None:
            raise ValueError(
                f"dataset {ds_id!r} was started with other settings {journal_settings}; pass --force to replace it"
            )
        records, bad = {}, bad + 1  # a journal of other settings beside this header: not this dataset's
    if journal_settings is None and header is None:
        records = {}  # nothing says which settings these episodes were written with
    complete = header is not None and header["electroloc"].get("complete") is True
    found = Inspection(header=header, header_problem=problem, journal_lines_bad=bad, complete=complete)
    if problem is not None and header_path(folder).exists():
        found.damaged.append((_HEADER_REL, problem))
    journal = folder / JOURNAL
    if os.path.lexists(journal) and (journal.is_symlink() or not journal.is_file()):
        found.damaged.append((JOURNAL, "not a file"))
    planned = len(episode_seeds)
    data = folder / "data"
    beyond = sorted(
        k for k in (_episode_index(p.name) for p in data.iterdir() if p.is_dir()) if k is not None and k >= planned
    )
    if beyond:
        raise ValueError(
            f"dataset {ds_id!r} holds episode {beyond[-1]}; resume it with --episodes {beyond[-1] + 1} or more"
        )
    for entry in sorted(data.iterdir(), key=lambda p: p.name):
        name = entry.name
        if name == "metadata.json":
            continue
        if _is_temporary(name, "metadata.json"):
            found.temporaries.append(entry)
            continue
        k = _episode_index(name)
        if k is None or not entry.is_dir():
            found.damaged.append((f"data/{name}", "not part of the dataset"))
            continue
        why = _episode_problem(entry, k, episode_seeds[k], records.get(k))
        if why is not None:
            found.damaged.append((f"data/{name}", why))
            continue
        found.kept[k] = records[k]
        for extra in sorted(p.name for p in entry.iterdir() if p.name not in EPISODE_FILES):
            found.damaged.append((f"data/{name}/{extra}", f"not a file of episode {k}"))
    found.temporaries += [p for p in folder.iterdir() if p.name == STAGING or _is_temporary(p.name, JOURNAL)]
    counted = header.get("total_episodes") if header is not None else None
    if type(counted) is int:
        present = {int(p.name) for p in data.iterdir() if _episode_index(p.name) is not None}
        found.missing = [k for k in range(min(counted, planned)) if k not in present]
    return found


#: Header keys a run rewrites (counts, size, the block) and those a resume may change (the reference).
_COUNTED = {"total_episodes", "total_steps", "dataset_size", "electroloc"}
_REFERENCE = {"ref_min_score", "ref_max_score"}


def set_aside(folder: Path, found: Inspection) -> Path | None:
    """Delete this module's temporaries and move what ``found`` marks damaged to ``quarantine/<n>/`` (the
    first unused n); returns that folder (None: nothing moved).
    """
    for tmp in found.temporaries:
        remove(tmp)
    if not found.damaged:
        return None
    base = folder / QUARANTINE
    n = 1
    while (base / str(n)).exists():
        n += 1
    target = base / str(n)
    for rel, _why in found.damaged:
        dest = target / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.rename(folder / rel, dest)
        kill_point("quarantined")
    return target


def flush_to_disk(folder: Path) -> None:
    """Flush what was written under ``folder`` to the disk: one ``sync`` where the system has it (one
    call, however many episodes), else an fsync of every file.
    """
    if hasattr(os, "sync"):
        os.sync()
        return
    for dirpath, _dirs, files in os.walk(folder):  # pragma: no cover - systems without sync()
        for name in files:
            fd = os.open(os.path.join(dirpath, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:  # pragma: no cover - Windows cannot open a folder
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - some file systems refuse a folder's fsync
        pass
    finally:
        os.close(fd)


def is_complete(folder: Path) -> bool:
    """The dataset folder's header is readable and says ``complete``."""
    header, _ = read_header(folder)
    block = header.get("electroloc") if header is not None else None
    return isinstance(block, dict) and block.get("complete") is True


def recover_swap(paths: DatasetFolder) -> None:
    """Finish a replacement a kill interrupted, and delete a replacement a kill left unfinished.

    The swap renames the dataset to ``.old``, the complete replacement ``.new`` to the dataset, and then
    deletes ``.old``; killed between the renames, the replacement is moved in now (or, were it not
    complete, the old dataset moved back).
    """
    path, new, old = paths.path, paths.new, paths.old
    if os.path.lexists(old):
        if not os.path.lexists(path):
            os.rename(new if new.is_dir() and is_complete(new) else old, path)
        remove(old)
    remove(new)


def remove(path: Path) -> None:
    """Delete a file, a folder and all it holds, or a symbolic link itself (never what a link points to);
    nothing if ``path`` does not exist.
    """
    if path.is_symlink() or path.is_file():
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


def swap_in(paths: DatasetFolder) -> None:
    """Replace the dataset by its complete replacement: rename, rename, then delete the old one."""
    os.rename(paths.path, paths.old)
    _fsync_dir(paths.path.parent)
    kill_point("swap")
    os.rename(paths.new, paths.path)
    _fsync_dir(paths.path.parent)
    kill_point("swapped")
    remove(paths.old)
