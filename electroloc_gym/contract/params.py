"""The simulation's frozen parameters: the arguments every env shares, and the task's own options beside them.

:class:`EnvParams` holds what every env of :data:`electroloc_gym.registry.ENVS` shares (the observation,
the sensor model, the particle filter's and the protocol's constants) and, in ``options``, its task's own
arguments: an instance of the task class's ``Options`` (a :class:`~electroloc_gym.contract.task_spec.TaskOptions`
declared in the task's module). :meth:`EnvParams.from_kwargs` is how every env builds it: the shared
arguments go to :class:`EnvParams`, the task's own to its ``Options``, with the defaults of its entry in
the env table; an argument neither takes, or a value outside its range, is one ``ValueError`` naming
the argument and what is allowed. The options several tasks share are declared here once, as bases a
task's ``Options`` inherits: :class:`LocalizeOptions` (the tank and its target: ``condition``,
``signal``, ``randomize_target``; read by both engines) and :class:`GainOptions` (the dynamic gain,
which the shared task machinery and the action space read). Defaults of the sensor model's calibration
and of the preset signal scale are those of :mod:`electroloc_gym.sensor_models` and
:func:`electroloc_gym.world.conditions.get_condition`, so a change there flows through unchanged.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from electroloc_gym.contract.observation import OBSERVATION_MODES
from electroloc_gym.contract.task_spec import Boolean, Numbers, TaskOptions, option
from electroloc_gym.protocol import MAX_OBSERVATIONS, MAX_STEP_MM, N_PARTICLES, SUCCESS_SPREAD_MM
from electroloc_gym.registry import TASKS, task_entry
from electroloc_gym.sensor_models import DEFAULT_CALIBRATION, SENSOR_MODEL_NAMES, CalibrationProtocol
from electroloc_gym.utils.checks import check_bool, check_choice, check_float, check_int
from electroloc_gym.utils.moved_paths import moved_name_error
from electroloc_gym.world.conditions import Condition, get_condition

__all__ = [
    "EnvParams",
    "LocalizeOptions",
    "GainOptions",
    "OBSERVATION_MODES",
    "ACTION_TYPES",
    "GAIN_FACTOR_LIMITS",
    "SIGNAL_LIMITS",
    "MAX_STEP_MM",
    "DISCRETE_MOVES_MM",
    "MIN_OBSERVATION_CAP",
    "memory_limit_bytes",
    "check_int",
    "check_float",
    "check_bool",
]

ACTION_TYPES = ("continuous", "discrete")

#: The dynamic-gain factors of the amplifier gain G (``gain_levels``): a thousandth to a thousand times the
#: preset (the paper's gains span 103–1977, a factor of 20).
GAIN_FACTOR_LIMITS = (1e-3, 1e3)
#: The presets' signal scale as a number (``signal``): a thousandth to a thousand (the fitted scales are ≈1–8).
SIGNAL_LIMITS = (1e-3, 1e3)
#: The smallest cap of readings per episode (``max_observations``): the reset takes the first reading and
#: every step one more, so the first step already makes two.
MIN_OBSERVATION_CAP = 2

#: The discrete action set: stay plus the 8 king moves of 10 mm per axis (index = 3·(dx+1) + (dy+1)).
DISCRETE_MOVES_MM = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.float64) * MAX_STEP_MM
DISCRETE_MOVES_MM.flags.writeable = False

#: Bytes of state and scratch per particle and env (particles, jitter draws, the kernels' scratch).
BYTES_PER_PARTICLE = 96

#: The preset signal scale's default (:func:`~electroloc_gym.world.conditions.get_condition`'s).
DEFAULT_SIGNAL: Any = inspect.signature(get_condition).parameters["signal"].default

_O = TypeVar("_O", bound=TaskOptions)


def _signal(name: str, value: Any) -> Any:
    """A number in :data:`SIGNAL_LIMITS` as a float; a name (checked with the condition) as it is."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        return check_float(name, value, SIGNAL_LIMITS[0], inclusive=True, high=SIGNAL_LIMITS[1])
    return value


@dataclass(frozen=True)
class LocalizeOptions(TaskOptions):
    """The options of the tasks in a tank of the paper's conditions with a target sphere (the localise family:
    ElectroLoc-v0, ElectroLocUnknownTarget-v0, ElectroLocTrack-v0), which both engines read.

    Attributes:
        condition: a preset name (``electroloc_gym.PRESET_NAMES``), a ``Condition``, a dict of one, or
            ``"random"`` (one of the eight presets per episode).
        signal: presets only: the signal scale, ``"fitted"``, ``"paper"``, ``"coverage"`` or a positive float
            in :data:`SIGNAL_LIMITS` (:func:`~electroloc_gym.world.conditions.get_condition`; default: its default).
        randomize_target: the target uniform in the start box per episode (else the condition's ``target_xy_mm``).
    """

    condition: Any = option(
        "fresh-steel-12.7", doc="a preset name, a Condition, a dict of one, or 'random' (a preset per episode)"
    )
    signal: Any = option(DEFAULT_SIGNAL, doc="the presets' signal scale: a name or a number", check=_signal)
    randomize_target: bool = option(False, doc="the target uniform in the start box per episode", check=Boolean())

    def check(self) -> None:
        """The condition (and a named signal) exist: an unknown name or a bad dict is one ValueError."""
        if isinstance(self.condition, Mapping):
            try:
                get_condition(self.condition, self.signal)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"condition (a dict of Condition fields) is invalid: {exc}") from None
        elif not (isinstance(self.condition, str) and self.condition == "random"):
            get_condition(self.condition, self.signal)  # raises for an unknown name or a bad signal
        elif self.signal is not None:
            get_condition("fresh-steel-12.7", self.signal)

    def conditions(self) -> tuple[Condition, ...]:
        """The episode's condition pool (one, or the eight presets for ``condition="random"``)."""
        from electroloc_gym.world.conditions import PRESET_NAMES

        if isinstance(self.condition, str) and self.condition == "random":
            return tuple(get_condition(n, self.signal) for n in PRESET_NAMES)
        return (get_condition(self.condition, self.signal),)


