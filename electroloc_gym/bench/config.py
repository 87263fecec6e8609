"""What a benchmark run is: its settings (:class:`BenchConfig`), its trials (:class:`TrialSpec`), their seeds.

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

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from electroloc_gym.baselines.agent import PAPER_AGENTS
from electroloc_gym.contract.params import MIN_OBSERVATION_CAP, EnvParams
from electroloc_gym.protocol import MAX_OBSERVATIONS, N_PARTICLES, SUCCESS_SPREAD_MM
from electroloc_gym.registry import BENCH_ENVS, ENVS, LiveMapping, LiveSequence, env_entry
from electroloc_gym.world.conditions import DEFAULT_SIGNAL, PRESET_NAMES, SIGNAL_CHOICES
from electroloc_gym.world.distractors import MAX_DISTRACTORS

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
]

#: Most readings a trial may be capped at (``max_observations``): far beyond the paper's 35, short of a
#: trial that cannot run.
MAX_READINGS = 100_000

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
#: paper §6.5, = info["condition"]); their trial seeds use condition index 8.
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


class SettingError(ValueError):
    """A run setting out of its range: ``setting`` names the field, ``allowed`` the range, ``got`` the value.

    ``str()`` names the field as Python spells it; a front end names it its own way (``--max-observations``)
    from the same three parts, so the check and its words live here once.
    """

    def __init__(self, setting: str, allowed: str, got: Any) -> None:
        super().__init__(f"{setting} must be {allowed}, got {got!r}")
        self.setting, self.allowed, self.got = setting, allowed, got

    def __reduce__(self) -> tuple[Any, ...]:
        return (SettingError, (self.setting, self.allowed, self.got))


@dataclass(frozen=True)
class BenchConfig:
    """What a benchmark run is (stored in ``config.json``; ``--resume`` checks it).

    Attributes:
        agents: agent specs (names, ``name[opts]``, shipped model names or policy paths).
        conditions: preset names.
        trials: trials per condition and agent.
        seed: root seed of the trial seeds.
        sensor_model: the filter's sensor model, "calibrated" (the paper's) or "analytic"; the unknown-target
            env: "analytic" (the theoretical EEV) or "interpolated" (:data:`ENV_SENSOR_MODELS`).
        signal: the presets' signal scale (:data:`electroloc_gym.world.conditions.DEFAULT_SIGNAL` by default):
            "fitted" (fitted to Table 3's measured detection distances), "coverage" (fitted × one factor
            matching the paper's §6.3 start coverage) or "paper" (scale 1); see conditions.get_condition.
        max_observations: the cap of readings of a trial (paper: 35; the env's smallest cap
            :data:`~electroloc_gym.contract.params.MIN_OBSERVATION_CAP` to :data:`MAX_READINGS`).
        n_particles: particles of the belief (paper: 2500).
        success_spread_mm: the success criterion, mm: a trial succeeds when the belief's spread √trace Σ is
            at most this (paper: 10 mm). With the cap, the particles, the sensor model, the signal, the
            layout and the distractors it is the run's protocol: fixed by the run for every agent (a
            plug-in agent's ``env_kwargs`` cannot change it) and compared by ``--resume``.
        env_id: the environment id.
        gain_levels: dynamic gain: the factors of the amplifier gain in the action (None: the preset gain).
        sensor_layout: ElectroLoc-v0's named sensor layout (``electroloc_gym.world.sensor_array.LAYOUT_NAMES``), or
            None: the env's default (the paper's pair).
        distractors: D, distractors drawn per trial in ElectroLoc-v0's tank (``distractors=D``; 0: none).
    """

    agents: tuple[str, ...] = DEFAULT_AGENTS
    conditions: tuple[str, ...] = PRESET_NAMES
    trials: int = 50
    seed: int = 0
    sensor_model: str = "calibrated"
    signal: str = DEFAULT_SIGNAL
    max_observations: int = MAX_OBSERVATIONS
    n_particles: int = N_PARTICLES
    env_id: str = field(default_factory=lambda: ENV_CHOICES[DEFAULT_ENV])
    gain_levels: tuple[float, ...] | None = None
    sensor_layout: str | None = None
    distractors: int = 0
    success_spread_mm: float = SUCCESS_SPREAD_MM

    @classmethod
    def build(
        cls,
        agents: Sequence[str],
        *,
        env: str = "target",
        conditions: str | Sequence[str] = "all",
        trials: int = 50,
        seed: int = 0,
        sensor_model: str | None = None,
        signal: str = DEFAULT_SIGNAL,
        max_observations: int | None = None,
        n_particles: int | None = None,
        sensor_layout: str | None = None,
        distractors: int = 0,
    ) -> BenchConfig:
        """The run ``electroloc bench`` (and :func:`electroloc_gym.bench.run`) describe: ``env`` is a bench row
        (``--env``), and every setting left None is the env's own default, read from the env table here.

        Raises:
            ValueError: an unknown ``env`` or a setting out of its range (:class:`SettingError`).
        """
        if env not in ENV_CHOICES:
            raise ValueError(f"env must be one of {list(ENV_CHOICES)}, got {env!r}")
        entry, row = BENCH_ENVS[env]
        env_id = entry.env_id
        return cls(
            agents=tuple(agents),
            conditions=run_conditions(env_id, conditions),
            trials=trials,
            seed=seed,
            sensor_model=sensor_model or ENV_SENSOR_MODELS[env_id][0],
            signal=signal,
            max_observations=ENV_MAX_OBSERVATIONS[env_id] if max_observations is None else max_observations,
            n_particles=ENV_N_PARTICLES[env_id] if n_particles is None else n_particles,
            env_id=env_id,
            gain_levels=row.env_kwargs.get("gain_levels"),
            sensor_layout=sensor_layout,
            distractors=distractors,
        )

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
        d = self.distractors
        if isinstance(d, bool) or not isinstance(d, int) or not 0 <= d <= MAX_DISTRACTORS:
            raise ValueError(f"distractors must be an integer in [0, {MAX_DISTRACTORS}], got {d!r}")
        if d and not ENV_TAKES_DISTRACTORS.get(self.env_id, False):
            raise ValueError(
                f"distractors apply to {[k for k, v in ENV_TAKES_DISTRACTORS.items() if v]} only, not {self.env_id}"
            )
        if self.gain_levels is not None:
            object.__setattr__(self, "gain_levels", tuple(float(g) for g in self.gain_levels))
        if not self.agents:
            raise ValueError("agents must name at least one agent")
        if len(set(self.agents)) != len(self.agents):
            raise ValueError(f"agents must be distinct, got {list(self.agents)}")
        object.__setattr__(self, "conditions", run_conditions(self.env_id, self.conditions))
        for name, val, low in (
            ("trials", self.trials, 1),
            ("seed", self.seed, 0),
            ("n_particles", self.n_particles, 1),
        ):
            if isinstance(val, bool) or not isinstance(val, int) or val < low:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {val!r}")
        cap = self.max_observations
        if isinstance(cap, bool) or not isinstance(cap, int) or not MIN_OBSERVATION_CAP <= cap <= MAX_READINGS:
            raise SettingError("max_observations", f"an integer in [{MIN_OBSERVATION_CAP}, {MAX_READINGS}]", cap)
        allowed = ENV_SENSOR_MODELS[self.env_id]
        if self.sensor_model not in allowed:
            raise ValueError(f"sensor_model of {self.env_id} must be one of {list(allowed)}, got {self.sensor_model!r}")
        if self.signal not in SIGNALS:
            raise ValueError(f"signal must be one of {list(SIGNALS)}, got {self.signal!r}")
        spread = self.success_spread_mm
        if isinstance(spread, bool) or not isinstance(spread, (int, float)) or not 0 < spread < float("inf"):
            raise ValueError(f"success_spread_mm must be a finite number of mm > 0, got {spread!r}")
        object.__setattr__(self, "success_spread_mm", float(spread))

    def identity(self) -> dict[str, Any]:
        """The fields that must match for ``--resume`` to append to an existing run."""
        return {"seed": self.seed, **self.record_settings(), "success_spread_mm": self.success_spread_mm}


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
    #: The run's settings.
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
    specs = []
    for cond in config.conditions:
        for k in range(config.trials):
            env_seed, agent_seed = trial_seeds(config.seed, cond, k)
            for agent in config.agents:
                specs.append(TrialSpec(cond, agent, k, env_seed, agent_seed, config, trust_pickle=trust_pickle))
    return specs
