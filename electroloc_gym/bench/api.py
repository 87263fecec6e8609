"""The benchmark from Python: :func:`run` takes agent objects or specs and returns the summary and table.

::

    from electroloc_gym.bench import run

    result = run(agents=[my_policy, "min-var"], conditions="fresh-steel-12.7", trials=5, seed=0)
    print(result.table)                      # the same table.md as ``electroloc bench``
    result.summary["rows"]                   # the same rows as summary.json

An agent object is anything with the agent protocol — ``reset(env)`` and
``predict(obs, state=None, episode_start=None, deterministic=True) -> (action, state)`` — and runs
under its ``name`` attribute (else its class name). Agent objects live in this process, so a run
with objects uses the serial backend (a process pool would need them pickled and rebuilt in every
worker; a spec — ``package.module:factory[...]`` — runs on any backend, since each worker builds it).
"""

from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.rollout import AgentCallError
from electroloc_gym.bench.agents import PluginAgent, register_object_agent, shipped_models
from electroloc_gym.bench.config import ENV_CHOICES, BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.world.conditions import DEFAULT_SIGNAL

__all__ = ["run", "BenchResult"]


@dataclass(frozen=True)
class BenchResult:
    """What :func:`run` returns.

    Attributes:
        summary: the run's summary (summary.json).
        table: the run's tables (table.md, Markdown).
        out: the folder holding trials.jsonl, summary.json, table.md and steps.png.
    """

    summary: dict[str, Any]
    table: str
    out: Path


def _object_name(agent: Any, taken: set[str]) -> str:
    try:
        raw = str(PluginAgent(agent).name)
    except AttributeError:  # no name: its class's
        raw = ""
    except AgentCallError as exc:
        raise ValueError(f"agent object {type(agent).__name__}: {exc}") from None
    raw = raw or type(agent).__name__
    base = re.sub(r"[^A-Za-z0-9_\-]+", "-", raw).strip("-") or "agent"
    name, k = base, 2
    while name in taken:
        name, k = f"{base}-{k}", k + 1
    return name


def _check_agents(agents: object) -> None:
    """``run``'s ``agents``: a non-empty list (or tuple), else a ValueError."""
    if not isinstance(agents, (list, tuple)) or not agents:
        raise ValueError(f"agents must be a non-empty list of agent objects or specs, got {agents!r}")


def run(
    agents: list[Any],
    *,
    env: str = "target",
    conditions: str | list[str] = "all",
    trials: int = 50,
    seed: int = 0,
    out: str | os.PathLike[str] | None = None,
    sensor_model: str | None = None,
    signal: str = DEFAULT_SIGNAL,
    max_observations: int | None = None,
    n_particles: int | None = None,
    backend: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = False,
    trust_pickle: bool = False,
    log: Any = None,
) -> BenchResult:
    """Benchmark ``agents`` (objects and/or specs) as ``electroloc bench`` does.

    Args:
        agents: agent objects (the agent protocol) and/or agent specs (strings, as ``--agents`` takes).
        env: ``"target"``, ``"global"``, ``"unknown-target"`` or ``"dynamic-gain"`` (``--env``).
        conditions: ``"all"``, comma-separated preset names, or a list of them.
        trials: trials per condition and agent.
        seed: root seed of the per-trial seeds.
        out: output folder (None: a new temporary folder).
        sensor_model: the filter's sensor model (None: the env's default).
        signal: the presets' signal scale.
        max_observations: the cap of readings of a trial (None: the env's, 35 as the paper).
        n_particles: particles of the belief (None: the env's default).
        backend: ``"serial"``, ``"process"``, ``"ray"`` (None: serial with agent objects, else process).
        workers: parallel workers of the backend.
        resume: continue the run in ``out``.
        progress: show a progress bar.
        trust_pickle: allow learned policies stored as a bare SB3 zip.
        log: where one-line notes go (None: silent; ``print`` to see them).

    Raises:
        ValueError: a bad argument, an object without the agent protocol, a non-serial ``backend``
            with agent objects, or anything ``electroloc bench`` refuses.
    """
    _check_agents(agents)
    if env not in ENV_CHOICES:
        raise ValueError(f"env must be one of {list(ENV_CHOICES)}, got {env!r}")
    taken = {a for a in agents if isinstance(a, str)} | set(shipped_models())
    specs: list[str] = []
    objects = False
    for agent in agents:
        if isinstance(agent, str):
            specs.append(agent.strip())
            continue
        name = _object_name(agent, taken)
        taken.add(name)
        register_object_agent(name, agent)
        specs.append(name)
        objects = True
    if backend is None:
        backend = "serial" if objects else "process"
    elif objects and backend != "serial":
        raise ValueError(
            f"agent objects run in this process, so backend must be 'serial' (got {backend!r}); "
            f"pass a spec (package.module:factory[...]) to run on {backend!r}"
        )
    config = BenchConfig.build(
        specs,
        env=env,
        conditions=conditions,
        trials=trials,
        seed=seed,
        sensor_model=sensor_model,
        signal=signal,
        max_observations=max_observations,
        n_particles=n_particles,
    )
    folder = Path(tempfile.mkdtemp(prefix="electroloc-bench-")) if out is None else Path(out)
    summary = run_benchmark(
        config,
        folder,
        workers=workers,
        backend=backend,
        resume=resume,
        progress=progress,
        trust_pickle=trust_pickle,
        log=log,
    )
    return BenchResult(summary=summary, table=(folder / "table.md").read_text(encoding="utf-8"), out=folder)
