"""A training run's folder: one run per folder, locked while it trains, its history kept in segments.

* A folder that already holds a run is refused unless the run is continued (``--resume``) or wiped
  first (``--force``); a non-empty folder that is not a run is never wiped.
* An exclusive ``flock`` on ``DIR/.lock`` keeps a second process out while a run trains.
* Each invocation is a *segment* in ``args.json`` (its arguments, start, wall time, timesteps); the
  record is updated during training, so a killed segment still shows how far it got.
  ``command.txt`` lists every segment's command; ``summary.json`` totals them.
* When a run resumes from an earlier point than where it stopped (a killed run continues from its
  last checkpoint), the evaluations and checkpoints past that point are moved to
  ``superseded/segment-K/`` — kept, but no longer mixed with the run's own history.
* JSON files are strict (non-finite floats are written as null).
"""

from __future__ import annotations

import csv
import fcntl
import json
import math
import os
import platform
import shlex
import shutil
import subprocess
import time
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from electroloc_gym.fileio import atomic_write_text
from electroloc_gym.train.config import ConfigError

__all__ = ["RUN_FILES", "RunDir", "strict_json", "git_commit", "versions", "read_segments"]

#: Names whose presence marks a folder as a training run.
RUN_FILES = ("args.json", "config.yml", "command.txt", "eval.csv", "summary.json", "model.zip", "policy.json",
             "checkpoints", "best")


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def strict_json(obj: Any) -> str:
    """``json.dumps`` that writes NaN/±inf as null (valid JSON for every reader)."""
    return json.dumps(_finite(obj), indent=2, allow_nan=False) + "\n"


def git_commit() -> dict[str, Any]:
    """The package's git commit and whether the work tree had changes (None outside a git checkout)."""
    here = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True,
                             timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip() != ""
    except (OSError, subprocess.SubprocessError):
        return {"git_commit": None, "git_dirty": None}
    return {"git_commit": sha or None, "git_dirty": dirty}


