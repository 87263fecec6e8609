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

import inspect
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.agent import AGENT_NAMES
from electroloc_gym.baselines.rollout import AgentCallError
from electroloc_gym.bench.agents import (
    PluginAgent,
    agent_kind,
    cached_agent,
    policy_meta,
    register_object_agent,
    shipped_model_env,
    shipped_models,
)
from electroloc_gym.bench.config import BENCH_OPTIONS, CONFIG_OPTIONS, BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.options import Option, SettingError, api_signature, message_names
from electroloc_gym.registry import BENCH_ENVS, bench_env, resolve_env_name
from electroloc_gym.utils.agentspec import split_specs
from electroloc_gym.utils.fileio import user_path

__all__ = ["run", "BenchResult", "prepare"]


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


def _runs_on_map_env(spec: str, env_id: str) -> bool:
    """On an env of one fixed map: a particle-filter controller, a user's factory agent, or a policy (shipped
    or a path) trained on that env.
    """
    kind = agent_kind(spec)
    if kind == "baseline":
        return getattr(cached_agent(spec), "table_layout", "table4") == "table4"
    if kind == "shipped":
        return shipped_model_env(shipped_models()[spec]) == (env_id, None)
    if kind == "path":  # a policy.json its schema accepted holds observation.env_id
        meta = policy_meta(spec)
        return meta is not None and meta["observation"]["env_id"] == env_id
    return kind in ("factory", "object")


def _agent_specs(agents: Any, values: dict[str, Any], note: Callable[[str], None]) -> tuple[list[str], bool]:
    """The run's agent specs and whether an agent is an object (registered here under a free name)."""
    from electroloc_gym.bench.default_run import default_agents

    if isinstance(agents, str):
        return split_specs(agents), False
    if agents is not None:
        taken = {a for a in agents if isinstance(a, str)} | set(shipped_models()) | set(AGENT_NAMES)
        specs: list[str] = []
        for agent in agents:
            if isinstance(agent, str):
                specs.append(agent.strip())
                continue
            name = _object_name(agent, taken)
            taken.add(name)
            register_object_agent(name, agent)
            specs.append(name)
        return specs, len(specs) > sum(isinstance(a, str) for a in agents)
    entry, row = bench_env(values["env"])
    choices = default_agents(
        names=row.agents,
        trust_pickle=values["trust_pickle"],
        env_id=entry.env_id,
        gain_levels=row.env_kwargs.get("gain_levels"),
        sensor_layout=values["sensor_layout"],
    )
    elsewhere = [f"{c.spec} ({c.runs_with})" for c in choices if c.skipped and c.runs_with]
    if elsewhere:  # expected, not a warning: the policy belongs to another run
        note(f"the shipped policies trained for other settings run there: {', '.join(elsewhere)}")
    for c in choices:
        if c.skipped and not c.runs_with:
            note(f"skipping {c.spec}: {c.skipped}")
    return [c.spec for c in choices if not c.skipped], False


