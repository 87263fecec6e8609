"""The benchmark runner: agents × conditions × seeded trials → trials.jsonl, summary.json, table.md, steps.png.

Protocol (paper §5.4, Appendix B): every agent runs ``trials`` trials per condition. Trial ``k`` of
condition ``c`` gets its seeds from ``numpy.random.SeedSequence(seed).spawn(...)`` indexed by
(condition, trial) — i.e. ``SeedSequence(seed, spawn_key=(preset index of c, k))`` — so

* every agent in a condition starts from the same seeded start position and sees the same noise
  stream (the paper did this for its two probabilistic controllers), and
* results depend neither on the worker count, nor on the backend, nor on which other agents or
  conditions are in the run.

Steps-to-localize is the number of observations fused (``info["n_observations"]``, the first
reading taken by ``reset`` included), as the paper counts. A trial succeeds when the env terminates
with √trace Σ ≤ 10 mm within 35 observations; an agent that ends trials itself (zero-crossing)
succeeds when it reports an estimate within its observation budget.

Output (in ``out_dir``): ``trials.jsonl`` gets one line per finished trial, appended, flushed and
fsync'ed at once (a killed run loses no finished trial; ``resume=True`` skips the trials already
there); ``config.json``, ``summary.json``, ``table.md`` and ``steps.png`` are written atomically.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from electroloc_gym.bench.backends import make_backend
from electroloc_gym.conditions import PRESET_NAMES, SIGNAL_CHOICES, get_condition
from electroloc_gym.fileio import atomic_write_text

__all__ = [
    "BenchConfig",
    "TrialSpec",
    "trial_seeds",
    "make_trial_specs",
    "run_trial",
    "run_benchmark",
    "read_trials",
    "write_json_atomic",
    "write_text_atomic",
    "DEFAULT_AGENTS",
    "discover_models",
    "resolve_conditions",
]

#: The paper's three controllers.
DEFAULT_AGENTS: tuple[str, ...] = ("rnd-wlk", "min-var", "zero-crossing")
SENSOR_MODELS = ("calibrated", "analytic")
SIGNALS = SIGNAL_CHOICES
#: Keys of a trial record that vary run to run (timings); everything else is deterministic.
TIMING_KEYS = ("decision_ms_median", "decision_ms_mean", "wall_s")
# The bench owns these env kwargs; an agent's env_kwargs cannot override them.
_BENCH_ONLY_KWARGS = ("condition", "signal", "randomize_target", "render_mode")
#: Global self-localisation (paper §6.5, Table 2): one fixed map, run as the single "condition"
#: GLOBAL_CONDITION (the map's name, = info["condition"]); its trial seeds use condition index 8.
GLOBAL_ENV_ID = "ElectroLocGlobal-v0"
GLOBAL_CONDITION = "six-cylinders"


@dataclass(frozen=True)
class BenchConfig:
    """What a benchmark run is (stored in ``config.json``; ``--resume`` checks it).

    Attributes:
        agents: agent specs (names, ``name[opts]`` or policy paths).
        conditions: preset names.
        trials: trials per condition and agent.
        seed: root seed of the trial seeds.
        sensor_model: the filter's sensor model, "calibrated" (the paper's) or "analytic".
        signal: "fitted" (presets' signal scale fitted to Table 3), "paper" (scale 1) or "coverage"
            (fitted × one factor matching the paper's §6.3 start coverage; see conditions.get_condition).
        max_observations: observation cap of a trial (paper: 35).
        n_particles: particles of the belief (paper: 2500).
        env_id: the environment id.
    """

    agents: tuple[str, ...] = DEFAULT_AGENTS
    conditions: tuple[str, ...] = PRESET_NAMES
    trials: int = 50
    seed: int = 0
    sensor_model: str = "calibrated"
    signal: str = "fitted"
    max_observations: int = 35
    n_particles: int = 2500
    env_id: str = "ElectroLoc-v0"

    def __post_init__(self) -> None:
        if not self.agents:
            raise ValueError("agents must name at least one agent")
        if len(set(self.agents)) != len(self.agents):
            raise ValueError(f"agents must be distinct, got {list(self.agents)}")
        if self.env_id == GLOBAL_ENV_ID:  # one map, no presets (signal does not apply)
            object.__setattr__(self, "conditions", (GLOBAL_CONDITION,))
        else:
            object.__setattr__(self, "conditions", tuple(resolve_conditions(list(self.conditions))))
        for name, val, low in (("trials", self.trials, 1), ("seed", self.seed, 0),
                               ("max_observations", self.max_observations, 1), ("n_particles", self.n_particles, 1)):
            if isinstance(val, bool) or not isinstance(val, int) or val < low:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {val!r}")
        if self.sensor_model not in SENSOR_MODELS:
            raise ValueError(f"sensor_model must be one of {list(SENSOR_MODELS)}, got {self.sensor_model!r}")
        if self.signal not in SIGNALS:
            raise ValueError(f"signal must be one of {list(SIGNALS)}, got {self.signal!r}")

    def identity(self) -> dict[str, Any]:
        """The fields that must match for ``--resume`` to append to an existing run."""
        return {k: getattr(self, k) for k in ("seed", "sensor_model", "signal", "max_observations", "n_particles",
                                              "env_id")}


@dataclass(frozen=True)
class TrialSpec:
    """One trial, self-contained and picklable (what a worker receives)."""

    condition: str
    agent: str
    trial: int
    env_seed: int
    agent_seed: int
    sensor_model: str
    signal: str
    max_observations: int
    n_particles: int
    env_id: str = "ElectroLoc-v0"
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def key(self) -> tuple[str, str, int]:
        """(condition, agent, trial): the identity of a trial in trials.jsonl."""
        return (self.condition, self.agent, self.trial)


def resolve_conditions(spec: str | Sequence[str]) -> list[str]:
    """``"all"`` or comma-separated preset names → list of preset names (validated).

    Raises:
        ValueError: unknown or repeated condition names (the message lists the valid ones).
    """
    names = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else [str(s).strip() for s in spec]
    if names == ["all"]:
        return list(PRESET_NAMES)
    if not names or any(not n for n in names):
        raise ValueError(f"conditions must be 'all' or comma-separated names from {list(PRESET_NAMES)}, got {spec!r}")
    bad = [n for n in names if n not in PRESET_NAMES]
    if bad:
        raise ValueError(f"unknown condition(s) {bad}; choose 'all' or names from {list(PRESET_NAMES)}")
    if len(set(names)) != len(names):
        raise ValueError(f"conditions must be distinct, got {names}")
    return names


def trial_seeds(seed: int, condition: str, trial: int) -> tuple[int, int]:
    """(env seed, agent seed) of trial ``trial`` of ``condition``.

    ``SeedSequence(seed, spawn_key=(i, trial))`` is exactly ``SeedSequence(seed).spawn(n)[i].spawn(m)[trial]``
    with ``i`` the condition's index among the presets: independent of the run's other conditions,
    agents, trial count and workers.
    """
    index = len(PRESET_NAMES) if condition == GLOBAL_CONDITION else PRESET_NAMES.index(condition)
    ss = np.random.SeedSequence(seed, spawn_key=(index, trial))
    env_seed, agent_seed = (int(v) for v in ss.generate_state(2, dtype=np.uint32))
    return env_seed, agent_seed


def make_trial_specs(config: BenchConfig) -> list[TrialSpec]:
    """All trials of a run, condition-major."""
    specs = []
    for cond in config.conditions:
        for k in range(config.trials):
            env_seed, agent_seed = trial_seeds(config.seed, cond, k)
            for agent in config.agents:
                specs.append(TrialSpec(cond, agent, k, env_seed, agent_seed, config.sensor_model, config.signal,
                                       config.max_observations, config.n_particles, config.env_id))
    return specs


# ---------------------------------------------------------------------------------------------
# The worker side
# ---------------------------------------------------------------------------------------------
_AGENTS: dict[str, Any] = {}
_ENVS: dict[tuple[Any, ...], Any] = {}


def _agent(spec: str) -> Any:
    if spec not in _AGENTS:
        from electroloc_gym.baselines.agent import make_agent

        _AGENTS[spec] = make_agent(spec)
    return _AGENTS[spec]


def _env(spec: TrialSpec, agent: Any) -> Any:
    import gymnasium as gym

    import electroloc_gym  # noqa: F401  (registers the ids in a fresh worker)

    kwargs: dict[str, Any] = {"sensor_model": spec.sensor_model, "n_particles": spec.n_particles,
                              "max_observations": spec.max_observations}
    if spec.env_id != GLOBAL_ENV_ID:  # the global env has one fixed map and no condition kwarg
        condition = get_condition(spec.condition, spec.signal)
        adapt = getattr(agent, "adapt_condition", None)
        if callable(adapt):
            condition = adapt(condition)
        kwargs["condition"] = condition
    kwargs.update({k: v for k, v in dict(getattr(agent, "env_kwargs", {}) or {}).items()
                   if k not in _BENCH_ONLY_KWARGS})
    key = (spec.env_id, spec.condition, spec.signal, spec.agent, repr(sorted(kwargs.items(), key=lambda kv: kv[0])))
    if key not in _ENVS:
        if len(_ENVS) > 16:
            for env in _ENVS.values():
                env.close()
            _ENVS.clear()
        _ENVS[key] = gym.make(spec.env_id, **kwargs)
    return _ENVS[key]


def _finite_or_none(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def run_trial(spec: TrialSpec) -> dict[str, Any]:
    """Run one trial and return its record (the worker function of every backend)."""
    t_start = time.perf_counter()
    agent = _agent(spec.agent)
    env = _env(spec, agent)
    obs, info = env.reset(seed=spec.env_seed)
    if hasattr(agent, "seed"):
        agent.seed(spec.agent_seed)
    agent.reset(env)
    start = info["position_mm"]
    state = None
    episode_start = np.ones((1,), dtype=bool)
    decision_s: list[float] = []
    terminated = truncated = False
    ended_by = "cap"
    while True:
        t0 = time.perf_counter()
        action, state = agent.predict(obs, state=state, episode_start=episode_start, deterministic=True)
        decision_s.append(time.perf_counter() - t0)
        episode_start = np.zeros((1,), dtype=bool)
        if getattr(agent, "done", False):
            ended_by = "agent"
            break
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            ended_by = "success" if terminated else "cap"
            break
    core = env.unwrapped
    if spec.env_id == GLOBAL_ENV_ID:  # the hidden state is the robot's own (final) position
        target = np.asarray(info["position_mm"], dtype=float)  # evaluation only
    else:
        target = np.asarray(core.condition.target_xy_mm, dtype=float)  # evaluation only
    self_ending = ended_by == "agent" or getattr(agent, "layout", "table4") == "table1"
    if self_ending:
        est = getattr(agent, "estimate_mm", None)
        success = bool(ended_by == "agent" and est is not None)
        estimate = None if est is None else [float(est[0]), float(est[1])]
    else:
        success = bool(terminated and info["success"])
        estimate = [float(info["estimate_mm"][0]), float(info["estimate_mm"][1])]
    if estimate is not None:
        err_xy = np.asarray(estimate) - target
        error = float(np.hypot(*err_xy))
        error_x, error_y = float(err_xy[0]), float(err_xy[1])
    else:
        error = error_x = error_y = None
    dms = np.asarray(decision_s) * 1e3
    return {
        "condition": spec.condition,
        "agent": spec.agent,
        "agent_label": str(getattr(agent, "name", spec.agent)),
        "layout": str(getattr(agent, "layout", "table4")),
        "trial": spec.trial,
        "seed": spec.env_seed,
        "agent_seed": spec.agent_seed,
        "success": success,
        "ended_by": ended_by,
        "observations": int(info["n_observations"]),
        "error_mm": _finite_or_none(error),
        "error_x_mm": _finite_or_none(error_x),
        "error_y_mm": _finite_or_none(error_y),
        "estimate": estimate,
        "target": [float(target[0]), float(target[1])],
        "start": [float(start[0]), float(start[1])],
        "spread_mm": _finite_or_none(info.get("spread_mm")),
        "decisions": int(dms.size),
        "decision_ms_median": float(np.median(dms)) if dms.size else None,
        "decision_ms_mean": float(np.mean(dms)) if dms.size else None,
        "sensor_model": spec.sensor_model,
        "signal": spec.signal,
        "wall_s": time.perf_counter() - t_start,
    }


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------
def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`electroloc_gym.fileio.atomic_write_text`)."""
    atomic_write_text(path, text)


def write_json_atomic(path: str | os.PathLike, obj: Any) -> None:
    """JSON-dump ``obj`` to ``path`` atomically."""
    write_text_atomic(path, json.dumps(obj, indent=2, allow_nan=False) + "\n")


def read_trials(path: str | os.PathLike, repair: bool = False) -> list[dict[str, Any]]:
    """Records of a trials.jsonl; a torn last line (a run killed mid-write) is skipped.

    Args:
        path: the file (missing: no records).
        repair: rewrite the file atomically without unparsable lines, so appends stay line-aligned.
    """
    path = Path(path)
    if not path.exists():
        return []
    records, bad = [], 0
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                bad += 1
                continue
            if isinstance(rec, dict) and {"condition", "agent", "trial"} <= rec.keys():
                records.append(rec)
            else:
                bad += 1
    if repair and bad:
        write_text_atomic(path, "".join(json.dumps(r) + "\n" for r in records))
    return records


def discover_models(roots: Sequence[str | os.PathLike] | None = None) -> list[str]:
    """Shipped learned policies: ``models/*/model.zip`` under the working directory or the repository.

    Returns the directories (as agent specs) — empty when there is no ``models/`` folder, no
    ``model.zip`` in it, or the training extra (stable-baselines3) is not installed.
    """
    import importlib.util

    if roots is None:
        roots = [Path.cwd() / "models", Path(__file__).resolve().parents[2] / "models"]
    found: list[str] = []
    seen: set[Path] = set()
    for root in roots:
        root = Path(root)
        if not root.is_dir():
            continue
        for zip_path in sorted(root.glob("*/model.zip")):
            folder = zip_path.parent.resolve()
            if folder not in seen:
                seen.add(folder)
                found.append(str(zip_path.parent))
    if found:
        try:
            ok = importlib.util.find_spec("stable_baselines3") is not None and \
                importlib.util.find_spec("electroloc_gym.train.policy") is not None
        except (ImportError, ValueError):
            ok = False
        if not ok:
            return []
    return found


# ---------------------------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------------------------
def _check_agents(agents: Sequence[str]) -> None:
    """Fail fast (before any worker starts) on bad agent names or paths."""
    from electroloc_gym.baselines.agent import make_agent

    for spec in agents:
        make_agent(spec)


def run_benchmark(config: BenchConfig, out_dir: str | os.PathLike, *, workers: int | None = None,
                  backend: str = "process", resume: bool = False, progress: bool = True,
                  backend_options: dict[str, Any] | None = None,
                  log: Callable[[str], None] | None = print) -> dict[str, Any]:
    """Run (or resume) a benchmark and write its files; returns the summary.

    Args:
        config: the run.
        out_dir: output directory (created).
        workers: parallel workers (None: all cores).
        backend: backend name (:data:`electroloc_gym.bench.backends.BACKENDS`).
        resume: skip trials already in ``out_dir/trials.jsonl``; without it an existing non-empty
            trials.jsonl is an error (never silently mixed).
        progress: show a tqdm progress bar.
        backend_options: extra options for the backend (e.g. a Ray address).
        log: where to print one-line notes (None: silent).

    Raises:
        ValueError: bad agents / conditions, an existing run without ``resume``, or a resumed run
            whose seed / sensor model / signal / cap / particles differ.
    """
    from electroloc_gym.bench.plots import plot_steps
    from electroloc_gym.bench.stats import summarize
    from electroloc_gym.bench.tables import render_table_md

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    trials_path = out / "trials.jsonl"
    config_path = out / "config.json"
    _check_agents(config.agents)
    be = make_backend(backend, workers, **(backend_options or {}))

    existing: list[dict[str, Any]] = []
    if trials_path.exists() and trials_path.stat().st_size > 0:
        if not resume:
            raise ValueError(f"{trials_path} already holds trials; pass resume=True (--resume) to continue that run "
                             f"or choose another output directory")
        if config_path.exists():
            stored = json.loads(config_path.read_text())
            mismatch = {k: (stored.get(k), v) for k, v in config.identity().items() if stored.get(k) != v}
            if mismatch:
                raise ValueError(f"cannot resume {out}: settings differ from the stored run (stored, now): {mismatch}")
        existing = read_trials(trials_path, repair=True)
    stored_cfg = asdict(config)
    if resume and config_path.exists():  # remember the union of what was ever asked for
        old = json.loads(config_path.read_text())
        stored_cfg["agents"] = list(dict.fromkeys([*old.get("agents", []), *config.agents]))
        stored_cfg["conditions"] = list(dict.fromkeys([*old.get("conditions", []), *config.conditions]))
        stored_cfg["trials"] = max(int(old.get("trials", 0)), config.trials)
    write_json_atomic(config_path, stored_cfg)

    done = {(r["condition"], r["agent"], int(r["trial"])) for r in existing}
    specs = [s for s in make_trial_specs(config) if s.key not in done]
    # Longest jobs first (min-var, learned policies), so the pool's tail is short.
    cost = {"rnd-wlk": 0, "zero-crossing": 1}
    specs.sort(key=lambda s: -cost.get(s.agent, 2))
    if log is not None:
        log(f"electroloc bench: {len(config.agents)} agents × {len(config.conditions)} conditions × {config.trials} "
            f"trials; {len(done)} already done, {len(specs)} to run on backend {be.name!r} with {be.workers} "
            f"worker(s) → {out}")
    t0 = time.perf_counter()
    bar = None
    if progress and specs:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(specs), desc="trials", unit="trial", dynamic_ncols=True)
    try:
        with open(trials_path, "a", encoding="utf-8") as f:
            for _, rec in be.run_trials(specs, run_trial):
                f.write(json.dumps(rec, allow_nan=False) + "\n")
                f.flush()
                os.fsync(f.fileno())
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix_str(f"{rec['agent'][:14]} {rec['condition']}", refresh=False)
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0

    wanted = {(c, a) for c in config.conditions for a in config.agents}
    records = [r for r in read_trials(trials_path) if (r["condition"], r["agent"]) in wanted
               and int(r["trial"]) < config.trials]
    summary = summarize(records, agents=list(config.agents), conditions=list(config.conditions))
    summary["config"] = asdict(config)
    summary["wall_s_this_run"] = wall
    summary["trials_run_this_time"] = len(specs)
    write_json_atomic(out / "summary.json", summary)
    write_text_atomic(out / "table.md", render_table_md(summary))
    plot_steps(summary, out / "steps.png")
    if log is not None:
        log(f"{len(specs)} trials in {wall:.1f} s; wrote {trials_path}, summary.json, table.md, steps.png")
    return summary
