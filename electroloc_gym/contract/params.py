"""The simulation's frozen parameters: every keyword argument of the envs, declared once, validated once.

:class:`EnvParams` holds every argument of every env of :data:`electroloc_gym.registry.ENVS` and their
native vector envs (units in the names or the field docs). :meth:`EnvParams.from_kwargs` is how every
env builds it: which arguments a task takes, its sensor models and its defaults come from its entry in
the env table; an argument the task does not take, or a value outside its range, is one ``ValueError``
naming the argument and what is allowed. Defaults of the sensor model's calibration and of the
preset signal scale are those of :mod:`electroloc_gym.sensor_models` and
:func:`electroloc_gym.world.conditions.get_condition`, so a change there flows through unchanged.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from electroloc_gym.contract.observation import OBSERVATION_MODES
from electroloc_gym.protocol import MAX_OBSERVATIONS, MAX_STEP_MM, N_PARTICLES, SUCCESS_SPREAD_MM
from electroloc_gym.registry import TASKS, task_entry
from electroloc_gym.sensor_models import DEFAULT_CALIBRATION, SENSOR_MODEL_NAMES, CalibrationProtocol
from electroloc_gym.sensor_models.map import DEFAULT_POSITION_BLUR_MM
from electroloc_gym.sensor_models.shape import DEFAULT_EEV_RADII_MM
from electroloc_gym.utils.checks import check_bool, check_choice, check_float, check_int
from electroloc_gym.world.conditions import Condition, get_condition
from electroloc_gym.world.distractors import resolve_distractors
from electroloc_gym.world.scene import Scene

__all__ = [
    "EnvParams",
    "OBSERVATION_MODES",
    "ACTION_TYPES",
    "TARGET_DRAWS",
    "CONTRASTS",
    "DEFAULT_RADIUS_RANGE_MM",
    "LAYOUTS",
    "RADIUS_LIMITS_MM",
    "GAIN_FACTOR_LIMITS",
    "MAX_POSITION_BLUR_MM",
    "SIGNAL_LIMITS",
    "MAX_STEP_MM",
    "DISCRETE_MOVES_MM",
    "TARGET_MOTIONS",
    "MOTION_MODELS",
    "MAX_TARGET_SPEED_MM",
    "MIN_OBSERVATION_CAP",
    "MOTION_OPTION_SCOPES",
    "memory_limit_bytes",
    "check_int",
    "check_float",
    "check_bool",
]

ACTION_TYPES = ("continuous", "discrete")
#: The unknown-target env: how the episode's sphere is drawn (``"prior"``: radius uniform in
#: ``radius_range_mm``, material or contrast from ``contrast``; ``"condition"``: the condition's own sphere).
TARGET_DRAWS = ("prior", "condition")
#: ``"binary"``: a conductor (χ = +1) or an insulator (χ = −½); ``"continuous"``: χ uniform in [−½, 1].
CONTRASTS = ("binary", "continuous")
#: The unknown-target env's default radius range (prior of the belief and of the draws), mm.
DEFAULT_RADIUS_RANGE_MM = (5.0, 20.0)
#: Named maps of the global task: the fixed benchmark map, or a new seeded six-cylinder map per episode.
LAYOUTS = ("benchmark", "random")

#: The sphere radii an env may hypothesise or calibrate (``radius_range_mm``, ``eev_radii_mm``), mm: from a
#: 1 mm bead to a 100 mm ball, as large as the paper's smallest allowed box (±50 mm) allows.
RADIUS_LIMITS_MM = (1.0, 50.0)
#: The dynamic-gain factors of the amplifier gain G (``gain_levels``): a thousandth to a thousand times the
#: preset (the paper's gains span 103–1977, a factor of 20).
GAIN_FACTOR_LIMITS = (1e-3, 1e3)
#: The map sensor models' largest position blur, mm (the map's box is ±80 mm).
MAX_POSITION_BLUR_MM = 100.0
#: The presets' signal scale as a number (``signal``): a thousandth to a thousand (the fitted scales are ≈1–8).
SIGNAL_LIMITS = (1e-3, 1e3)

#: The moving target's true motion (ElectroLocTrack-v0, :mod:`electroloc_gym.engines.numba_core.track_task`):
#: Gaussian steps, or a constant-speed swimmer whose heading turns by Gaussian increments.
TARGET_MOTIONS = ("random_walk", "swimmer")
#: The motion model the moving target's filter is told (its prediction before every update): a random walk,
#: or none (a static target, the paper's filter).
MOTION_MODELS = ("random_walk", "static")
#: The largest target speed and filter step, mm per reading: twice the carriage's largest move per axis.
MAX_TARGET_SPEED_MM = 20.0
#: The smallest cap of readings per episode (``max_observations``): the reset takes the first reading and
#: every step one more, so the first step already makes two.
MIN_OBSERVATION_CAP = 2
#: The moving target's options that act under one value of another option only: (option, the other option,
#: the value it acts under, why it does not under the other). Such an option set away from its default
#: while the other option has another value would be silently ignored: one ValueError names both.
MOTION_OPTION_SCOPES = (
    ("turn_std_rad", "target_motion", "swimmer", "the random walk has no heading"),
    ("motion_step_mm", "motion_model", "random_walk", "the static filter takes no step"),
)

#: The discrete action set: stay plus the 8 king moves of 10 mm per axis (index = 3·(dx+1) + (dy+1)).
DISCRETE_MOVES_MM = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.float64) * MAX_STEP_MM
DISCRETE_MOVES_MM.flags.writeable = False

#: Bytes of state and scratch per particle and env (particles, jitter draws, the kernels' scratch).
BYTES_PER_PARTICLE = 96


def _default_signal() -> Any:
    return inspect.signature(get_condition).parameters["signal"].default


def _numbers_in(name: str, value: Any, count: int | None, low: float, high: float, unit: str = "") -> tuple[float, ...]:
    """A tuple of finite numbers in [low, high] (radii in mm, or gain factors): ``count`` of them, or at least
    one, given as a tuple, a list or a 1-d array.
    """
    items = None
    if isinstance(value, (tuple, list)) or (isinstance(value, np.ndarray) and value.ndim == 1):
        items = tuple(value)
    want = f"{count}" if count is not None else "one or more"
    if items is None or not items or (count is not None and len(items) != count):
        raise ValueError(f"{name} must be a tuple of {want} numbers in [{low:g}, {high:g}]{unit}, got {value!r}")
    return tuple(check_float(name, v, low, inclusive=True, high=high) for v in items)


def memory_limit_bytes() -> int:
    """The memory the simulation may plan to use: this machine's physical memory, bytes."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 16 * 2**30


