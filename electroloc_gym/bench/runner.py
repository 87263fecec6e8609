"""The benchmark run: agents × conditions × seeded trials → trials.jsonl, summary.json, table.md and the figures.

:func:`run_benchmark` checks everything before any trial runs — the output folder
(:func:`~electroloc_gym.bench.records.prepare_out_dir`), its lock (a second run on the same folder
refuses), the stored run when resuming (``config.json`` and every record's own seeds and settings,
:mod:`electroloc_gym.bench.records`), and that every agent builds — then maps the missing trials
(:mod:`electroloc_gym.bench.config`) over a backend (:mod:`electroloc_gym.bench.backends`) with the
worker function :func:`~electroloc_gym.bench.trials.run_trial`, appending each record as it arrives.
The summary and tables are computed from the records keyed by (condition, agent, trial), so a trial
is never counted twice; ``config.json``, ``summary.json``, ``table.md`` and the figures ``steps.png`` and
``conditions.png`` (:mod:`electroloc_gym.bench.plots`) are written atomically.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.agent import AGENT_NAMES, BaselineAgent, agent_class
from electroloc_gym.baselines.rollout import AgentCallError, exception_line
from electroloc_gym.bench.agents import (
    AgentRef,
    agent_display_name,
    cached_agent,
    decision_seconds,
    layout_problem,
    planner_memory_bytes,
    plug_in_problem,
    policy_env_problem,
    resolve_agent,
)
from electroloc_gym.bench.backends import WorkerLost, make_backend
from electroloc_gym.bench.config import (
    BENCH_OPTIONS,
    DEFAULT_AGENTS,
    IDENTITY_DEFAULTS,
    MAP_CONDITIONS,
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
    TRIALS_GZ_FILE,
    LoadedRecords,
    RecordWriter,
    load_records,
    prepare_out_dir,
    read_trials,
    run_lock,
    set_aside,
)
from electroloc_gym.bench.schema import TIMING_KEYS
from electroloc_gym.bench.stored_run import read_config, record_rules
from electroloc_gym.bench.trials import TrialFailed, describe_trial, run_trial
from electroloc_gym.options import message_names, message_words
from electroloc_gym.utils.fileio import atomic_write_bytes, check_output_folder, strict_json, write_json_atomic

# The run, plus the names a caller of the runner needs (defined in config, records and trials).
__all__ = [
    "run_benchmark",
    "read_config",
    "record_rules",
    "OUTPUT_FILES",
    "BenchConfig",
    "TrialSpec",
    "DEFAULT_AGENTS",
    "MAP_CONDITIONS",
    "resolve_conditions",
    "trial_seeds",
    "make_trial_specs",
    "read_trials",
    "TIMING_KEYS",
    "run_trial",
]

#: The files a run derives from its records, written together (:func:`_write_outputs`).
OUTPUT_FILES = ("summary.json", "table.md", "steps.png", "conditions.png")
#: An agent whose own estimate of one decision exceeds this is announced before the run, s.
SLOW_DECISION_S = 10.0


def _resume(
    config: BenchConfig, out: Path, log: Callable[[str], None], trust_pickle: bool, names: Mapping[str, str]
) -> tuple[LoadedRecords, dict[str, Any] | None]:
    """Check a stored run against ``config``; set damaged lines aside. Returns its records and config."""
    stored = read_config(out / "config.json", log)
    if stored is not None:
        was = {k: stored.get(k, IDENTITY_DEFAULTS.get(k)) for k in config.identity()}  # keys added later: defaults
        mismatch = {k: (was[k], v) for k, v in config.identity().items() if was[k] != v}
        if mismatch:
            raise ValueError(f"cannot resume {out}: settings differ from the stored run (stored, now): {mismatch}")
    loaded = load_records(out / TRIALS_FILE, config, record_rules(config, stored, trust_pickle=trust_pickle))
    if loaded.foreign:
        n, why = loaded.foreign[0]
        more = f" (and {len(loaded.foreign) - 1} more)" if len(loaded.foreign) > 1 else ""
        raise ValueError(
            f"cannot resume {out}: {loaded.path}:{n}{more} is not a trial of this run — {why}; "
            f"resume with that run's settings or choose another {names['out']}"
        )
    if loaded.rejected:
        set_aside(loaded)
        for msg in loaded.messages():
            log(msg)
        log(f"set {len(loaded.rejected)} line(s) aside in {out / REJECTED_FILE}; those trials run again")
    return loaded, stored


def _check_agents(config: BenchConfig, trust_pickle: bool) -> tuple[str, list[str]]:
    """Fail fast (before any worker starts and before the output folder is touched) on bad agent names,
    paths, factories or policy files, and on an agent that cannot run (:func:`_check_agent`). Returns what
    runs, and the warnings.
    """
    described, warnings = [], []
    for spec in config.agents:
        ref = resolve_agent(spec)
        agent = cached_agent(ref, trust_pickle=trust_pickle)
        try:
            text, warning = _check_agent(config, ref, agent)
        except AgentCallError as exc:  # the agent's own code raised: a method, or reading an attribute
            raise ValueError(f"agent {spec!r}: {exc}") from None
        described.append(text)
        if warning is not None:
            warnings.append(warning)
    return "agents: " + "; ".join(described), warnings


def _check_agent(config: BenchConfig, ref: AgentRef, agent: Any) -> tuple[str, str | None]:
    """What runs, and a warning (or None) when the agent's own estimate of a decision exceeds
    :data:`SLOW_DECISION_S`.

    Raises:
        ValueError: a plug-in agent that would change the run's protocol
            (:func:`~electroloc_gym.bench.agents.plug_in_problem`), an agent that cannot run on the run's sensor
            layout or whose decisions do not fit in memory, or a learned policy recorded for another env,
            observation layout or action space.
        AgentCallError: the agent's own code raised (a plug-in agent's attributes are read through
            :class:`~electroloc_gym.bench.agents.PluginAgent`).
    """
    spec, kind, warning = ref.text, ref.kind, None
    if not ref.builtin:
        why = plug_in_problem(agent, config.env_id)
        if why is not None:
            raise ValueError(f"agent {spec!r} cannot run on this benchmark: {why}")
    why = layout_problem(agent, config.sensor_layout)
    if why is not None:
        raise ValueError(f"agent {spec!r} cannot run with --sensor-layout {config.sensor_layout or 'single'}: {why}")
    try:
        need = planner_memory_bytes(agent, config.n_particles)
    except AgentCallError:
        raise
    except Exception as exc:  # noqa: BLE001 - an estimate that is not a number: one line
        raise ValueError(f"agent {spec!r}: its memory_bytes() gave no byte count ({exception_line(exc)})") from None
    if need > _memory_budget():
        raise ValueError(
            f"agent {spec!r} needs ≈{need / 2**30:.3g} GiB per decision with {config.n_particles} "
            f"particles; this machine has ≈{_memory_budget() / 2**30:.3g} GiB to spare: choose "
            f"smaller options"
        )
    slow = decision_seconds(agent, config.n_particles)
    if slow > SLOW_DECISION_S:
        warning = (
            f"electroloc bench: warning: agent {spec!r} takes ≈{slow:.3g} s per decision by its own "
            f"estimate (up to {config.max_observations} decisions a trial, {config.trials} trial(s) "
            f"per condition): choose smaller options for a shorter run"
        )
    probe_env(config, spec, agent)
    if kind in ("baseline", "factory", "object"):
        return spec, warning
    why = policy_env_problem(spec, agent, config.env_id, config.gain_levels, config.sensor_layout)
    if why is not None:
        raise ValueError(f"agent {spec!r} cannot run on this benchmark: {why}")
    text = (
        f"{agent_display_name(spec)} (learned policy: {spec if kind == 'path' else 'shipped'}, "
        f"{getattr(agent, 'env_kwargs', {}).get('observation', '?')} observation)"
    )
    return text, warning


def _lost_text(exc: WorkerLost) -> str:
    """One line: the trial (or the few trials in flight) a dead worker process was running."""
    trials = [describe_trial(spec) for spec in exc.specs[:4]]
    more = f" (and {len(exc.specs) - 4} more)" if len(exc.specs) > 4 else ""
    which = trials[0] if len(trials) == 1 else "one of: " + "; ".join(trials) + more
    return f"a worker process died ({exc.reason}) while running {which}"


def _memory_budget() -> int:
    """Half the physical memory available now, bytes (8 GiB where the OS does not say)."""
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2)
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 8 * 2**30


def probe_env(config: BenchConfig, spec: str, agent: Any) -> None:
    """Build the env a trial of ``spec`` runs in (first condition), so the env's own argument checks
    (particle count, cap, sensor model, the agent's env_kwargs) fail before any trial; a built-in controller
    is also bound to it once (``reset``), so a controller that cannot read that env's belief (look-ahead on
    the moving target's velocity belief, say) is refused before any trial too. A plug-in agent's code is not
    run here.

    Raises:
        ValueError: the env refuses the run's settings with this agent, or the controller refuses the env (the
            message names the agent).
    """
    import gymnasium as gym

    builtin = resolve_agent(spec).builtin
    kwargs = config.env_kwargs(agent, config.conditions[0], builtin=builtin)
    try:
        env = gym.make(config.env_id, **kwargs)
    except (TypeError, ValueError, MemoryError) as exc:
        raise ValueError(f"agent {spec!r}: {config.env_id} refuses this run's settings: {exc}") from None
    try:
        if builtin:
            env.reset(seed=0)
            agent.reset(env)
    except ValueError as exc:
        raise ValueError(f"agent {spec!r} cannot run on {config.env_id} with these settings: {exc}") from None
    finally:
        env.close()


def _write_outputs(out: Path, summary: dict[str, Any]) -> None:
    """The :data:`OUTPUT_FILES`, all rendered before any is written: together or not at all (on a failure none
    stays, so no folder holds a summary and a table of different records).
    """
    from electroloc_gym.bench.plots import conditions_png, steps_png
    from electroloc_gym.bench.tables import render_table_md

    try:
        content = {
            "summary.json": strict_json(summary).encode("utf-8"),
            "table.md": render_table_md(summary).encode("utf-8"),
            "steps.png": steps_png(summary),
            "conditions.png": conditions_png(summary),
        }
        for name in OUTPUT_FILES:
            atomic_write_bytes(out / name, content[name])
    except BaseException:  # the old files describe other records: none stays beside trials.jsonl
        for name in OUTPUT_FILES:
            (out / name).unlink(missing_ok=True)
        raise


def run_benchmark(
    config: BenchConfig,
    out_dir: str | os.PathLike[str],
    *,
    workers: int | None = None,
    backend: str = "process",
    resume: bool = False,
    progress: bool = True,
    backend_options: dict[str, Any] | None = None,
    trust_pickle: bool = False,
    log: Callable[[str], None] | None = print,
    names: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """Run (or resume) ``config``'s benchmark in ``out_dir`` (created; locked for the run) and write its files;
    returns the summary. ``workers``, ``backend``, ``resume``, ``progress`` and ``trust_pickle`` are the
    :data:`~electroloc_gym.bench.config.RUN_OPTIONS` of those names; ``backend_options``: the backend's own
    (e.g. a Ray address); ``log``: where one-line notes go (None: silent); ``names``: how its messages name the
    settings (:func:`~electroloc_gym.options.message_names`; None: as Python spells them, ``resume=True``).

    Raises:
        ValueError: a bad output folder, a folder in use by another run, bad agents, an existing
            run without ``resume``, a stored run whose seed or settings differ, or a kept run's
            ``trials.jsonl.gz`` in the folder (read by the reports, never appended to).
    """
    from electroloc_gym.bench.stats import summarize

    log = log if log is not None else (lambda line: None)
    names = message_words(message_names(BENCH_OPTIONS, lambda opt: opt.name), names)
    described, warnings = _check_agents(config, trust_pickle)  # before the folder is touched: nothing written
    packed = check_output_folder(names["out"], out_dir) / TRIALS_GZ_FILE
    if packed.is_file():  # a kept run stored compressed is read, never appended to; nothing is written
        raise ValueError(
            f"{packed} holds a kept run's trials (compressed); gunzip it to continue that run, or choose another "
            f"{names['out']}"
        )
    out = prepare_out_dir(out_dir, names["out"])
    with run_lock(out, names["out"]):
        log(described)
        for line in warnings:
            log(line)
        trials_path, config_path = out / TRIALS_FILE, out / "config.json"
        stored: dict[str, Any] | None = None
        loaded = LoadedRecords(trials_path)
        if trials_path.exists() and trials_path.stat().st_size > 0:
            if not resume:
                raise ValueError(
                    f"{trials_path} already holds trials; pass {names['resume']} to continue that run or choose "
                    f"another {names['out']}"
                )
            loaded, stored = _resume(config, out, log, trust_pickle, names)
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
        cost = {name: agent_class(name).cost_rank for name in AGENT_NAMES}
        specs.sort(key=lambda s: -cost.get(s.agent, BaselineAgent.cost_rank))
        log(
            f"electroloc bench: {len(config.agents)} agents × {len(config.conditions)} conditions × "
            f"{config.trials} trials; {len(records)} already done, {len(specs)} to run on backend {be.name!r} "
            f"with {be.workers} worker(s) → {out}"
        )
        t0 = time.perf_counter()
        bar = TrialProgress(len(specs), be.workers, enabled=progress)
        done_before = len(records)
        try:
            with RecordWriter(trials_path) as writer:
                for spec, rec in be.run_trials(specs, run_trial):
                    writer.write(rec)
                    records[spec.key] = rec
                    bar.update(rec)
        except (TrialFailed, WorkerLost) as exc:
            what = str(exc) if isinstance(exc, TrialFailed) else _lost_text(exc)
            raise ValueError(
                f"{what}; the {len(records)} finished trial(s) ({len(records) - done_before} this time) "
                f"are kept in {trials_path}: fix the agent, then run again with {names['resume']}"
            ) from None
        finally:
            bar.close()
        wall = time.perf_counter() - t0

        wanted = [
            r for (c, a, k), r in records.items() if c in config.conditions and a in config.agents and k < config.trials
        ]
        summary = summarize(wanted, agents=list(config.agents), conditions=list(config.conditions))
        summary["config"] = asdict(config)
        summary["wall_s_this_run"] = wall
        summary["trials_run_this_time"] = len(specs)
        _write_outputs(out, summary)
    log(f"{len(specs)} trials in {wall:.1f} s; wrote {trials_path}, {', '.join(OUTPUT_FILES)}")
    return summary