def _gain_levels(name: str, value: Any) -> tuple[float, ...] | None:
    """None, or distinct factors in :data:`GAIN_FACTOR_LIMITS`."""
    if value is None:
        return None
    levels = Numbers(None, *GAIN_FACTOR_LIMITS)(name, value)
    if len(set(levels)) != len(levels):
        raise ValueError(f"{name} must be distinct factors of the gain, got {levels!r}")
    return levels


@dataclass(frozen=True)
class GainOptions(TaskOptions):
    """The dynamic gain (§7), an option of the tasks whose ``Options`` inherit it.

    Attributes:
        gain_levels: factors (positive, distinct) of the condition's amplifier gain G among which the agent
            picks the gain of every reading (the action gets a gain component); None: every reading at G.
            Reset reads at the level nearest to 1.
    """

    gain_levels: Any = option(
        None,
        doc="factors of the amplifier gain the agent picks from every reading (None: the preset's)",
        check=_gain_levels,
    )


def memory_limit_bytes() -> int:
    """The memory the simulation may plan to use: this machine's physical memory, bytes."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 16 * 2**30


@dataclass(frozen=True)
class EnvParams:
    """The arguments every env shares and its task's own options (frozen; validated on construction).

    Attributes:
        task: the core's task, one of :data:`electroloc_gym.registry.TASKS` (``"localize"``: ElectroLoc-v0,
            ``"global"``: ElectroLocGlobal-v0, ``"unknown"``: ElectroLocUnknownTarget-v0, ``"track"``:
            ElectroLocTrack-v0).
        observation: ``"belief"`` (81 features) or ``"raw"`` (3).
        sensor_model: the filter's and the agent's sensor model, ``"analytic"`` or ``"calibrated"``; unknown
            target: ``"analytic"`` (the theoretical EEV of each hypothesis) or ``"interpolated"``.
        n_particles: particles M per env (≥ 1; paper: 2500).
        max_observations: readings per episode before truncation, the reset's included (≥
            :data:`MIN_OBSERVATION_CAP`, 2: the reset's reading and one step's; paper §5.4: 35).
        success_spread_mm: success when √trace Σ ≤ this, mm (> 0; paper: 10 mm).
        action_type: ``"continuous"`` (Box(−1, 1, (2,)) × 10 mm) or ``"discrete"`` (Discrete(9)).
        calibration_seed: seed of every episode's calibration (≥ 0), or None: a new calibration per
            episode drawn from the env's generator.
        calibration: how the calibrated model is taken (a ``CalibrationProtocol`` or a dict of its
            fields; default ``DEFAULT_CALIBRATION``).
        max_episode_steps: truncate after this many steps (≥ 1), or None (a ``TimeLimit`` in the env).
        options: the task's own arguments, an instance of its task class's ``Options`` (None: its defaults).
    """

    task: str = "localize"
    observation: str = "belief"
    sensor_model: str = SENSOR_MODEL_NAMES[0]
    n_particles: int = N_PARTICLES
    max_observations: int = MAX_OBSERVATIONS
    success_spread_mm: float = SUCCESS_SPREAD_MM
    action_type: str = "continuous"
    calibration_seed: int | None = None
    calibration: Any = DEFAULT_CALIBRATION
    max_episode_steps: int | None = None
    options: Any = None

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        check_choice("task", self.task, TASKS)
        options_class: type[TaskOptions] = task_entry(self.task).options_class
        if self.options is None:
            put("options", options_class())
        elif type(self.options) is not options_class:
            raise ValueError(
                f"options must be a {options_class.__name__} (the {self.task!r} task's options), "
                f"got {type(self.options).__name__}"
            )
        check_choice("observation", self.observation, OBSERVATION_MODES)
        check_choice("sensor_model", self.sensor_model, task_entry(self.task).sensor_models)
        check_choice("action_type", self.action_type, ACTION_TYPES)
        put("n_particles", check_int("n_particles", self.n_particles, 1, 2**31 - 2))
        cap = self.max_observations
        if isinstance(cap, (bool, np.bool_)) or not isinstance(cap, (int, np.integer)) or cap < MIN_OBSERVATION_CAP:
            raise ValueError(
                f"max_observations must be an integer ≥ {MIN_OBSERVATION_CAP} (the reset takes the first reading "
                f"and every step one more), got {cap!r}"
            )
        put("max_observations", int(cap))
        put("success_spread_mm", check_float("success_spread_mm", self.success_spread_mm, 0.0))
        if self.calibration_seed is not None:
            put("calibration_seed", check_int("calibration_seed", self.calibration_seed, 0, 2**63 - 1))
        if self.max_episode_steps is not None:
            put("max_episode_steps", check_int("max_episode_steps", self.max_episode_steps, 1))
        cal = self.calibration
        if isinstance(cal, Mapping):
            fields = {f.name for f in dataclasses.fields(CalibrationProtocol)}
            unknown = sorted(set(cal) - fields)
            if unknown:
                raise ValueError(f"calibration has unknown fields {unknown}; allowed: {sorted(fields)}")
            cal = CalibrationProtocol(**cal)
        if not isinstance(cal, CalibrationProtocol):
            raise ValueError(f"calibration must be a CalibrationProtocol or a dict of its fields, got {cal!r}")
        put("calibration", cal)

    @classmethod
    def shared_names(cls) -> tuple[str, ...]:
        """The arguments every env takes (the fields but ``task``, set by the env id, and ``options``)."""
        return tuple(f.name for f in dataclasses.fields(cls) if f.name not in ("task", "options"))

    @classmethod
    def from_kwargs(cls, task: str, kwargs: Mapping[str, Any], env_id: str) -> EnvParams:
        """The params of ``task`` from an env's keyword arguments, over the defaults of its entry in the env
        table (its first sensor model, its ``defaults``): the shared arguments to the params, the task's own
        to its ``Options``; an argument neither takes is a ValueError naming it and listing the allowed ones.
        """
        entry = task_entry(task)
        allowed = entry.all_arguments
        unknown = [k for k in kwargs if k not in allowed]
        if unknown:
            raise ValueError(f"{env_id} got unexpected argument(s) {unknown}; its arguments are {sorted(allowed)}")
        merged = {"sensor_model": entry.sensor_models[0], **entry.defaults, **kwargs}
        options_class: type[TaskOptions] = entry.options_class
        own = set(options_class.names())
        options = options_class(**{k: v for k, v in merged.items() if k in own})
        return cls(task=task, options=options, **{k: v for k, v in merged.items() if k not in own})

    def options_as(self, options_class: type[_O]) -> _O:
        """``options`` as ``options_class`` (a task reads its own options typed; a TypeError if they are not)."""
        if not isinstance(self.options, options_class):
            raise TypeError(f"the {self.task!r} task's options are no {options_class.__name__}")
        return self.options

    @property
    def gain_levels(self) -> tuple[float, ...] | None:
        """The dynamic gain's factors (:class:`GainOptions`), None without (a task that takes no gain levels)."""
        return getattr(self.options, "gain_levels", None)

    @property
    def gains(self) -> tuple[float, ...]:
        """The gain factors of the readings (``gain_levels``, or (1,) without dynamic gain)."""
        return (1.0,) if self.gain_levels is None else self.gain_levels

    @property
    def reset_gain_index(self) -> int:
        """The level reset reads at: the one nearest to the preset gain (factor 1, on a log scale)."""
        return int(np.argmin([abs(math.log(f)) for f in self.gains]))

    def replace(self, **changes: Any) -> EnvParams:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def check_memory(self, num_envs: int, calibration_points: int) -> None:
        """Refuse sizes that cannot fit in memory, naming the limit.

        Args:
            num_envs: envs simulated together.
            calibration_points: the largest calibration grid's points per axis (0 for analytic).
        """
        limit = memory_limit_bytes()
        need = num_envs * self.n_particles * BYTES_PER_PARTICLE
        if need > limit:
            raise ValueError(
                f"n_particles × num_envs = {self.n_particles} × {num_envs} needs ≈{need / 2**30:.3g} GiB "
                f"({BYTES_PER_PARTICLE} bytes per particle), more than this machine's "
                f"{limit / 2**30:.3g} GiB: at most {limit // (BYTES_PER_PARTICLE * num_envs)} "
                f"particles per env"
            )
        n = calibration_points
        cal = 8 * self.calibration.samples_per_point * n * n + num_envs * 32 * n * n
        if n and cal > limit:
            raise ValueError(
                f"calibration grid of {n}×{n} points × {self.calibration.samples_per_point} "
                f"readings needs ≈{cal / 2**30:.3g} GiB, more than this machine's "
                f"{limit / 2**30:.3g} GiB: choose a coarser calibration grid_step_mm"
            )
        if n and num_envs * ((n - 1) ** 2 + 1) >= 2**31:
            raise ValueError(
                f"calibration tables of {num_envs} envs × {(n - 1) ** 2 + 1} cells exceed the "
                f"kernels' int32 row index (2**31 rows): fewer envs or a coarser grid_step_mm"
            )


def __getattr__(name: str) -> Any:
    """A name that moved out of this module: one ImportError naming its new place (``utils.moved_paths``)."""
    raise moved_name_error(__name__, name)