def prepare(
    values: dict[str, Any], spell: Callable[[Option], str], note: Callable[[str], None]
) -> tuple[BenchConfig, dict[str, Any]]:
    """The run ``values`` (every :data:`~electroloc_gym.bench.config.BENCH_OPTIONS` setting) describe, checked
    before anything is written: its :class:`BenchConfig` and :func:`run_benchmark`'s keywords. Both front
    ends run it; a refused setting is named as ``spell`` spells its option (``--max-observations`` or
    ``max_observations``), and so are the settings the run's messages name; ``note`` gets what a default agent
    list skipped, once the settings are valid.

    Raises:
        ValueError: one line naming the setting.
    """
    name = {opt.name: spell(opt) for opt in BENCH_OPTIONS}
    values = {**values, "env": resolve_env_name(values["env"], name["env"])}  # MODULE:NAME imports MODULE
    for opt in BENCH_OPTIONS:
        values[opt.name] = opt.check_value(name[opt.name], values[opt.name])
    env, backend = values["env"], values["backend"]
    if values["address"] is not None and backend != "ray":
        raise ValueError(
            f"{name['address']} applies to {name['backend']} ray only (got {name['backend']} {backend or 'process'})"
        )
    ray_names = {k: name[k] for k in ("backend", "address")}  # how the Ray backend's refusals name them
    if backend == "ray":  # Ray installed and the cluster reachable, before the output folder is touched
        from electroloc_gym.bench.ray_backend import check_ray_address

        check_ray_address(values["address"], ray_names)
    notes: list[str] = []
    specs, objects = _agent_specs(values["agents"], values, notes.append)
    if not specs:  # every default skipped: the notes say why
        for line in notes:
            note(line)
        raise ValueError(f"{name['agents']} names no agent")
    layout_rows = [n for n, (e, r) in BENCH_ENVS.items() if e.takes("sensor_layout") and not r.env_kwargs]
    if values["sensor_layout"] is not None and env not in layout_rows:
        raise ValueError(
            f"{name['sensor_layout']} applies to {name['env']} {' or '.join(layout_rows)}, got {name['env']} {env}"
        )
    try:
        config = BenchConfig.build(
            specs, env=env, **{o.name: values[o.name] for o in CONFIG_OPTIONS if o.name != "agents"}
        )
    except SettingError as exc:
        raise ValueError(f"{name.get(exc.setting, exc.setting)} must be {exc.allowed}, got {exc.got!r}") from None
    for line in notes:
        note(line)
    entry = bench_env(env)[0]
    if entry.map_condition is not None:  # zero-crossing looks for one sphere; a policy must know the map
        bad = [a for a in specs if not _runs_on_map_env(a, entry.env_id)]
        if bad:
            raise ValueError(
                f"{name['env']} {env} runs the particle-filter controllers (Table 2), policies "
                f"trained on {entry.env_id} and users' factory agents; not applicable: {bad}"
            )
    if backend is None:
        backend = "serial" if objects else "process"
    elif objects and backend != "serial":
        raise ValueError(
            f"agent objects run in this process, so backend must be 'serial' (got {backend!r}); "
            f"pass a spec (package.module:factory[...]) to run on {backend!r}"
        )
    run_options = {k: values[k] for k in ("workers", "resume", "progress", "trust_pickle")}
    options = {"address": values["address"], "names": ray_names} if backend == "ray" else {}
    names = message_names(BENCH_OPTIONS, spell)
    return config, {**run_options, "backend": backend, "backend_options": options, "names": names}


def run(agents: Any = None, **settings: Any) -> BenchResult:
    """Benchmark ``agents`` (objects and/or specs) as ``electroloc bench`` does.

    ``agents``: agent objects (the agent protocol) and/or agent specs (strings, as ``--agents`` takes), a
    comma-separated string of specs, or None: the command's default set. Every other keyword is an option
    of ``electroloc bench`` (:data:`~electroloc_gym.bench.config.BENCH_OPTIONS`: the same names, checks and
    defaults, except ``out``: None, a new temporary folder, and ``progress``: False), and ``log``: where
    one-line notes go (None: silent; ``print`` to see them). The signature lists them.

    Raises:
        ValueError: a bad argument (one line naming it), an object without the agent protocol, a non-serial
            ``backend`` with agent objects, or anything ``electroloc bench`` refuses.
        TypeError: a keyword that is no setting.
    """
    log = settings.pop("log", None)
    unknown = sorted(set(settings) - {o.name for o in BENCH_OPTIONS} - {"agents"})
    if unknown:
        raise TypeError(f"run() got unexpected keyword(s) {unknown}")
    values = {o.name: settings.get(o.name, o.api_default) for o in BENCH_OPTIONS}
    values["agents"] = agents
    config, options = prepare(values, lambda opt: opt.name, log or (lambda line: None))
    out = values["out"]
    folder = Path(tempfile.mkdtemp(prefix="electroloc-bench-")) if out is None else user_path(out)
    summary = run_benchmark(config, folder, **options, log=log)
    return BenchResult(summary=summary, table=(folder / "table.md").read_text(encoding="utf-8"), out=folder)


run.__signature__ = api_signature(
    [o for o in BENCH_OPTIONS if o.name != "agents"],
    inspect.Parameter("agents", inspect.Parameter.POSITIONAL_OR_KEYWORD, default=None),
    last=[inspect.Parameter("log", inspect.Parameter.KEYWORD_ONLY, default=None)],
)
