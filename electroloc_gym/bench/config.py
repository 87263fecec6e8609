"""What a benchmark run is: its settings (:class:`BenchConfig`), its trials (:class:`TrialSpec`), their seeds.

Every setting of ``electroloc bench`` is declared once, here: a :class:`BenchConfig` field (what the run is,
stored in ``config.json``) or a :data:`RUN_OPTIONS` entry (how and where it runs), each with its
:class:`~electroloc_gym.options.Option` — flag, help, check, the front ends' default. The command's parser,
the Python API's keywords (:func:`electroloc_gym.bench.run`), their checks (one message, spelled with each
front end's name) and ``config.json`` (the fields) all come from :data:`BENCH_OPTIONS`.

A run's settings are one object, built and validated once (:meth:`BenchConfig.build`, from the command
line or from Python; the defaults read from the env table there) and carried unchanged: stored in
``config.json``, held by every :class:`TrialSpec`, written into every record
(:meth:`BenchConfig.record_settings`), and the only source of a trial env's ``gym.make`` kwargs
(:meth:`BenchConfig.env_kwargs`).

Protocol (paper §5.4, Appendix B): every agent runs ``trials`` trials per condition. Trial ``k`` of
condition ``c`` gets its seeds from ``numpy.random.SeedSequence(seed).spawn(...)`` indexed by
(condition, trial) — i.e. ``SeedSequence(seed, spawn_key=(preset index of c, k))`` — so

* every agent in a condition starts from the same seeded start position and sees the same noise
  stream (the paper did this for its two probabilistic controllers), and
* results depend neither on the worker count, nor on the backend, nor on which other agents or
  conditions are in the run.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from electroloc_gym.baselines.agent import PAPER_AGENTS
from electroloc_gym.contract.params import MIN_OBSERVATION_CAP, EnvParams
from electroloc_gym.options import Option, SettingError, int_in, is_bool, one_of, options_of, setting
from electroloc_gym.protocol import MAX_OBSERVATIONS, N_PARTICLES, SUCCESS_SPREAD_MM
from electroloc_gym.registry import BENCH_ENVS, ENVS, PAPER_ENV_ID, LiveMapping, LiveSequence, bench_env, env_entry
from electroloc_gym.utils.fileio import check_output_folder
from electroloc_gym.world.conditions import DEFAULT_SIGNAL, PRESET_NAMES, SIGNAL_CHOICES
from electroloc_gym.world.distractors import MAX_DISTRACTORS
from electroloc_gym.world.sensor_array import LAYOUT_NAMES

__all__ = [
    "BenchConfig",
    "TrialSpec",
    "trial_seeds",
    "make_trial_specs",
    "resolve_conditions",
    "DEFAULT_AGENTS",
    "SENSOR_MODELS",
    "SIGNALS",
    "MAP_CONDITIONS",
    "run_conditions",
    "ENV_CHOICES",
    "ENV_SENSOR_MODELS",
    "ENV_N_PARTICLES",
    "ENV_DEFAULT_AGENTS",
    "ENV_MAX_OBSERVATIONS",
    "IDENTITY_KEYS",
    "IDENTITY_DEFAULTS",
    "ENV_TAKES_DISTRACTORS",
    "MAX_READINGS",
    "SettingError",
    "DEFAULT_ENV",
    "BENCH_OPTIONS",
    "CONFIG_OPTIONS",
    "RUN_OPTIONS",
    "MAX_TRIALS",
    "MAX_WORKERS",
    "MAX_PARTICLES",
    "MAX_PLANNED_TRIALS",
]

#: Most readings a trial may be capped at (``max_observations``): far beyond the paper's 35, short of a
#: trial that cannot run.
MAX_READINGS = 100_000
#: Bounds of the other numeric settings: far beyond the paper (50 trials, 2500 particles), short of what cannot run.
MAX_TRIALS = 100_000
MAX_WORKERS = 1024
MAX_PARTICLES = 1_000_000
#: Most trials a run plans (agents × conditions × trials; the plan is held in memory, ≈1 KB a trial).
MAX_PLANNED_TRIALS = 1_000_000

#: The paper's three controllers (the baselines' registry's :data:`~electroloc_gym.baselines.agent.PAPER_AGENTS`).
DEFAULT_AGENTS: tuple[str, ...] = PAPER_AGENTS
SIGNALS = SIGNAL_CHOICES
# The per-env settings below are read from the env table (electroloc_gym.registry), not declared here;
# they are live views, so an env registered later is in them.
#: ``electroloc bench --env`` names → environment ids (``dynamic-gain``: ElectroLoc-v0 with its row's
#: ``gain_levels``, the gain part of every action).
ENV_CHOICES: LiveMapping[str] = LiveMapping(lambda: {name: entry.env_id for name, (entry, _) in BENCH_ENVS.items()})
#: The ``--env`` row a run is on by default (its env id is :attr:`BenchConfig.env_id`'s default, read from the table).
DEFAULT_ENV = "target"
#: The bench's default particle count per env (the env's own default).
ENV_N_PARTICLES: LiveMapping[int] = LiveMapping(
    lambda: {e.env_id: e.defaults.get("n_particles", EnvParams.n_particles) for e in ENVS}
)
#: The bench's default cap of readings per env (the env's own default; the paper's 35).
ENV_MAX_OBSERVATIONS: LiveMapping[int] = LiveMapping(
    lambda: {e.env_id: e.defaults.get("max_observations", MAX_OBSERVATIONS) for e in ENVS}
)
#: The sensor models of each env (the first is the bench's default there).
ENV_SENSOR_MODELS: LiveMapping[tuple[str, ...]] = LiveMapping(lambda: {e.env_id: e.sensor_models for e in ENVS})
#: Every sensor model some env takes (``--sensor-model`` choices).
SENSOR_MODELS: LiveSequence[str] = LiveSequence(lambda: tuple(dict.fromkeys(m for e in ENVS for m in e.sensor_models)))
#: ``--env`` names → the default agents' names (None: every registered controller).
ENV_DEFAULT_AGENTS: LiveMapping[tuple[str, ...] | None] = LiveMapping(
    lambda: {name: bench.agents for name, (_, bench) in BENCH_ENVS.items()}
)
#: The single "conditions" of the envs with one fixed map (e.g. ElectroLocGlobal-v0's six-cylinder map,
#: paper §6.5, = env.unwrapped.condition.name); their trial seeds use condition index 8.
MAP_CONDITIONS: LiveSequence[str] = LiveSequence(
    lambda: tuple(dict.fromkeys(e.map_condition for e in ENVS if e.map_condition is not None))
)
#: Which envs take ``distractors=`` (``--distractors``).
ENV_TAKES_DISTRACTORS: LiveMapping[bool] = LiveMapping(lambda: {e.env_id: e.takes("distractors") for e in ENVS})
#: What an identity key missing from an older record or config means.
IDENTITY_DEFAULTS = {"distractors": 0, "success_spread_mm": SUCCESS_SPREAD_MM}
#: Settings every record of a run shares (stored in each record; ``--resume`` checks them).
IDENTITY_KEYS = (
    "sensor_model",
    "signal",
    "max_observations",
    "n_particles",
    "env_id",
    "gain_levels",
    "sensor_layout",
    "distractors",
)


def _bench_row(name: str, value: Any) -> None:
    """``env``: a bench row, or ``package.module:NAME`` (:func:`~electroloc_gym.registry.bench_env`, the one
    resolution of ``--env``: it imports the module).
    """
    try:
        bench_env(value)
    except ValueError as exc:
        raise ValueError(re.sub(r"^--env\b", name, str(exc))) from None


def _conditions(name: str, value: Any) -> None:
    if not isinstance(value, (str, list, tuple)):
        raise SettingError(name, "'all', comma-separated preset names or a list of them", value)
    resolve_conditions(value)


def _agents(name: str, value: Any) -> None:
    """``agents``: comma-separated specs (a string) or a list of specs and agent objects."""
    from electroloc_gym.bench.agents import agent_kind
    from electroloc_gym.utils.agentspec import split_specs

    if isinstance(value, str):
        try:
            specs = split_specs(value)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None
        if not any(specs):
            raise ValueError(f"{name} names no agent (got {value!r}); leave it out for the default set")
        if not all(specs):
            raise ValueError(f"{name} has an empty item in {value!r}")
    elif isinstance(value, (list, tuple)) and value:
        specs = [a.strip() for a in value if isinstance(a, str)]
    else:
        raise SettingError(name, "comma-separated agent specs or a non-empty list of specs and agent objects", value)
    for spec in specs:
        try:
            agent_kind(spec)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None


def _out_folder(name: str, value: Any) -> None:
    check_output_folder(name, value)  # the rule of every command's outputs, before any work


@dataclass(frozen=True)
class BenchConfig:
    """What a benchmark run is (stored in ``config.json``; ``--resume`` checks it).

    A field declared by :func:`~electroloc_gym.options.setting` is an option of ``electroloc bench``: its
    ``help`` says what it is (docs/benchmark.md lists them). The others:

    Attributes:
        env_id: the environment id (of the ``--env`` row).
        gain_levels: dynamic gain: the factors of the amplifier gain in the action (None: the preset gain).
        success_spread_mm: the success criterion, mm: a trial succeeds when the belief's spread √trace Σ is
            at most this (paper: 10 mm). With the cap, the particles, the sensor model, the signal, the
            layout and the distractors it is the run's protocol: fixed by the run for every agent (a
            plug-in agent's ``env_kwargs`` cannot change it) and compared by ``--resume``.
    """

    agents: tuple[str, ...] = setting(
        DEFAULT_AGENTS,
        default=None,
        check=_agents,
        bad=("", "nope", []),
        help=f"comma-separated agents: {', '.join(PAPER_AGENTS)}, NAME[key=value,...] "
        "(e.g. min-var[n_voters=2500]), a shipped model by name (e.g. ppo-belief), or a "
        "path to a model folder, or package.module:factory[key=value,...] (a factory of your "
        "own, imported like any module: it runs your code) (default: the --env row's controllers, "
        "the paper's three on the target, plus every shipped model trained for the run's settings that runs here; "
        "the run says which and why one is skipped)",
    )
    conditions: tuple[str, ...] = setting(
        PRESET_NAMES,
        default="all",
        check=_conditions,
        bad=("nope", "", 3),
        help="'all' or comma-separated preset names (an env of one fixed map, --env global, runs its map instead)",
    )
    trials: int = setting(
        50,
        kind="int",
        check=int_in(1, MAX_TRIALS),
        bad=(0, MAX_TRIALS + 1),
        help=f"trials per condition and agent (paper: 50; at most {MAX_TRIALS:,}, and {MAX_PLANNED_TRIALS:,} in all)",
    )
    seed: int = setting(
        0, kind="int", check=int_in(0, 2**63 - 1), bad=(-1, 2**63), help="root seed of the per-trial seeds"
    )
    sensor_model: str = setting(
        "calibrated",
        default=None,
        check=one_of(lambda: SENSOR_MODELS),
        choices=lambda: SENSOR_MODELS,
        from_env=lambda env_id: ENV_SENSOR_MODELS[env_id][0],
        bad=("exact",),
        help="the particle filter's sensor model (default: calibrated, the paper's; "
        "unknown-target: analytic, the theoretical EEV, or interpolated)",
    )
    signal: str = setting(
        DEFAULT_SIGNAL,
        check=one_of(lambda: SIGNALS),
        choices=lambda: SIGNALS,
        bad=("loud",),
        help="signal scale of the presets: fitted to Table 3's measured detection distances, "
        "coverage (fitted × one factor matching §6.3's 78%% of starts inside the detection "
        "region), or the paper's equations (scale 1); docs/fidelity.md compares them",
    )
    max_observations: int = setting(
        MAX_OBSERVATIONS,
        default=None,
        kind="int",
        check=int_in(MIN_OBSERVATION_CAP, MAX_READINGS),
        from_env=lambda env_id: ENV_MAX_OBSERVATIONS[env_id],
        bad=(MIN_OBSERVATION_CAP - 1, MAX_READINGS + 1),
        help=f"the cap of readings of a trial, the reset's included: {MIN_OBSERVATION_CAP}–{MAX_READINGS} "
        f"(default: the env's, {MAX_OBSERVATIONS} as the paper)",
    )
    n_particles: int = setting(
        N_PARTICLES,
        default=None,
        kind="int",
        check=int_in(2, MAX_PARTICLES),
        from_env=lambda env_id: ENV_N_PARTICLES[env_id],
        bad=(1, MAX_PARTICLES + 1),
        help=lambda: (
            f"particles of the belief (default: the env's, {N_PARTICLES} as the paper; unknown-target: "
            f"{ENV_N_PARTICLES[ENV_CHOICES['unknown-target']]})"
        ),
    )
    env_id: str = field(default_factory=lambda: ENV_CHOICES[DEFAULT_ENV])
    gain_levels: tuple[float, ...] | None = None
    sensor_layout: str | None = setting(
        None,
        check=one_of(lambda: LAYOUT_NAMES),
        choices=lambda: LAYOUT_NAMES,
        bad=("ring-99",),
        help=f"{PAPER_ENV_ID}'s sensing pairs (§7; observations = snapshots, K readings each)",
    )
    distractors: int = setting(
        0,
        kind="int",
        check=int_in(0, MAX_DISTRACTORS),
        bad=(-1, MAX_DISTRACTORS + 1),
        help=f"D objects that are not the target drawn per trial in the tank (ElectroLoc-v0's "
        f"distractors=D, 0–{MAX_DISTRACTORS}; in the true reading only)",
    )
    success_spread_mm: float = SUCCESS_SPREAD_MM

    @classmethod
    def build(cls, agents: Sequence[str], *, env: str = DEFAULT_ENV, **settings: Any) -> BenchConfig:
        """The run ``electroloc bench`` (and :func:`electroloc_gym.bench.run`) describe: ``env`` is a bench row
        (``--env``), ``settings`` the fields' front-end values (:data:`CONFIG_OPTIONS`); a setting left out is
        its option's default, and one None is the env's own, read from the env table here.

        Raises:
            ValueError: an unknown ``env`` or a setting out of its range (:class:`SettingError`).
            TypeError: a keyword that is no setting.
        """
        _bench_row("env", env)
        entry, row = bench_env(env)
        values: dict[str, Any] = {}
        for opt in CONFIG_OPTIONS:
            if opt.name == "agents":  # the first argument
                continue
            value = settings.pop(opt.name, opt.default)
            values[opt.name] = opt.from_env(entry.env_id) if value is None and opt.from_env else value
        if settings:
            raise TypeError(f"BenchConfig.build() got unexpected keyword(s) {sorted(settings)}")
        return cls(agents=tuple(agents), env_id=entry.env_id, gain_levels=row.env_kwargs.get("gain_levels"), **values)

    def env_kwargs(self, agent: Any = None, condition: str | None = None, *, builtin: bool = False) -> dict[str, Any]:
        """The ``gym.make(self.env_id, ...)`` kwargs of this run's trial of ``agent`` in ``condition``: the run's
        settings, then what the agent declares (:func:`electroloc_gym.bench.policy_fit.bench_env_kwargs`; a
        built-in controller's ``env_kwargs`` and ``adapt_condition`` apply, a plug-in agent's observation mode
        only). ``condition`` None: no condition (the agent's protocol without a tank).
        """
        from electroloc_gym.bench.policy_fit import bench_env_kwargs

        return bench_env_kwargs(
            self.env_id,
            agent,
            self.gain_levels,
            condition=condition,
            signal=self.signal,
            sensor_model=self.sensor_model,
            n_particles=self.n_particles,
            max_observations=self.max_observations,
            sensor_layout=self.sensor_layout,
            distractors=self.distractors,
            success_spread_mm=self.success_spread_mm,
            builtin=builtin,
        )

    def record_settings(self) -> dict[str, Any]:
        """The settings every record of this run carries (:data:`IDENTITY_KEYS`, as JSON stores them)."""
        plain = {k: getattr(self, k) for k in IDENTITY_KEYS}
        if plain["gain_levels"] is not None:
            plain["gain_levels"] = list(plain["gain_levels"])
        return plain

    def __post_init__(self) -> None:
        if self.env_id not in ENV_SENSOR_MODELS:
            raise ValueError(f"env_id must be one of {list(ENV_SENSOR_MODELS)}, got {self.env_id!r}")
        for opt in CONFIG_OPTIONS:
            if opt.name not in ("agents", "conditions"):  # these two are resolved below
                object.__setattr__(self, opt.name, opt.check_value(opt.name, getattr(self, opt.name)))
        if self.distractors and not ENV_TAKES_DISTRACTORS.get(self.env_id, False):
            takes = [k for k, v in ENV_TAKES_DISTRACTORS.items() if v]
            raise SettingError("distractors", f"0 on {self.env_id} (only {takes} take distractors)", self.distractors)
        if self.gain_levels is not None:
            object.__setattr__(self, "gain_levels", tuple(float(g) for g in self.gain_levels))
        if not self.agents:
            raise ValueError("agents must name at least one agent")
        if len(set(self.agents)) != len(self.agents):
            raise ValueError(f"agents must be distinct, got {list(self.agents)}")
        object.__setattr__(self, "conditions", run_conditions(self.env_id, self.conditions))
        allowed = ENV_SENSOR_MODELS[self.env_id]
        if self.sensor_model not in allowed:
            raise SettingError("sensor_model", f"one of {list(allowed)} on {self.env_id}", self.sensor_model)
        per_trial = len(self.agents) * len(self.conditions)  # the plan is held in memory
        if self.trials * per_trial > MAX_PLANNED_TRIALS:
            raise SettingError(
                "trials",
                f"at most {MAX_PLANNED_TRIALS // per_trial:,} with {len(self.agents)} agent(s) × "
                f"{len(self.conditions)} condition(s) ({MAX_PLANNED_TRIALS:,} trials in all)",
                self.trials,
            )
        spread = self.success_spread_mm
        if isinstance(spread, bool) or not isinstance(spread, (int, float)) or not 0 < spread < float("inf"):
            raise ValueError(f"success_spread_mm must be a finite number of mm > 0, got {spread!r}")
        object.__setattr__(self, "success_spread_mm", float(spread))

    def identity(self) -> dict[str, Any]:
        """The fields that must match for ``--resume`` to append to an existing run."""
        return {"seed": self.seed, **self.record_settings(), "success_spread_mm": self.success_spread_mm}


#: The settings a run is (what ``config.json`` stores), as the front ends take them.
CONFIG_OPTIONS: tuple[Option, ...] = options_of(BenchConfig)


def _workers_help() -> str:
    from electroloc_gym.bench.backends import default_workers

    return f"parallel worker processes (default: all cores, here {default_workers()})"


def _backends() -> list[str]:
    from electroloc_gym.bench.backends import BACKENDS

    return sorted(BACKENDS)


#: How and where a run runs (not the run: not in ``config.json``, free to change on ``--resume``).
RUN_OPTIONS: tuple[Option, ...] = (
    Option(
        "env",
        default=DEFAULT_ENV,
        check=_bench_row,
        bad=("nowhere", "no_such_module_xyz:nowhere"),
        help=lambda: (
            "; ".join(f"{n}: {entry.env_id} {row.summary}".rstrip() for n, (entry, row) in BENCH_ENVS.items())
            + "; or package.module:NAME, a bench name your own module registers (a task of your own, "
            "electroloc_gym.tasks): imported like any module, it runs your code (default: %(default)s)"
        ),
    ),
    Option("workers", kind="int", check=int_in(1, MAX_WORKERS), bad=(0, MAX_WORKERS + 1), help=_workers_help),
    Option(
        "backend",
        check=one_of(_backends),
        choices=_backends,
        bad=("cloud",),
        help="where trials run: a local process pool, in-process (serial), or Ray; from Python, serial when an "
        "agent is an object (default: process)",
    ),
    Option("address", help="cluster address for a distributed backend (e.g. --backend ray --address auto)"),
    Option(
        "out",
        default="bench_out",
        python_default=None,
        check=_out_folder,
        bad=("",),
        help="output folder (locked while the run writes to it; from Python, None: a new temporary folder)",
    ),
    Option(
        "resume",
        default=False,
        kind="switch",
        check=is_bool,
        bad=("yes",),
        help="continue the run in --out: run only the trials not yet in its trials.jsonl (each "
        "record's seeds and settings are checked; damaged lines are set aside and re-run)",
    ),
    Option(
        "trust_pickle",
        default=False,
        kind="switch",
        check=is_bool,
        bad=("yes",),
        help="also load learned policies stored as a bare SB3 .zip, which unpickles code from "
        "the file: only for files you trust",
    ),
    Option(
        "progress",
        default=True,
        python_default=False,
        kind="negated",
        flag="--no-progress",
        check=is_bool,
        bad=("yes",),
        help="no progress bar (from Python: progress=True draws one)",
    ),
)

#: Every setting of ``electroloc bench`` and :func:`electroloc_gym.bench.run`, in the order ``--help`` lists them.
BENCH_OPTIONS: tuple[Option, ...] = CONFIG_OPTIONS + RUN_OPTIONS


@dataclass(frozen=True)
class TrialSpec:
    """One trial, self-contained and picklable (what a worker receives): its key, its seeds and the run's
    settings (:class:`BenchConfig`, the same object for every trial of the run).
    """

    condition: str
    agent: str
    trial: int
    env_seed: int
    agent_seed: int
    config: BenchConfig
    #: Let the worker load a learned policy whose files need unpickling (SB3's bare zip).
    trust_pickle: bool = False

    @property
    def key(self) -> tuple[str, str, int]:
        """(condition, agent, trial): the identity of a trial in trials.jsonl."""
        return (self.condition, self.agent, self.trial)

    @property
    def env_id(self) -> str:
        """The run's environment id."""
        return self.config.env_id

    @property
    def signal(self) -> str:
        """The run's signal scale."""
        return self.config.signal

    def env_kwargs(self, agent: Any, *, builtin: bool) -> dict[str, Any]:
        """The ``gym.make`` kwargs of this trial's env (:meth:`BenchConfig.env_kwargs` in its condition)."""
        return self.config.env_kwargs(agent, self.condition, builtin=builtin)


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


def run_conditions(env_id: str, conditions: str | Sequence[str]) -> tuple[str, ...]:
    """The conditions a run on ``env_id`` has: an env with one fixed map runs its map as the one condition
    (``conditions`` does not apply), the others the presets ``conditions`` names (:func:`resolve_conditions`).
    """
    entry = env_entry(env_id)
    if entry.map_condition is not None:
        return (entry.map_condition,)
    return tuple(resolve_conditions(conditions if isinstance(conditions, str) else list(conditions)))


def trial_seeds(seed: int, condition: str, trial: int) -> tuple[int, int]:
    """(env seed, agent seed) of trial ``trial`` of ``condition``.

    ``SeedSequence(seed, spawn_key=(i, trial))`` is exactly ``SeedSequence(seed).spawn(n)[i].spawn(m)[trial]``
    with ``i`` the condition's index among the presets: independent of the run's other conditions,
    agents, trial count and workers.
    """
    index = len(PRESET_NAMES) if condition in MAP_CONDITIONS else PRESET_NAMES.index(condition)
    ss = np.random.SeedSequence(seed, spawn_key=(index, trial))
    env_seed, agent_seed = (int(v) for v in ss.generate_state(2, dtype=np.uint32))
    return env_seed, agent_seed


def make_trial_specs(config: BenchConfig, *, trust_pickle: bool = False) -> list[TrialSpec]:
    """All trials of a run, condition-major."""
    seeds = {(c, k): trial_seeds(config.seed, c, k) for c in config.conditions for k in range(config.trials)}
    return [
        TrialSpec(c, a, k, *seeds[c, k], config, trust_pickle=trust_pickle) for c, k in seeds for a in config.agents
    ]