@dataclass(frozen=True)
class EnvParams:
    """Every argument of the envs (frozen; validated on construction).

    Attributes:
        task: the core's task, one of :data:`electroloc_gym.registry.TASKS` (``"localize"``: ElectroLoc-v0,
            ``"global"``: ElectroLocGlobal-v0, ``"unknown"``: ElectroLocUnknownTarget-v0).
        condition: localize: a preset name (``electroloc_gym.PRESET_NAMES``), a ``Condition``, a dict of
            one, or ``"random"`` (one of the eight presets per episode).
        signal: localize, presets only: the signal scale, ``"fitted"``, ``"paper"``, ``"coverage"`` or a
            positive float (:func:`~electroloc_gym.world.conditions.get_condition`; default: its default).
        randomize_target: localize: the target uniform in the start box per episode (else the
            condition's ``target_xy_mm``).
        layout: global: ``"benchmark"`` (the fixed map), ``"random"`` (a new six-cylinder map per
            episode) or a :class:`~electroloc_gym.world.scene.Scene`.
        position_blur_mm: global: the map sensor models' position blur b, mm (≥ 0).
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
        target_draw: unknown target: ``"prior"`` (the sphere drawn from the prior) or ``"condition"``
            (the condition's own sphere, hidden from the agent: the benchmark over the paper's pairs).
        radius_range_mm: unknown target: (low, high) radius range of the prior, mm (0 < low < high).
        contrast: unknown target: ``"binary"`` (conductor or insulator) or ``"continuous"`` (χ ∈ [−½, 1]).
        eev_radii_mm: unknown target, ``sensor_model="interpolated"``: the radii of the calibrated
            EEVs (mm, positive, distinct) the model interpolates between.
        gain_levels: dynamic gain (§7): factors (positive, distinct) of the condition's amplifier gain G
            among which the agent picks the gain of every reading (the action gets a gain component);
            None: every reading at G. Reset reads at the level nearest to 1.
        sensor_layout: localize: the carriage's sensing pairs (§7), a name of
            :data:`electroloc_gym.world.sensor_array.LAYOUT_NAMES`, a
            :class:`~electroloc_gym.world.sensor_array.SensorLayout`, or (K, 2, 2) electrode offsets in mm
            (stored as a ``SensorLayout``); ``"single"``: the paper's one pair.
        fixed_carriage: localize: the carriage never moves (the stationary array); the action space is
            unchanged and its moves are ignored.
        distractors: localize: objects that are not the target, in the true reading only
            (:mod:`electroloc_gym.engines.numba_core.distractor_task`): a count D drawn per episode, a
            ``DistractorDraw``, a
            dict of its fields, or an explicit layout (a ``DistractorSet`` or a sequence of ``SceneObject``);
            stored resolved (0: none, the plain env).
        target_motion: moving target: the target's true motion, ``"random_walk"`` or ``"swimmer"``
            (:data:`TARGET_MOTIONS`).
        target_speed_mm: moving target: its speed, mm per reading, in [0, 20]: the random walk's RMS step
            (per-axis std ``target_speed_mm``/√2), the swimmer's constant step length.
        turn_std_rad: moving target, ``"swimmer"``: std of the heading's change per reading, rad, in [0, π]
            (another value than the default 0.5 with ``target_motion="random_walk"`` is refused:
            :data:`MOTION_OPTION_SCOPES`).
        motion_model: moving target: the filter's motion model, ``"random_walk"`` (every particle takes a
            Gaussian step before each update) or ``"static"`` (none: the paper's filter) (:data:`MOTION_MODELS`).
        motion_step_mm: moving target: the filter's random-walk RMS step, mm per reading, in [0, 20], or
            None: the target's ``target_speed_mm`` (a different value is a model mismatch); a number with
            ``motion_model="static"`` is refused (:data:`MOTION_OPTION_SCOPES`).
    """

    task: str = "localize"
    condition: Any = "fresh-steel-12.7"
    signal: Any = dataclasses.field(default_factory=_default_signal)
    randomize_target: bool = False
    layout: Any = "benchmark"
    position_blur_mm: float = DEFAULT_POSITION_BLUR_MM
    observation: str = "belief"
    sensor_model: str = SENSOR_MODEL_NAMES[0]
    n_particles: int = N_PARTICLES
    max_observations: int = MAX_OBSERVATIONS
    success_spread_mm: float = SUCCESS_SPREAD_MM
    action_type: str = "continuous"
    calibration_seed: int | None = None
    calibration: Any = DEFAULT_CALIBRATION
    max_episode_steps: int | None = None
    target_draw: str = "prior"
    radius_range_mm: Any = DEFAULT_RADIUS_RANGE_MM
    contrast: str = "binary"
    eev_radii_mm: Any = DEFAULT_EEV_RADII_MM
    gain_levels: Any = None
    sensor_layout: Any = "single"
    fixed_carriage: bool = False
    distractors: Any = 0
    target_motion: str = "swimmer"
    target_speed_mm: float = 1.0
    turn_std_rad: float = 0.5
    motion_model: str = "random_walk"
    motion_step_mm: float | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        check_choice("task", self.task, TASKS)
        check_choice("observation", self.observation, OBSERVATION_MODES)
        check_choice("sensor_model", self.sensor_model, task_entry(self.task).sensor_models)
        check_choice("target_draw", self.target_draw, TARGET_DRAWS)
        check_choice("contrast", self.contrast, CONTRASTS)
        put("radius_range_mm", _numbers_in("radius_range_mm", self.radius_range_mm, 2, *RADIUS_LIMITS_MM, " mm"))
        if self.radius_range_mm[0] >= self.radius_range_mm[1]:
            raise ValueError(f"radius_range_mm must be (low, high) with low < high, got {self.radius_range_mm!r}")
        put(
            "eev_radii_mm",
            tuple(sorted(_numbers_in("eev_radii_mm", self.eev_radii_mm, None, *RADIUS_LIMITS_MM, " mm"))),
        )
        if len(set(self.eev_radii_mm)) != len(self.eev_radii_mm):
            raise ValueError(f"eev_radii_mm must be distinct, got {self.eev_radii_mm!r}")
        if self.gain_levels is not None:
            put("gain_levels", _numbers_in("gain_levels", self.gain_levels, None, *GAIN_FACTOR_LIMITS))
            if len(set(self.gain_levels)) != len(self.gain_levels):
                raise ValueError(f"gain_levels must be distinct factors of the gain, got {self.gain_levels!r}")
        check_choice("action_type", self.action_type, ACTION_TYPES)
        check_choice("target_motion", self.target_motion, TARGET_MOTIONS)
        check_choice("motion_model", self.motion_model, MOTION_MODELS)
        top = MAX_TARGET_SPEED_MM
        put("target_speed_mm", check_float("target_speed_mm", self.target_speed_mm, 0.0, inclusive=True, high=top))
        put("turn_std_rad", check_float("turn_std_rad", self.turn_std_rad, 0.0, inclusive=True, high=math.pi))
        if self.motion_step_mm is not None:
            put("motion_step_mm", check_float("motion_step_mm", self.motion_step_mm, 0.0, inclusive=True, high=top))
        self._check_option_scopes()
        put("n_particles", check_int("n_particles", self.n_particles, 1, 2**31 - 2))
        cap = self.max_observations
        if isinstance(cap, (bool, np.bool_)) or not isinstance(cap, (int, np.integer)) or cap < MIN_OBSERVATION_CAP:
            raise ValueError(
                f"max_observations must be an integer ≥ {MIN_OBSERVATION_CAP} (the reset takes the first reading "
                f"and every step one more), got {cap!r}"
            )
        put("max_observations", int(cap))
        put("success_spread_mm", check_float("success_spread_mm", self.success_spread_mm, 0.0))
        put("randomize_target", check_bool("randomize_target", self.randomize_target))
        put("fixed_carriage", check_bool("fixed_carriage", self.fixed_carriage))
        if not isinstance(self.sensor_layout, str):
            from electroloc_gym.world.sensor_array import make_sensor_layout

            put("sensor_layout", make_sensor_layout(self.sensor_layout))  # one error naming sensor_layout
        elif self.sensor_layout != "single":
            from electroloc_gym.world.sensor_array import named_layout

            named_layout(self.sensor_layout)  # an unknown name: one error naming sensor_layout
        put(
            "position_blur_mm",
            check_float("position_blur_mm", self.position_blur_mm, 0.0, inclusive=True, high=MAX_POSITION_BLUR_MM),
        )
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
        if "distractors" in task_entry(self.task).arguments:
            put("distractors", resolve_distractors(self.distractors))
        if "condition" in task_entry(self.task).arguments:
            signal = self.signal
            if isinstance(signal, (int, float, np.integer, np.floating)) and not isinstance(signal, (bool, np.bool_)):
                put("signal", check_float("signal", signal, SIGNAL_LIMITS[0], inclusive=True, high=SIGNAL_LIMITS[1]))
            if isinstance(self.condition, Mapping):
                try:
                    get_condition(self.condition, self.signal)
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"condition (a dict of Condition fields) is invalid: {exc}") from None
            elif not (isinstance(self.condition, str) and self.condition == "random"):
                get_condition(self.condition, self.signal)  # raises for an unknown name or a bad signal
            elif self.signal is not None:
                get_condition("fresh-steel-12.7", self.signal)
        elif not isinstance(self.layout, Scene):
            check_choice("layout", self.layout, LAYOUTS)

    def _check_option_scopes(self) -> None:
        """Refuse an option of :data:`MOTION_OPTION_SCOPES` set away from its default while the option it
        depends on has a value under which it does nothing (one ValueError naming both and what is allowed).
        """
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        for name, mode, acts_under, why in MOTION_OPTION_SCOPES:
            value, default, mode_value = getattr(self, name), defaults[name], getattr(self, mode)
            if mode_value != acts_under and value != default:
                keep = "None" if default is None else f"at its default {default!r}"
                raise ValueError(
                    f"{name} applies only when {mode} is {acts_under!r} ({why}); got {mode}={mode_value!r} "
                    f"with {name}={value!r}: leave {name} {keep} or choose {mode}={acts_under!r}"
                )

    @classmethod
    def from_kwargs(cls, task: str, kwargs: Mapping[str, Any], env_id: str) -> EnvParams:
        """The params of ``task`` from an env's keyword arguments, over the defaults of its entry in the env
        table (its first sensor model, its ``defaults``); an argument the task does not take is a ValueError
        naming it and listing the allowed ones.
        """
        entry = task_entry(task)
        allowed = entry.all_arguments
        unknown = [k for k in kwargs if k not in allowed]
        if unknown:
            raise ValueError(f"{env_id} got unexpected argument(s) {unknown}; its arguments are {sorted(allowed)}")
        return cls(task=task, **{"sensor_model": entry.sensor_models[0], **entry.defaults, **kwargs})

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

    def conditions(self) -> tuple[Condition, ...]:
        """The localize task's condition pool (one, or the eight presets for ``condition="random"``)."""
        from electroloc_gym.world.conditions import PRESET_NAMES

        if isinstance(self.condition, str) and self.condition == "random":
            return tuple(get_condition(n, self.signal) for n in PRESET_NAMES)
        return (get_condition(self.condition, self.signal),)

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