def versions() -> dict[str, str | None]:
    """Versions of Python and of the packages a policy depends on."""
    out: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("electroloc-gym", "torch", "stable-baselines3", "sb3-contrib", "gymnasium", "numpy", "safetensors"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def read_segments(folder: str | Path) -> list[dict[str, Any]]:
    """The segments recorded in ``folder/args.json`` ([] when there is none; a pre-segment file is one)."""
    p = Path(folder) / "args.json"
    if not p.is_file():
        return []
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{p} is not valid JSON ({exc}); cannot continue this run's record") from exc
    if isinstance(data, dict) and isinstance(data.get("segments"), list):
        return [s for s in data["segments"] if isinstance(s, dict)]
    if isinstance(data, dict):  # written before segments were recorded: one segment of unknown length
        return [{"args": data, "argv": None, "wall_time_s": None, "status": "unknown"}]
    raise ConfigError(f"{p} must be a JSON object")


class RunDir:
    """The ``--out`` folder of a training run.

    Args:
        path: the folder.

    Raises:
        ConfigError: ``path`` is an existing file, or ``""``.
    """

    def __init__(self, path: str | Path) -> None:
        if str(path).strip() == "":
            raise ConfigError("--out must be a folder path, got ''")
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise ConfigError(f"--out {str(path)!r} is an existing file, not a folder")
        self._lock_fd: int | None = None
        self.segments: list[dict[str, Any]] = []

    def holds_run(self) -> bool:
        """Whether the folder already holds (part of) a training run."""
        return self.path.is_dir() and any((self.path / n).exists() for n in RUN_FILES)

    def check_can_start(self, *, resume: bool, force: bool) -> None:
        """Refuse to mix runs: an existing run needs ``resume`` or ``force``; foreign files are never wiped."""
        if not self.path.is_dir():
            return
        entries = [p.name for p in self.path.iterdir() if p.name != ".lock"]
        if self.holds_run():
            if not (resume or force):
                raise ConfigError(f"--out {str(self.path)!r} already holds a training run; pass --resume to continue "
                                  f"it, --force to delete it and start over, or choose another --out")
        elif entries:
            raise ConfigError(f"--out {str(self.path)!r} exists and is not a training run folder (it holds "
                              f"{sorted(entries)[:5]}); choose a new or empty folder")

    def lock(self) -> None:
        """Take the folder's exclusive lock (held until the process ends).

        Raises:
            ConfigError: the folder cannot be created, or another process holds the lock.
        """
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ConfigError(f"--out {str(self.path)!r}: cannot create the run folder: {exc.strerror}") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            raise ConfigError(f"--out {str(self.path)!r} is in use by another training process (its lock is "
                              f"held); wait for it to finish or choose another --out") from exc
        self._lock_fd = fd

    def unlock(self) -> None:
        """Release the lock (also released when the process ends)."""
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def wipe(self) -> None:
        """Delete everything in the (locked) folder but the lock file (``--force``)."""
        for p in self.path.iterdir():
            if p.name == ".lock":
                continue
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink()

    # ------------------------------------------------------------------------------- history
    def set_aside_after(self, timesteps: int) -> Path | None:
        """Move evaluations and checkpoints past ``timesteps`` to ``superseded/segment-K/`` (K = next segment).

        Returns:
            The folder they went to, or None when nothing was past that point.
        """
        k = len(read_segments(self.path)) + 1
        dest = self.path / "superseded" / f"segment-{k}"
        moved = False
        ckpts = self.path / "checkpoints"
        if ckpts.is_dir():
            for d in ckpts.glob("step_*"):
                step = d.name.removeprefix("step_")
                if step.isdigit() and int(step) > timesteps:
                    (dest / "checkpoints").mkdir(parents=True, exist_ok=True)
                    d.rename(dest / "checkpoints" / d.name)
                    moved = True
        csv_path = self.path / "eval.csv"
        if csv_path.is_file():
            with csv_path.open(newline="") as fh:
                rows = list(csv.reader(fh))
            if rows:
                keep = [rows[0]] + [r for r in rows[1:] if not (r and r[0].isdigit() and int(r[0]) > timesteps)]
                late = [r for r in rows[1:] if r and r[0].isdigit() and int(r[0]) > timesteps]
                if late:
                    dest.mkdir(parents=True, exist_ok=True)
                    atomic_write_text(dest / "eval.csv", _csv_text([rows[0], *late]))
                    atomic_write_text(csv_path, _csv_text(keep))
                    moved = True
        return dest if moved else None

    def start_segment(self, argv: Sequence[str], args: Mapping[str, Any], *, timesteps_start: int,
                      resumed_from: str | None, set_aside: str | None) -> None:
        """Append this invocation to the run's segments (args.json) and rewrite command.txt."""
        self.segments = read_segments(self.path)
        for s in self.segments:  # a segment that never recorded its end was killed
            if s.get("status") == "running":
                s["status"] = "killed"
        self.segments.append({
            "argv": list(argv), "cwd": os.getcwd(), "args": dict(args),
            "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "resumed_from": resumed_from, "set_aside": set_aside, "timesteps_start": int(timesteps_start),
            "timesteps_end": int(timesteps_start), "wall_time_s": 0.0, "status": "running",
        })
        self._t0 = time.time()
        self._write_records()

    def previous_wall_time_s(self) -> float:
        """Wall time of the segments before this one (those with a recorded time)."""
        return sum(float(s.get("wall_time_s") or 0.0) for s in self.segments[:-1])

    def update_segment(self, timesteps: int, status: str = "running") -> None:
        """Record the current segment's progress (called during training and at its end)."""
        seg = self.segments[-1]
        seg.update(timesteps_end=int(timesteps), wall_time_s=round(time.time() - self._t0, 1), status=status)
        self._write_records()

    def total_wall_time_s(self) -> float:
        return round(sum(float(s.get("wall_time_s") or 0.0) for s in self.segments), 1)

    def commands(self) -> list[str]:
        """Every segment's command line (for provenance)."""
        return ["python -m electroloc_gym.train " + shlex.join(s["argv"]) for s in self.segments
                if s.get("argv") is not None]

    def _write_records(self) -> None:
        atomic_write_text(self.path / "args.json", strict_json({"segments": self.segments}))
        lines = [f"# training run {self.path.name}: {len(self.segments)} segment(s), "
                 f"{self.total_wall_time_s()} s wall time in total"]
        for i, s in enumerate(self.segments, 1):
            lines.append(f"# segment {i} ({s.get('status')}), started {s.get('started_utc', '?')}"
                         + (f", resumed from {s['resumed_from']}" if s.get("resumed_from") else ""))
            if s.get("argv") is not None:
                lines += [f"cd {shlex.quote(str(s.get('cwd', '.')))}",
                          "python -m electroloc_gym.train " + shlex.join(s["argv"])]
            seed = (s.get("args") or {}).get("seed")
            lines.append(f"# seed: {seed}; timesteps {s.get('timesteps_start', '?')} → {s.get('timesteps_end', '?')}; "
                         f"training wall time (s): {s.get('wall_time_s')}")
        atomic_write_text(self.path / "command.txt", "\n".join(lines) + "\n")


def _csv_text(rows: Sequence[Sequence[str]]) -> str:
    import io

    buf = io.StringIO()
    csv.writer(buf).writerows(rows)
    return buf.getvalue()
