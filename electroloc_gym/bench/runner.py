"""The benchmark run: agents × conditions × seeded trials → trials.jsonl, summary.json, table.md, steps.png.

:func:`run_benchmark` checks everything before any trial runs — the output folder
(:func:`~electroloc_gym.bench.records.prepare_out_dir`), its lock (a second run on the same folder
refuses), the stored run when resuming (``config.json`` and every record's own seeds and settings,
:mod:`electroloc_gym.bench.records`), and that every agent builds — then maps the missing trials
(:mod:`electroloc_gym.bench.config`) over a backend (:mod:`electroloc_gym.bench.backends`) with the
worker function :func:`~electroloc_gym.bench.trials.run_trial`, appending each record as it arrives.
The summary and tables are computed from the records keyed by (condition, agent, trial), so a trial
is never counted twice; ``config.json``, ``summary.json``, ``table.md`` and ``steps.png`` are
written atomically.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from electroloc_gym.bench.agents import agent_display_name, agent_kind, cached_agent
from electroloc_gym.bench.backends import make_backend
from electroloc_gym.bench.config import (
    DEFAULT_AGENTS,
    GLOBAL_CONDITION,
    GLOBAL_ENV_ID,
    IDENTITY_KEYS,
    BenchConfig,
    TrialSpec,
    make_trial_specs,
    resolve_conditions,
    trial_seeds,
)
from electroloc_gym.bench.progress import TrialProgress
from electroloc_gym.bench.records import (
    REJECTED_FILE,
    TRIALS_FILE,
    FolderLock,
    LoadedRecords,
    RecordWriter,
    load_records,
    prepare_out_dir,
    read_trials,
    set_aside,
)
from electroloc_gym.bench.trials import TIMING_KEYS, run_trial
from electroloc_gym.fileio import atomic_write_text

# The run, plus the names a caller of the runner needs (defined in config, records and trials).
__all__ = ["run_benchmark", "write_json_atomic", "read_config", "BenchConfig", "TrialSpec", "DEFAULT_AGENTS",
           "GLOBAL_CONDITION", "GLOBAL_ENV_ID", "resolve_conditions", "trial_seeds", "make_trial_specs",
           "read_trials", "TIMING_KEYS", "run_trial"]

_Log = Callable[[str], None] | None


def write_json_atomic(path: str | os.PathLike, obj: Any) -> None:
    """JSON-dump ``obj`` to ``path`` atomically (strict JSON: no NaN)."""
    atomic_write_text(path, json.dumps(obj, indent=2, allow_nan=False) + "\n")


def _config_problem(stored: Any) -> str | None:
    """Why a parsed config.json cannot describe a run (None: it can)."""
    if not isinstance(stored, dict):
        return f"not a JSON object ({type(stored).__name__})"
    later = ("gain_levels", "sensor_layout")  # keys added later
    missing = [k for k in ("seed", *IDENTITY_KEYS) if k not in stored and k not in later]
    if missing:
        return f"missing key(s) {missing}"
    if isinstance(stored["seed"], bool) or not isinstance(stored["seed"], int):
        return f"'seed' must be an integer, got {stored['seed']!r}"
    for key, kind in (("agents", list), ("conditions", list), ("trials", int)):
        if key in stored and not isinstance(stored[key], kind):
            return f"{key!r} must be a {kind.__name__}, got {stored[key]!r}"
    return None


def read_config(path: Path, log: _Log) -> dict[str, Any] | None:
    """config.json of a stored run; a damaged one is reported, set aside (renamed) and ignored."""
    if not path.exists():
        return None
    try:
        stored = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        why = f"not valid UTF-8 JSON ({exc})"
    else:
        why = _config_problem(stored)
        if why is None:
            return stored
    aside = path.with_name("config.rejected.json")
    os.replace(path, aside)
    if log is not None:
        log(f"{path}: {why}; moved to {aside.name}; every record is checked on its own instead")
    return None


def _resume(config: BenchConfig, out: Path, log: _Log) -> tuple[LoadedRecords, dict[str, Any] | None]:
    """Check a stored run against ``config``; set damaged lines aside. Returns its records and config."""
    stored = read_config(out / "config.json", log)
    if stored is not None:
        mismatch = {k: (stored.get(k), v) for k, v in config.identity().items() if stored.get(k) != v}
        if mismatch:
            raise ValueError(f"cannot resume {out}: settings differ from the stored run (stored, now): {mismatch}")
    loaded = load_records(out / TRIALS_FILE, config)
    if loaded.foreign:
        n, why = loaded.foreign[0]
        more = f" (and {len(loaded.foreign) - 1} more)" if len(loaded.foreign) > 1 else ""
        raise ValueError(f"cannot resume {out}: {loaded.path}:{n}{more} is not a trial of this run — {why}; "
                         f"resume with that run's settings or choose another --out")
    if loaded.rejected:
        set_aside(loaded)
        if log is not None:
            for msg in loaded.messages():
                log(msg)
            log(f"set {len(loaded.rejected)} line(s) aside in {out / REJECTED_FILE}; those trials run again")
    return loaded, stored


def _check_agents(config: BenchConfig, trust_pickle: bool, log: _Log) -> None:
    """Fail fast (before any worker starts) on bad agent names, paths or policy files; say what runs."""
    described = []
    for spec in config.agents:
        agent = cached_agent(spec, trust_pickle=trust_pickle)
        kind = agent_kind(spec)
        if kind == "baseline":
            described.append(spec)
        else:
            described.append(f"{agent_display_name(spec)} (learned policy: {spec if kind == 'path' else 'shipped'}, "
                             f"{getattr(agent, 'env_kwargs', {}).get('observation', '?')} observation)")
    if log is not None:
        log("agents: " + "; ".join(described))


def run_benchmark(config: BenchConfig, out_dir: str | os.PathLike, *, workers: int | None = None,
                  backend: str = "process", resume: bool = False, progress: bool = True,
                  backend_options: dict[str, Any] | None = None, trust_pickle: bool = False,
                  log: _Log = print) -> dict[str, Any]:
    """Run (or resume) a benchmark and write its files; returns the summary.

    Args:
        config: the run.
        out_dir: output folder (created; locked for the run).
        workers: parallel workers (None: all cores).
        backend: backend name (:data:`electroloc_gym.bench.backends.BACKENDS`).
        resume: run only the trials not yet in ``out_dir/trials.jsonl``; without it an existing
            non-empty trials.jsonl is an error (never silently mixed).
        progress: show a progress bar.
        backend_options: extra options for the backend (e.g. a Ray address).
        trust_pickle: allow learned policies whose files need unpickling (SB3's bare zip).
        log: where to print one-line notes (None: silent).

    Raises:
        ValueError: a bad output folder, a folder in use by another run, bad agents, an existing
            run without ``resume``, or a stored run whose seed or settings differ.
    """
    from electroloc_gym.bench.plots import plot_steps
    from electroloc_gym.bench.stats import summarize
    from electroloc_gym.bench.tables import render_table_md

    out = prepare_out_dir(out_dir)
    with FolderLock(out):
        trials_path, config_path = out / TRIALS_FILE, out / "config.json"
        stored: dict[str, Any] | None = None
        loaded = LoadedRecords(trials_path)
        if trials_path.exists() and trials_path.stat().st_size > 0:
            if not resume:
                raise ValueError(f"{trials_path} already holds trials; pass --resume to continue that run "
                                 f"or choose another --out")
            loaded, stored = _resume(config, out, log)
        _check_agents(config, trust_pickle, log)
        be = make_backend(backend, workers, **(backend_options or {}))

        stored_cfg = asdict(config)
        if stored is not None:  # remember the union of what was ever asked for
            stored_cfg["agents"] = list(dict.fromkeys([*stored.get("agents", []), *config.agents]))
            stored_cfg["conditions"] = list(dict.fromkeys([*stored.get("conditions", []), *config.conditions]))
            stored_cfg["trials"] = max(int(stored.get("trials", 0)), config.trials)
        write_json_atomic(config_path, stored_cfg)

        records = dict(loaded.records)
        specs = [s for s in make_trial_specs(config, trust_pickle=trust_pickle) if s.key not in records]
        # Longest jobs first (min-var, learned policies), so the pool's tail is short.
        cost = {"rnd-wlk": 0, "zero-crossing": 1}
        specs.sort(key=lambda s: -cost.get(s.agent, 2))
        if log is not None:
            log(f"electroloc bench: {len(config.agents)} agents × {len(config.conditions)} conditions × "
                f"{config.trials} trials; {len(records)} already done, {len(specs)} to run on backend {be.name!r} "
                f"with {be.workers} worker(s) → {out}")
        t0 = time.perf_counter()
        bar = TrialProgress(len(specs), be.workers, enabled=progress)
        try:
            with RecordWriter(trials_path) as writer:
                for spec, rec in be.run_trials(specs, run_trial):
                    writer.write(rec)
                    records[spec.key] = rec
                    bar.update(rec)
        finally:
            bar.close()
        wall = time.perf_counter() - t0

        wanted = [r for (c, a, k), r in records.items()
                  if c in config.conditions and a in config.agents and k < config.trials]
        summary = summarize(wanted, agents=list(config.agents), conditions=list(config.conditions))
        summary["config"] = asdict(config)
        summary["wall_s_this_run"] = wall
        summary["trials_run_this_time"] = len(specs)
        write_json_atomic(out / "summary.json", summary)
        atomic_write_text(out / "table.md", render_table_md(summary))
        plot_steps(summary, out / "steps.png")
    if log is not None:
        log(f"{len(specs)} trials in {wall:.1f} s; wrote {trials_path}, summary.json, table.md, steps.png")
    return summary

