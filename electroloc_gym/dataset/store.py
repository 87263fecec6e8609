"""A dataset's folders on disk: where a run writes, how it publishes, and what a resume keeps.

Layout, under the datasets root (:func:`datasets_root`)::

    <namespace>/<name>-vN/                          the dataset (what the id names; Minari reads data/)
        data/metadata.json                          Minari's header and the "electroloc" block
        data/<k>/part-0.arrow, data/<k>/metadata.json     episode k, Minari's arrow storage
        quarantine/<n>/...                          what the n-th resume set aside (moved, never deleted)
    <namespace>/.<name>-vN.electroloc-partial/      the run's output while it is written (the same layout)
    <namespace>/.<name>-vN.electroloc-partial.new/  the partial while its header is written (then renamed)
    <namespace>/.<name>-vN.electroloc-old/          --force: the replaced dataset between two renames
    .electroloc-locks/<id>.lock                     one writer per id

**Sized to data that regenerates.** Every episode of a dataset is a function of its settings and its seed,
so a run needs no journal: it writes beside the dataset, in the partial folder, and publishes with one
rename. The partial is made whole with its header (its settings, ``complete`` false; :func:`start_partial`);
each episode is written by Minari's own arrow storage into the partial's ``.staging/`` and moved into
``data/<k>`` whole (one rename), its ``metadata.json`` carrying the sha256 of its ``part-0.arrow`` and of the
run's settings (:func:`settings_digest`). When all are there, the files are flushed to the disk, the header
gets its counts and ``complete``, and the partial is renamed to the dataset's name. A kill at any moment
leaves whole episodes in the partial, or the published dataset.

**Resume** (:func:`inspect_dataset`, :func:`set_aside`) keeps each episode that is exactly one of these
settings — its two files and nothing else, its index, seed and settings digest, its arrow file's sha256
and row count — and regenerates the rest from their seeds. Anything else in ``data/``, and an unreadable or
altered header (then rebuilt), is moved to ``quarantine/<n>/`` and named in one line. A published dataset is
checked the same way: intact and as long as asked, it is left as it is; otherwise it is moved back to the
partial (one rename) and continued.

**Replacement** (``--force``): the dataset is renamed to ``.<name>-vN.electroloc-old``, the partial to its
name, and the old one deleted last; a run killed between the renames is finished by the next run on the id
(:func:`recover_swap`). Only a folder that is exactly a dataset (``data/`` and this module's own names) is
ever replaced.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import msgspec
from msgspec import Meta, Struct

from electroloc_gym.utils.fileio import FolderLock, atomic_write_text, check_output_folder, probe_write

__all__ = [
    "MAX_ID_CHARS",
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
    "settings_digest",
]

#: Longest dataset id (characters): the folder name plus this module's suffixes stays within a file
#: system's 255-byte name limit.
MAX_ID_CHARS = 200
#: Where a resume sets damaged files aside, beside ``data/``.
QUARANTINE = "quarantine"
#: The files of one episode folder (Minari's arrow storage).
EPISODE_FILES = ("metadata.json", "part-0.arrow")
#: Where episodes are written before they are moved into ``data/``, beside it.
STAGING = ".staging"
#: The names a dataset folder may hold besides ``data/`` (``checksums.jsonl``: the journal of the layout
#: before episodes carried their own checksums; a resume sets it aside).
OWN_NAMES = frozenset({"data", QUARANTINE, STAGING, "checksums.jsonl"})
_HEADER_REL = "data/metadata.json"
_PARTIAL, _OLD = ".electroloc-partial", ".electroloc-old"
_LOCKS = ".electroloc-locks"
_ID_RE = re.compile(r"(?P<namespace>[A-Za-z0-9_-]+(?:/[A-Za-z0-9_-]+)*)/(?P<name>[A-Za-z0-9_-]+)-v(?P<version>[0-9]+)")
Sha256 = Annotated[str, Meta(pattern="^[0-9a-f]{64}$")]


class EpisodeMeta(Struct, forbid_unknown_fields=True):
    """An episode's ``metadata.json``: Minari's keys and the two checksums this package adds."""

    id: Annotated[int, Meta(ge=0)]
    seed: Annotated[int, Meta(ge=0)]
    total_steps: Annotated[int, Meta(ge=1)]
    sha256: Sha256  # of its part-0.arrow
    settings_sha256: Sha256  # of the settings it was collected with (settings_digest)


_EPISODE_META = msgspec.json.Decoder(EpisodeMeta)


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
    """The datasets root: ``MINARI_DATASETS_PATH``, or Minari's default when unset; writable. A missing folder
    is created when its parent folder exists (Minari's default with its parents).

    Raises:
        ValueError: set to an empty string (Minari's loaders cannot use it either), a file, a folder whose
            parent does not exist, or a place this process cannot write — one line naming the variable.
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
    """The folders of dataset ``ds_id`` under ``root``: the dataset, the run's partial, the swap's old copy."""

    root: Path
    ds_id: str

    @property
    def path(self) -> Path:
        return self.root.joinpath(*self.ds_id.split("/"))

    @property
    def partial(self) -> Path:
        return self.path.with_name("." + self.path.name + _PARTIAL)

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
        others = sorted(p.name for p in path.iterdir() if p.name not in OWN_NAMES)
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


def header_path(folder: Path) -> Path:
    return folder / "data" / "metadata.json"


def read_header(folder: Path) -> tuple[dict[str, Any] | None, str | None]:
    """(the header, None) or (None, why it is unreadable)."""
    try:
        header = msgspec.json.decode(header_path(folder).read_bytes())
    except FileNotFoundError:
        return None, "missing"
    except (OSError, msgspec.DecodeError, RecursionError) as exc:
        return None, f"unreadable ({type(exc).__name__})"
    if not isinstance(header, dict):
        return None, "not a JSON object"
    return header, None


def write_header(folder: Path, header: Mapping[str, Any]) -> None:
    """Replace ``data/metadata.json`` atomically (strict JSON: every field is JSON data already)."""
    atomic_write_text(header_path(folder), json.dumps(header, allow_nan=False))


class Settings(Struct):
    """What every episode of a dataset depends on: the agent spec, the env, its kwargs and the root seed (the
    header's ``electroloc`` block holds them beside the run's record, which is not checked here).
    """

    agent: Annotated[str, Meta(min_length=1)]
    env_id: Annotated[str, Meta(min_length=1)]
    env_kwargs: dict[str, Any]
    seed: Annotated[int, Meta(ge=1)]


def settings_of(block: Any) -> dict[str, Any] | None:
    """The :class:`Settings` of a header's ``electroloc`` block as plain data, or None where it holds none."""
    try:
        return msgspec.to_builtins(msgspec.convert(block, Settings))
    except msgspec.ValidationError:
        return None


def settings_digest(settings: Mapping[str, Any]) -> str:
    """The sha256 of the settings an episode depends on (their sorted JSON): what each episode records."""
    return hashlib.sha256(json.dumps(dict(settings), sort_keys=True).encode()).hexdigest()


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def episode_problem(folder: Path, k: int, seed: int, digest: str) -> tuple[int | None, str | None]:
    """(its step count, None) if episode folder ``folder`` is exactly episode ``k`` of the settings whose
    digest is ``digest``, reset with ``seed``; else (None, why not).
    """
    for name in EPISODE_FILES:
        if not (folder / name).is_file():
            return None, f"no {name}"
    try:
        meta = _EPISODE_META.decode((folder / "metadata.json").read_bytes())
    except OSError:
        return None, "metadata.json unreadable"
    except (msgspec.MsgspecError, RecursionError) as exc:
        return None, f"metadata.json: {str(exc)[:120]}"
    if (meta.id, meta.seed) != (k, seed):
        return None, "metadata.json does not name this episode"
    if meta.settings_sha256 != digest:
        return None, "written with other settings"
    try:
        if file_sha256(folder / "part-0.arrow") != meta.sha256:
            return None, "part-0.arrow does not match its checksum"
        import pyarrow.ipc as ipc

        with ipc.open_file(folder / "part-0.arrow") as reader:
            rows = sum(reader.get_batch(i).num_rows for i in range(reader.num_record_batches))
    except Exception as exc:  # noqa: BLE001 - any read failure means the file cannot be kept
        return None, f"part-0.arrow unreadable ({type(exc).__name__})"
    if rows != meta.total_steps + 1:
        return None, f"part-0.arrow holds {rows} rows, not {meta.total_steps + 1}"
    return meta.total_steps, None


@dataclass
class Inspection:
    """What a resume found in a dataset folder, before anything is moved.

    Attributes:
        header: the readable header, or None.
        header_problem: why the header is set aside and rebuilt (None: kept).
        kept: episode index → its step count, for the episodes that pass every check.
        damaged: (path relative to the dataset folder, why) of what is set aside.
        missing: episodes the header counted that are not there.
        temporaries: this package's own leftovers of a killed run (the staging folder, a header's
            temporary file): deleted.
    """

    header: dict[str, Any] | None
    header_problem: str | None
    kept: dict[int, int] = field(default_factory=dict)
    damaged: list[tuple[str, str]] = field(default_factory=list)
    missing: list[int] = field(default_factory=list)
    temporaries: list[Path] = field(default_factory=list)

    def intact(self, planned: int) -> bool:
        """Nothing to set aside, rebuild or collect: every one of ``planned`` episodes kept, the header good."""
        return not self.damaged and not self.missing and self.header_problem is None and len(self.kept) == planned

    def report(self, moved_to: Path | None, recollect: int) -> str | None:
        """One line saying what was set aside, where, and what is re-collected (None: nothing to say)."""
        parts = []
        episodes = [(rel.split("/")[1], why) for rel, why in self.damaged if _is_episode_path(rel)]
        others = [(rel, why) for rel, why in self.damaged if not _is_episode_path(rel) and rel != _HEADER_REL]
        for noun, items, listed in (("damaged episode", episodes, episodes), ("other file", others, others[:3])):
            if items:
                shown = "; ".join(f"{name}: {why}" for name, why in listed)
                parts.append(f"{len(items)} {noun}{'s' if len(items) > 1 else ''} ({_clip(shown)})")
        if self.header_problem is not None and moved_to is not None and not parts:
            parts.append(_HEADER_REL)
        line = f"set aside {' and '.join(parts)} in {moved_to}" if parts else ""
        extra = []
        if self.missing:
            extra.append(f"episode{'s' if len(self.missing) > 1 else ''} {_ranges(self.missing)} missing")
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


#: Header keys a run rewrites (counts, size, the block) and those a resume may change (the reference).
_COUNTED = {"total_episodes", "total_steps", "dataset_size", "electroloc"}
REFERENCE_KEYS = {"ref_min_score", "ref_max_score"}


def inspect_dataset(
    ds_id: str,
    folder: Path,
    settings: Mapping[str, Any],
    episode_seeds: list[int],
    expected_header: Mapping[str, Any],
    force: str,
) -> Inspection:
    """Check dataset ``ds_id``'s ``folder`` (published or partial) for resuming with ``settings`` (read only):
    ``episode_seeds`` the reset seed of each planned episode, ``expected_header`` the header these settings give
    (a readable header whose fixed fields differ from it is set aside and rebuilt); ``force``: how a refusal
    names the switch that replaces the dataset, in the caller's words (:func:`~electroloc_gym.options.message_names`).

    Raises:
        ValueError: a dataset of other settings, one not written by this package, or one holding episodes
            beyond ``len(episode_seeds)`` — one line; nothing is moved.
    """
    header, problem = read_header(folder)
    if header is not None:
        old = settings_of(header.get("electroloc"))
        if old is None:
            raise ValueError(
                f"dataset {ds_id!r} ({folder}) was not written by electroloc dataset (its metadata has no "
                f"'electroloc' block); pass {force} to replace it"
            )
        if old != dict(settings):
            raise ValueError(f"dataset {ds_id!r} was started with other settings {old}; pass {force} to replace it")
        fixed = {k: v for k, v in header.items() if k not in _COUNTED | REFERENCE_KEYS}
        if fixed != {k: v for k, v in expected_header.items() if k not in _COUNTED | REFERENCE_KEYS}:
            problem = "differs from the header of these settings"
    found = Inspection(header=header, header_problem=problem)
    if problem is not None and os.path.lexists(header_path(folder)):
        found.damaged.append((_HEADER_REL, problem))
    planned, digest = len(episode_seeds), settings_digest(settings)
    data = folder / "data"
    beyond = sorted(
        k for k in (_episode_index(p.name) for p in data.iterdir() if p.is_dir()) if k is not None and k >= planned
    )
    if beyond:
        raise ValueError(
            f"dataset {ds_id!r} holds episode {beyond[-1]}; resume it with --episodes {beyond[-1] + 1} or more"
        )
    for entry in sorted(data.iterdir(), key=lambda p: p.name):
        k = _episode_index(entry.name)
        if entry.name == "metadata.json":
            continue
        if entry.name.startswith(".metadata.json.") and entry.name.endswith(".tmp"):  # a header write's own
            found.temporaries.append(entry)
            continue
        if k is None or not entry.is_dir() or entry.is_symlink():
            found.damaged.append((f"data/{entry.name}", "not part of the dataset"))
            continue
        steps, why = episode_problem(entry, k, episode_seeds[k], digest)
        if steps is None:
            found.damaged.append((f"data/{entry.name}", why or "damaged"))
            continue
        found.kept[k] = steps
        for extra in sorted(p.name for p in entry.iterdir() if p.name not in EPISODE_FILES):
            found.damaged.append((f"data/{entry.name}/{extra}", f"not a file of episode {k}"))
    if os.path.lexists(folder / "checksums.jsonl"):
        found.damaged.append(("checksums.jsonl", "not part of the dataset"))
    counted = header.get("total_episodes") if header is not None else None
    if type(counted) is int:
        present = {int(p.name) for p in data.iterdir() if _episode_index(p.name) is not None}
        found.missing = [k for k in range(min(counted, planned)) if k not in present]
    return found


def set_aside(folder: Path, found: Inspection) -> Path | None:
    """Delete this module's own leftovers (the staging folder, ``found``'s temporaries) and move what
    ``found`` marks damaged to ``quarantine/<n>/`` (the first unused n); returns that folder (None: nothing
    moved).
    """
    for tmp in [folder / STAGING, *found.temporaries]:
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
            with open(os.path.join(dirpath, name), "rb") as fh:
                os.fsync(fh.fileno())


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
    """Finish a replacement a kill interrupted between its two renames: the complete partial is moved in
    (or, were it not complete, the old dataset moved back), and the old one deleted.
    """
    path, partial, old = paths.path, paths.partial, paths.old
    if os.path.lexists(old):
        if not os.path.lexists(path):
            os.rename(partial if partial.is_dir() and is_complete(partial) else old, path)
        remove(old)


def remove(path: Path) -> None:
    """Delete a file, a folder and all it holds, or a symbolic link itself (never what a link points to);
    nothing if ``path`` does not exist.
    """
    if path.is_symlink() or path.is_file():
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


def start_partial(paths: DatasetFolder, header: Mapping[str, Any]) -> None:
    """Make the partial folder with ``header`` and an empty ``data/``, whole: built under ``<partial>.new`` (this
    module's own name: a leftover of a killed start is replaced) and renamed to the partial's name.
    """
    fresh = paths.partial.with_name(paths.partial.name + ".new")
    remove(fresh)
    (fresh / "data").mkdir(parents=True)
    write_header(fresh, header)
    os.rename(fresh, paths.partial)


def publish(paths: DatasetFolder) -> None:
    """Move the complete partial to the dataset's name: one rename, or, replacing a dataset, rename, rename,
    then delete the old one.
    """
    if os.path.lexists(paths.path):
        os.rename(paths.path, paths.old)
        _fsync_dir(paths.path.parent)
    os.rename(paths.partial, paths.path)
    _fsync_dir(paths.path.parent)
    remove(paths.old)
