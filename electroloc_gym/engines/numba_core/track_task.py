"""The ``track`` task (ElectroLocTrack-v0): the particles follow a target sphere that moves during the episode.

The paper's target sits still (Solberg, Lynch & MacIver, IJRR 2008, §4); the fish that inspired the
robot hunt moving prey in the dark. Here the sphere of the episode's condition swims in its horizontal
plane below the carriage, and the belief must carry a motion model.

**The target's motion** (``target_motion``, before every reading but the reset's): ``"random_walk"``:
a Gaussian step of per-axis std ``target_speed_mm``/√2 (RMS step ``target_speed_mm`` mm per reading);
``"swimmer"``: a step of exactly ``target_speed_mm`` along its heading, the heading turning by a Gaussian
increment of std ``turn_std_rad`` per reading (drawn uniform at reset). The target stays in the
allowed box [−H, H]² for any step: a step that crosses a wall is reflected at it, as many times as the
straight path crosses walls (a step longer than the box; :func:`reflect`), and the swimmer's heading is
mirrored with each.

**Why a default of 1 mm per reading.** Weakly electric fish hunt water fleas (Daphnia, 2–3 mm) that
swim about one body length per second, a few mm/s, while the fish cruises at the order of 10 cm/s
(Nelson & MacIver, J. Exp. Biol. 1999; MacIver, Sharabash & Nelson, J. Exp. Biol. 2001): the prey is
2–5 % as fast as its hunter. The paper gives no time per reading, so the speed is scaled by the
hunter's reach instead: the carriage moves at most 10 mm per axis per reading (§4.1.3), so the
biological ratio is 0.2–0.5 mm per reading. The default (1 mm per reading, 10 % of the carriage's
reach) is two to five times that, so that a 70-reading episode's target travels 70 mm (the swimmer)
— across the paper's ±50 mm box — and tracking, not localisation, decides the score; ``target_speed_mm``
goes to 20 mm per reading, where no controller can follow (docs/extensions.md's speed sweep).

**The filter's motion model** (``motion_model``, what the belief is told; it may differ from the truth):
``"random_walk"``: each particle takes a Gaussian step of per-axis std σ_f = ``motion_step_mm``/√2
(None: the target's own ``target_speed_mm``) before every update; ``"static"``: none (the paper's
filter); ``"swimmer"``: the swimmer's own model, each particle a velocity beside its position (below).
The random walk's step is taken where the particle filter already draws a Gaussian per particle and
axis: the jitter after resampling (paper §4.1.2: N(0, 1 mm²) per axis). Resample → jitter → the next
reading's update is the same sequence as resample → predict → update, and the sum of the two
independent Gaussians is one Gaussian, so the jitter's std becomes √(1 mm² + σ_f²): the same draws
(the kernels' normal quantile table, scaled once), no extra cost per step, and a particle stepping past
a wall is clipped to it as the jitter's always were. So the belief an agent reads between steps *is*
the predicted belief of the next reading: ``predicted_particles_mm`` returns it unchanged, and min-var
votes on the predicted belief (the paper's Algorithm 1, one reading ahead, with the motion model).

**The swimmer filter** (``motion_model="swimmer"``): a searcher's belief over prey that keeps its course
should carry the prey's velocity, not only its position (Carbone et al., arXiv 2604.13121, 2026: the
belief over a moving target's position and velocity in olfactory pursuit). Each particle is a hypothesis
(x, y, speed, heading) — mm, mm, mm per reading, rad — the position in ``State.particles_mm``, the speed
and heading in ``State.shape_particles`` (``particle_dims`` = 4), as the unknown target carries its radius
and contrast. At reset every particle's speed is drawn uniform in ``motion_speed_mm``'s (low, high) (None:
every particle has the target's ``target_speed_mm``, no draw) and its heading uniform in [−π, π). Before
each reading, when the target steps, every particle steps by its velocity — ``speed``·(cos, sin)(heading)
— reflected at the walls as the target is (:func:`reflect`, the heading mirrored with each wall,
:func:`velocity_step`). The update is the unknown target's two-pass one: the log-likelihood of the
positions (the calibrated kernel's, :func:`~electroloc_gym.kernels.calibrated_log_likelihood`, or the
analytic model's), the systematic-resampling indices, then position, speed and heading resampled with the
same indices and jittered (:func:`~electroloc_gym.kernels.jitter_resampled`): the position by the paper's
N(0, 1 mm²) per axis, clipped to the box; the speed by :data:`SPEED_JITTER_MM` (none when the prior is one
speed), clipped to the prior's range; the heading by N(0, σ_turn²) with σ_turn = ``motion_turn_std_rad``
(None: the target's ``turn_std_rad``), unclipped. That heading jitter *is* the swimmer's turn (the turn
before its next step, as the true swimmer turns then steps), taken where the filter already draws a
normal per particle and coordinate: the (2 + 2)·M jitter draws of the step, as the unknown target's. The
belief an agent reads is the posterior over the target now, its headings already turned for the next
step; ``predicted_particles_mm`` steps the hypotheses (M, 4) by their velocities (the same
:func:`velocity_step`), and min-var and pursuit act on that prediction. The cosine and sine are a fixed
polynomial of exact operations (:func:`sin_cos`), never numpy's ``sin``/``cos``, whose SIMD paths differ
by CPU. The velocity's belief is reported: info ``velocity_mean_mm`` (the particles' mean velocity (vx,
vy), mm per reading) and ``velocity_spread_mm`` (√(var vx + var vy)), and with ``observation="belief"``
four entries appended to the 81 (81–82: the mean velocity, 83–84: its std per axis, each over the speed
prior's upper end — 1 mm per reading when that is 0 — clipped to [−1, 1]; :data:`VELOCITY_OBS_DIM`).

**Draw order.** Reset: ElectroLoc-v0's (condition, calibration, target, start, particles), then the
swimmer's heading (1 uniform; the random walk draws none), then with ``motion_model="swimmer"`` the
particles' speeds (M uniforms; none when ``motion_speed_mm`` is None) and headings (M uniforms). Every
step, before the step's reading draws: the target's step (2 normals for the random walk, 1 for the
swimmer's turn); the particles' steps draw nothing. The step's jitter draws are 2·M indices, (2 + 2)·M
with ``motion_model="swimmer"`` (x, y of particle j at 2j, 2j + 1; speed, heading at 2M + 2j, 2M + 2j + 1).

**Episode, metric, reward.** An episode is ``max_observations`` readings (default 70; never
terminated: there is no "found" for prey that keeps moving). The first half is the paper's whole
localisation budget (35 readings, §5.4), in which min-var localises a still target in 95 % of the
paper's trials; the **tracking error** is the mean distance from the belief's mean to the true target
over the second half's readings (info ``tracking_error_mm``, the running mean of the second half so
far; before it, the current error). **Capture**: the carriage within :data:`CAPTURE_DISTANCE_MM` (10 mm)
of the target after the last reading (info ``captured``, ``carriage_distance_mm``): one carriage move
(10 mm per axis, §4.1.3) and less than the smaller sphere's diameter (12.7 mm) — a hunter that close
strikes in one move. Reward: −(the belief mean's distance to the target)/10 mm per reading (ground
truth, as the info's error: for learning and evaluation, never for the agent's decisions).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.params import EnvParams, LocalizeOptions
from electroloc_gym.contract.task_spec import (
    Choice,
    Column,
    CurvePanel,
    Numbers,
    Optional,
    Real,
    RecordField,
    Score,
    Table,
    TaskMetrics,
    TaskState,
    option,
    state_array,
)
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.state import State as SimState
from electroloc_gym.kernels import (
    calibrated_log_likelihood,
    jitter_resampled,
    resample_indices,
    row_sums,
)
from electroloc_gym.utils.intervals import wilson_interval

__all__ = [
    "TrackTask",
    "TrackOptions",
    "TrackState",
    "TARGET_MOTIONS",
    "MOTION_MODELS",
    "MAX_TARGET_SPEED_MM",
    "MOTION_OPTION_SCOPES",
    "CAPTURE_DISTANCE_MM",
    "TRACK_EPISODE_READINGS",
    "TRACK_INFO_KEYS",
    "TRACK_RECORD_KEYS",
    "TRACK_METRICS",
    "CAPTURE_CONFIDENCE",
    "tracking_statistics",
    "reflect",
    "sin_cos",
    "velocity_step",
    "PAPER_JITTER_STD_MM",
    "VELOCITY_MODEL",
    "SPEED_JITTER_MM",
    "VELOCITY_INFO_KEYS",
    "VELOCITY_OBS_DIM",
]

#: The capture distance: the carriage within this distance of the target at the end is a capture, mm.
CAPTURE_DISTANCE_MM = 10.0
#: Readings per episode (``max_observations``): twice the paper's cap of 35 (§5.4); the second half is scored.
TRACK_EPISODE_READINGS = 70
#: The info keys the track env adds: the true target now (mm), the second half's mean tracking error so
#: far (mm), the carriage's distance to the target (mm), and whether it is within the capture distance.
TRACK_INFO_KEYS = ("target_mm", "tracking_error_mm", "carriage_distance_mm", "captured")
#: What a benchmark record keeps of the final info.
TRACK_RECORD_KEYS = ("tracking_error_mm", "carriage_distance_mm", "captured")
#: The paper's jitter after resampling, per axis, mm (§4.1.2; the kernels' normal table has unit std).
PAPER_JITTER_STD_MM = 1.0
_SQRT_HALF = np.sqrt(0.5)

#: The moving target's true motion: Gaussian steps, or a constant-speed swimmer whose heading turns by
#: Gaussian increments.
TARGET_MOTIONS = ("random_walk", "swimmer")
#: The motion model the moving target's filter is told (its prediction before every update): a random walk,
#: none (a static target, the paper's filter), or the swimmer's own (every particle carries a velocity).
MOTION_MODELS = ("random_walk", "static", "swimmer")
#: The filter's motion model whose particles carry a velocity (speed, heading) beside their position.
VELOCITY_MODEL = "swimmer"
#: The jitter of a particle's speed after resampling, mm per reading, when the speed prior is a range (none
#: when it is one speed): a twentieth of the default speed, so that resampling keeps the speeds the
#: readings favour without smearing them; the heading's jitter is the filter's turn.
SPEED_JITTER_MM = 0.05
#: The info keys the swimmer filter adds: the particles' mean velocity (vx, vy) and its spread
#: √(var vx + var vy), mm per reading.
VELOCITY_INFO_KEYS = ("velocity_mean_mm", "velocity_spread_mm")
#: The belief observation's entries the swimmer filter appends (81–84): the mean velocity (x, y) and its std
#: (x, y), over the speed prior's upper end (1 mm per reading when that is 0), clipped to [−1, 1].
VELOCITY_OBS_DIM = 4
#: The largest target speed and filter step, mm per reading: twice the carriage's largest move per axis.
MAX_TARGET_SPEED_MM = 20.0
#: The moving target's options that act under one value of another option only: (option, the other option,
#: the value it acts under, why it does not under the other). Such an option set away from its default
#: while the other option has another value would be silently ignored: one ValueError names both.
MOTION_OPTION_SCOPES = (
    ("turn_std_rad", "target_motion", "swimmer", "the random walk has no heading"),
    ("motion_step_mm", "motion_model", "random_walk", "only the random-walk filter takes a Gaussian step"),
    ("motion_turn_std_rad", "motion_model", "swimmer", "only the swimmer filter's particles have a heading"),
    ("motion_speed_mm", "motion_model", "swimmer", "only the swimmer filter's particles have a speed"),
)
_SPEED = Real(0.0, MAX_TARGET_SPEED_MM, inclusive=True)
_TURN = Real(0.0, math.pi, inclusive=True)


def _speed_range(name: str, value: Any) -> tuple[float, ...]:
    """(low, high) speeds in [0, :data:`MAX_TARGET_SPEED_MM`] mm per reading, low ≤ high."""
    r = Numbers(2, 0.0, MAX_TARGET_SPEED_MM, " mm")(name, value)
    if r[0] > r[1]:
        raise ValueError(f"{name} must be (low, high) with low ≤ high, got {r!r}")
    return r


@dataclass(frozen=True)
class TrackOptions(LocalizeOptions):
    """ElectroLocTrack-v0's own options, beside the tank's (:class:`~electroloc_gym.contract.params.LocalizeOptions`).

    Attributes:
        target_motion: the target's true motion, ``"random_walk"`` or ``"swimmer"`` (:data:`TARGET_MOTIONS`).
        target_speed_mm: its speed, mm per reading, in [0, 20]: the random walk's RMS step (per-axis std
            ``target_speed_mm``/√2), the swimmer's constant step length.
        turn_std_rad: ``"swimmer"``: std of the heading's change per reading, rad, in [0, π] (another value
            than the default 0.5 with ``target_motion="random_walk"`` is refused: :data:`MOTION_OPTION_SCOPES`).
        motion_model: the filter's motion model, ``"random_walk"`` (every particle takes a Gaussian step
            before each update), ``"static"`` (none: the paper's filter) or ``"swimmer"`` (every particle
            carries a speed and a heading and steps by them; module docstring) (:data:`MOTION_MODELS`).
        motion_step_mm: the filter's random-walk RMS step, mm per reading, in [0, 20], or None: the target's
            ``target_speed_mm`` (a different value is a model mismatch); a number with another ``motion_model``
            than ``"random_walk"`` is refused (:data:`MOTION_OPTION_SCOPES`).
        motion_turn_std_rad: the swimmer filter's turn per reading (std of the heading's jitter), rad, in
            [0, π], or None: the target's ``turn_std_rad``; only with ``motion_model="swimmer"``.
        motion_speed_mm: the swimmer filter's speed prior, (low, high) mm per reading in [0, 20] with
            low ≤ high (each particle's speed uniform in it at reset), or None: every particle has the
            target's ``target_speed_mm``; only with ``motion_model="swimmer"``.
    """

    target_motion: str = option("swimmer", doc="the target's true motion", check=Choice(TARGET_MOTIONS))
    target_speed_mm: float = option(1.0, doc="the target's speed per reading", check=_SPEED, unit="mm")
    turn_std_rad: float = option(0.5, doc="the swimmer's turn per reading (std)", check=_TURN, unit="rad")
    motion_model: str = option("random_walk", doc="the filter's motion model", check=Choice(MOTION_MODELS), agent=True)
    motion_step_mm: float | None = option(
        None,
        doc="the filter's RMS step per reading (None: the target's speed)",
        check=Optional(_SPEED),
        unit="mm",
        agent=True,
    )
    motion_turn_std_rad: float | None = option(
        None,
        doc="the swimmer filter's turn per reading (std; None: turn_std_rad)",
        check=Optional(_TURN),
        unit="rad",
        agent=True,
    )
    motion_speed_mm: Any = option(
        None,
        doc="the swimmer filter's speed prior per reading: (low, high), or None: target_speed_mm",
        check=Optional(_speed_range),
        unit="mm",
        agent=True,
    )

    def check(self) -> None:
        """The tank's checks, then refuse an option of :data:`MOTION_OPTION_SCOPES` set away from its default
        while the option it depends on has a value under which it does nothing (one ValueError naming both and
        what is allowed).
        """
        super().check()
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        for name, mode, acts_under, why in MOTION_OPTION_SCOPES:
            value, default, mode_value = getattr(self, name), defaults[name], getattr(self, mode)
            if mode_value != acts_under and value != default:
                keep = "None" if default is None else f"at its default {default!r}"
                raise ValueError(
                    f"{name} applies only when {mode} is {acts_under!r} ({why}); got {mode}={mode_value!r} "
                    f"with {name}={value!r}: leave {name} {keep} or choose {mode}={acts_under!r}"
                )


@dataclass
class TrackState(TaskState):
    """The moving target's per-env arrays.

    Attributes:
        target_heading_rad: (N,) the swimmer's heading, rad.
        track_error_sum_mm: (N,) the tracking errors summed over the episode's second half, mm.
        track_error_count: (N,) the readings in that sum.
        velocity_mean_mm: (N, 2) the swimmer filter's mean particle velocity (vx, vy), mm per reading (0 with
            the other models).
        velocity_std_mm: (N, 2) its std per axis, mm per reading.
    """

    target_heading_rad: NDArray[np.float64] = state_array(np.float64)
    track_error_sum_mm: NDArray[np.float64] = state_array(np.float64)
    track_error_count: NDArray[np.int64] = state_array(np.int64)
    velocity_mean_mm: NDArray[np.float64] = state_array(np.float64, (2,))
    velocity_std_mm: NDArray[np.float64] = state_array(np.float64, (2,))


def reflect(x: NDArray, half: Any) -> tuple[NDArray, NDArray[np.bool_]]:
    """``x`` folded into [−half, half] as a straight path from inside the box is by its walls, and where it
    was reflected an odd number of times (a swimmer's heading is mirrored once per wall).

    The fold is the triangle wave of period 4·half (mirror at every wall crossed): for |x| ≤ 3·half (a step
    shorter than 2·half from inside the box) it is the single fold at the crossed wall, ``2·half − x`` or
    ``−2·half − x``, bit for bit; farther out, ``x`` is first brought into [−half, 3·half) by the period
    (``mod(x + half, 4·half) − half``), an even number of reflections, then folded once. The result is
    clipped to the box, which changes nothing but a last-digit overshoot of a wall. Elementwise, in
    ``x``'s precision; ``half`` > 0, broadcastable against ``x``.
    """
    period = 4 * half
    far = np.abs(x) > 3 * half
    x = np.where(far, np.mod(x + half, period) - half, x)
    over, under = x > half, x < -half
    out = np.where(over, 2 * half - x, np.where(under, -2 * half - x, x))
    return np.clip(out, -half, half), over | under


_TWO_PI = 2.0 * math.pi
_HALF_PI = 0.5 * math.pi
#: Taylor coefficients of sin t / t and cos t in t² on [−π/4, π/4] (to t¹⁵, t¹⁶: error below 10⁻¹⁵).
_SIN_COEFFS = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(8))
_COS_COEFFS = tuple((-1) ** k / math.factorial(2 * k) for k in range(9))


def _horner(coeffs: tuple[float, ...], t2: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.full_like(t2, coeffs[-1])
    for c in coeffs[-2::-1]:
        out = out * t2 + c
    return out


def sin_cos(angle_rad: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(sin, cos) of ``angle_rad``, float64, by exact elementwise operations only (+, −, ×, ÷, rint,
    comparisons): the quadrant q = rint(angle/(π/2)), then the Taylor polynomials of the remainder
    t = angle − q·π/2 ∈ [−π/4, π/4] (Horner, fixed order), swapped and signed by q mod 4. Within 10⁻¹⁵ of
    ``np.sin``/``np.cos`` for |angle| ≤ 100 rad, and the same bits on every CPU (numpy's own ``sin``/``cos``
    dispatch to SIMD paths that differ by CPU; docs/design.md, "Results that do not depend on the CPU").
    """
    a = np.asarray(angle_rad, dtype=np.float64)
    q = np.rint(a / _HALF_PI)
    t = a - q * _HALF_PI
    t2 = t * t
    s = _horner(_SIN_COEFFS, t2) * t
    c = _horner(_COS_COEFFS, t2)
    r = np.mod(q, 4.0)
    sin = np.where(r == 0, s, np.where(r == 1, c, np.where(r == 2, -s, -c)))
    cos = np.where(r == 0, c, np.where(r == 1, -s, np.where(r == 2, -c, s)))
    return sin, cos


def velocity_step(
    x_mm: Any, y_mm: Any, speed_mm: Any, heading_rad: Any, half_mm: Any
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """One step of the swimmer filter's hypotheses (module docstring): each position moves by its velocity
    ``speed``·(cos, sin)(heading) (:func:`sin_cos`), folded into [−half, half]² by :func:`reflect`, the heading
    mirrored with each wall (x wall θ → π − θ, y wall θ → −θ) and wrapped to [−π, π] (θ − 2π·rint(θ/2π)).

    Elementwise in float64 (the arguments broadcast; ``half_mm`` > 0); returns (x, y, heading), which the
    engine stores as float32. The engine's particles and the agents' predictions (``predicted_particles_mm``)
    both step through this function, so a prediction equals the engine's step bit for bit.
    """
    sin, cos = sin_cos(heading_rad)
    speed = np.asarray(speed_mm, dtype=np.float64)
    half = np.asarray(half_mm, dtype=np.float64)
    x, x_flipped = reflect(np.asarray(x_mm, dtype=np.float64) + speed * cos, half)
    y, y_flipped = reflect(np.asarray(y_mm, dtype=np.float64) + speed * sin, half)
    h = np.asarray(heading_rad, dtype=np.float64)
    h = np.where(x_flipped, math.pi - h, h)
    h = np.where(y_flipped, -h, h)
    return x, y, h - _TWO_PI * np.rint(h / _TWO_PI)


class TrackTask(LocalizeTask):
    """The env ElectroLocTrack-v0: what it simulates, its spaces, reward, episode end, info and arguments.

    ## Description

    ElectroLoc-v0 with prey that moves: the sphere of the episode's condition swims in its horizontal
    plane below the carriage while the robot reads, and the particle filter predicts every particle's
    step with a motion model before each update. Weakly electric fish hunt water fleas this way at
    night (Nelson & MacIver, J. Exp. Biol. 1999); the paper's target sits still (Solberg, Lynch &
    MacIver, IJRR 2008). The agent keeps the belief on the target and the carriage near it.

    ## Action Space, Observation Space

    As ElectroLoc-v0 (``Box(-1, 1, (2,))`` × 10 mm or ``Discrete(9)``; 81 belief features or 3 raw).
    Entry 11 (readings used / cap) tells the agent how far the episode has run. With
    ``motion_model="swimmer"`` the belief observation has 85 entries: 81–82 the belief's mean velocity
    (x, y), 83–84 its std per axis, each over the speed prior's upper end (1 mm per reading when that is
    0), clipped to [−1, 1] (the raw observation is unchanged).

    ## Rewards

    −(distance from the belief's mean to the true target)/10 mm after every reading (ground truth:
    the env's, for learning; the agent never reads it).

    ## Starting State

    As ElectroLoc-v0 (the target at the condition's ``target_xy_mm`` or, with ``randomize_target``,
    uniform in the start box; the carriage uniform in the start box; the particles uniform over the
    allowed box); the swimmer's heading uniform in [0, 2π); with ``motion_model="swimmer"`` each particle's
    speed uniform in ``motion_speed_mm`` (or the target's speed) and its heading uniform in [−π, π).

    ## Episode End

    * Termination: never (prey that keeps moving is never "found").
    * Truncation: ``max_observations`` readings (default 70: the paper's cap of 35 to localise, then
      35 scored readings of tracking), or ``max_episode_steps`` steps.

    ## Info

    ElectroLoc-v0's keys (``error_mm`` is the current tracking error) plus ``target_mm`` (the true
    target now), ``tracking_error_mm`` (mean error over the second half's readings so far: at the end,
    the episode's tracking metric; before the second half, the current error),
    ``carriage_distance_mm`` (carriage to target) and ``captured`` (that distance ≤ 10 mm) — ground
    truth, for evaluation. With ``motion_model="swimmer"`` also ``velocity_mean_mm`` (the particles' mean
    velocity (vx, vy), mm per reading) and ``velocity_spread_mm`` (√(var vx + var vy), mm per reading):
    the belief's, not the truth.

    ## Accessors

    As ElectroLoc-v0. With the random walk the belief between steps is already the predicted belief of the
    next reading (the motion model's step is taken in the filter's jitter after resampling), so
    ``predicted_particles_mm`` returns the hypotheses unchanged and min-var votes on the predicted belief.
    With ``motion_model="swimmer"`` ``belief.particles`` is (M, 4) — x, y (mm), speed (mm per reading),
    heading (rad) — and ``predicted_particles_mm`` steps each (M, 4) hypothesis by its velocity, as the
    engine does before the next reading. ``target_mm`` is the target now (ground truth).

    ## Arguments

    ```python
    gym.make("ElectroLocTrack-v0", condition="fresh-steel-12.7", target_motion="swimmer",
             target_speed_mm=1.0, turn_std_rad=0.5, motion_model="random_walk", motion_step_mm=None,
             motion_turn_std_rad=None, motion_speed_mm=None,
             observation="belief", sensor_model="calibrated", n_particles=2500, max_observations=70,
             success_spread_mm=10.0, signal=<get_condition's default>, action_type="continuous",
             randomize_target=False, calibration_seed=None, calibration=DEFAULT_CALIBRATION,
             max_episode_steps=None, render_mode=None)
    ```

    * ``target_motion``: ``"random_walk"`` (Gaussian steps, RMS ``target_speed_mm`` per reading) or
      ``"swimmer"`` (steps of exactly ``target_speed_mm`` along a heading that turns by N(0,
      ``turn_std_rad``²) per reading); both reflect at the walls of the allowed box.
    * ``target_speed_mm``: mm per reading, [0, 20]; default 1 (prey 2–5 % as fast as its hunter, scaled
      to the carriage's 10 mm per reading and doubled, :mod:`~electroloc_gym.engines.numba_core.track_task`).
    * ``turn_std_rad``: the swimmer's turn std per reading, rad, [0, π] (the random walk has no heading:
      another value than 0.5 with ``target_motion="random_walk"`` is refused).
    * ``motion_model``: what the filter is told: ``"random_walk"`` (each particle a Gaussian step of RMS
      ``motion_step_mm`` before each update: the jitter after resampling grows from the paper's 1 mm to
      √(1 mm² + ``motion_step_mm``²/2) per axis), ``"static"`` (the paper's filter) or ``"swimmer"`` (the
      swimmer's own model: each particle carries a speed and a heading, steps by them before each update,
      reflected at the walls, and the jitter after resampling turns its heading by N(0, σ_turn²)).
    * ``motion_step_mm``: the filter's RMS step, mm per reading, [0, 20], or None: ``target_speed_mm``
      (another value is a model mismatch; a number with another ``motion_model`` is refused).
    * ``motion_turn_std_rad``: the swimmer filter's σ_turn, rad, [0, π], or None: ``turn_std_rad``
      (``motion_model="swimmer"`` only).
    * ``motion_speed_mm``: the swimmer filter's speed prior, (low, high) mm per reading in [0, 20] with
      low ≤ high (uniform at reset; jittered by 0.05 mm after resampling), or None: every particle has
      ``target_speed_mm`` (``motion_model="swimmer"`` only).

    Every argument is a field of :class:`electroloc_gym.contract.params.EnvParams`; any other argument, a
    value out of range, or two arguments that contradict each other, is one ValueError naming them and what
    is allowed.

    ## Version History

    * v0: initial version.
    """

    info_keys = TRACK_INFO_KEYS
    Options = TrackOptions
    State = TrackState
    options: TrackOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        o = self.options = params.options_as(TrackOptions)
        self.swimmer = o.target_motion == "swimmer"
        #: The random walk's per-axis std of the target's step, mm.
        self.target_std_mm = o.target_speed_mm * _SQRT_HALF
        step = o.target_speed_mm if o.motion_step_mm is None else o.motion_step_mm
        #: The filter's per-axis Gaussian step std σ_f, mm (0: no Gaussian step; the random walk's only).
        self.filter_std_mm = step * _SQRT_HALF if o.motion_model == "random_walk" else 0.0
        #: The jitter's per-axis std after resampling: √(1 mm² + σ_f²), mm (module docstring).
        self.jitter_std_mm = float(np.hypot(PAPER_JITTER_STD_MM, self.filter_std_mm))
        self._half_readings = params.max_observations // 2
        self._jitter_table: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        #: The swimmer filter: every particle carries a speed and a heading (module docstring).
        self.velocity = o.motion_model == VELOCITY_MODEL
        if self.velocity:
            self.particle_dims = 4  # x, y, speed, heading: State.shape_particles holds speed and heading
            self.info_keys = TRACK_INFO_KEYS + VELOCITY_INFO_KEYS
            low, high = (o.target_speed_mm,) * 2 if o.motion_speed_mm is None else o.motion_speed_mm
            #: The speed prior's (low, high), mm per reading (the speeds' clip after the jitter).
            self.speed_range_mm = (float(low), float(high))
            #: The filter's turn per reading (the heading's jitter std), rad.
            self.filter_turn_std_rad = o.turn_std_rad if o.motion_turn_std_rad is None else o.motion_turn_std_rad
            self._velocity_jitter = np.array(
                [
                    PAPER_JITTER_STD_MM,
                    PAPER_JITTER_STD_MM,
                    SPEED_JITTER_MM if high > low else 0.0,
                    self.filter_turn_std_rad,
                ],
                dtype=np.float32,
            )
            #: The observation's velocity scale: the speed prior's upper end (1 mm per reading when it is 0).
            self.velocity_scale_mm = float(high) if high > 0 else 1.0
            if params.observation == "belief":
                self.obs_dim += VELOCITY_OBS_DIM

    # ---- the episode ------------------------------------------------------------------------------
    def begin_episode(self, state: SimState, i: int, g: np.random.Generator) -> None:
        """ElectroLoc-v0's reset draws, then the swimmer's heading (1 uniform in [0, 2π)), then with the swimmer
        filter the particles' speeds (M uniforms in ``motion_speed_mm``; none when it is None) and headings
        (M uniforms in [−π, π)).
        """
        super().begin_episode(state, i, g)
        own = TrackState.of(state)  # the step set its rows to 0 (TaskState.reset_rows): no error summed yet
        own.target_heading_rad[i] = g.uniform(0.0, 2 * np.pi) if self.swimmer else 0.0
        if self.velocity:
            m = state.n_particles
            low, high = self.speed_range_mm
            state.shape_particles[i, 0] = low if self.options.motion_speed_mm is None else g.uniform(low, high, m)
            state.shape_particles[i, 1] = g.uniform(-np.pi, np.pi, m)
            self._velocity_statistics(state, np.array([i]))

    def move(self, state: SimState, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The carriage moves (truncated at the walls), then the target takes its step (reflected at the
        walls), from each env's generator.
        """
        super().move(state, ids, moves_mm)
        idx = np.arange(state.num_envs)[ids]
        if idx.size == 0:
            return
        speed = self.options.target_speed_mm
        own = TrackState.of(state)
        steps = np.empty((idx.size, 2))
        for j, i in enumerate(idx.tolist()):
            g = state.gens[i]
            assert g is not None  # reset made every env's generator
            if self.swimmer:  # scalar libm per env (docs/design.md, "Results that do not depend on the CPU")
                h = float(own.target_heading_rad[i]) + float(g.normal(0.0, self.options.turn_std_rad))
                own.target_heading_rad[i] = h
                steps[j] = speed * math.cos(h), speed * math.sin(h)
            else:
                steps[j] = g.normal(0.0, self.target_std_mm, 2)
        half = state.half_mm[idx][:, None]
        target, flipped = reflect(state.target_mm[idx] + steps, half)
        state.target_mm[idx] = target
        if self.swimmer:  # a reflection mirrors the heading: x wall θ → π − θ, y wall θ → −θ
            h = own.target_heading_rad[idx]
            h = np.where(flipped[:, 0], np.pi - h, h)
            own.target_heading_rad[idx] = np.where(flipped[:, 1], -h, h)
        if self.velocity:  # the swimmer filter's particles step by their velocities (no draw)
            xy, vel = state.particles_mm[idx], state.shape_particles[idx]
            x, y, h = velocity_step(xy[:, 0], xy[:, 1], vel[:, 0], vel[:, 1], state.half_mm[idx][:, None])
            xy[:, 0], xy[:, 1], vel[:, 1] = x, y, h
            state.particles_mm[idx], state.shape_particles[idx] = xy, vel

    def assimilate(
        self,
        state: SimState,
        ids: NDArray[np.intp],
        reading: NDArray[np.float64],
        u0: NDArray[np.float64],
        jitter: NDArray[np.uint16],
        normal_table: NDArray[np.float32],
    ) -> int:
        """ElectroLoc-v0's update with the motion model's step in the jitter (the normal table scaled to
        √(1 mm² + σ_f²), module docstring) — with the swimmer filter the update of (x, y, speed, heading)
        hypotheses (:meth:`_assimilate_velocity`) —, then the second half's tracking error accumulated
        (readings > T/2).
        """
        if self.velocity:
            bad = self._assimilate_velocity(state, ids, reading, u0, jitter, normal_table)
        else:
            if self.filter_std_mm > 0:
                if self._jitter_table is None or self._jitter_table[0] is not normal_table:
                    self._jitter_table = (normal_table, normal_table * np.float32(self.jitter_std_mm))
                normal_table = self._jitter_table[1]
            bad = super().assimilate(state, ids, reading, u0, jitter, normal_table)
        if bad < 0:
            own = TrackState.of(state)
            second = state.n_observations[ids] > self._half_readings
            own.track_error_sum_mm[ids] += np.where(second, self._error_mm(state, ids), 0.0)
            own.track_error_count[ids] += second
        return bad

    def _assimilate_velocity(
        self,
        state: SimState,
        ids: NDArray[np.intp],
        reading: NDArray[np.float64],
        u0: NDArray[np.float64],
        jitter: NDArray[np.uint16],
        normal_table: NDArray[np.float32],
    ) -> int:
        """The swimmer filter's update (module docstring): the positions' log-likelihoods, the resampling
        indices, then (x, y, speed, heading) resampled with them, jittered and clipped (the unknown target's
        two passes), then the statistics; returns −1 or the first env whose log-likelihood is NaN.
        """
        s = state
        k, m = len(ids), s.n_particles
        xy = s.particles_mm[ids]
        origin = self.histogram_origin(s, ids)
        if self.calibrated:
            ll = np.empty((k, m), dtype=np.float32)
            calibrated_log_likelihood(
                xy,
                origin,
                self.offset_sign,
                s.grid_lo_mm[ids],
                s.grid_inv_mm[ids],
                s.grid_cells[ids],
                self.table_rows(s, ids),
                s.table,
                reading.astype(np.float32),
                ll,
            )
        else:
            ll = self._analytic_log_likelihood(s, ids, xy, origin, reading)
        idx = np.empty((k, m), dtype=np.int64)
        bad = resample_indices(ll, u0, idx)
        if bad >= 0:
            return int(bad)
        cloud = np.concatenate([xy, s.shape_particles[ids]], axis=1)  # (k, 4, M): x, y, speed, heading
        half = s.half_mm[ids].astype(np.float32)
        lo = np.empty((k, 4), dtype=np.float32)
        hi = np.empty((k, 4), dtype=np.float32)
        lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1] = -half, -half, half, half
        lo[:, 2], hi[:, 2] = self.speed_range_mm
        lo[:, 3], hi[:, 3] = -np.inf, np.inf
        out = np.empty_like(cloud)
        jitter_resampled(idx, cloud, jitter[:k], normal_table, self._velocity_jitter, lo, hi, out)
        s.particles_mm[ids] = out[:, :2]
        s.shape_particles[ids] = out[:, 2:]
        self.update_statistics(s, ids)
        return -1

    def update_statistics(self, state: SimState, ids: NDArray[np.intp] | slice) -> None:
        """The x–y statistics, and the swimmer filter's velocity statistics (:meth:`_velocity_statistics`)."""
        super().update_statistics(state, ids)
        if self.velocity:
            self._velocity_statistics(state, np.arange(state.num_envs)[ids])

    @staticmethod
    def _velocity_statistics(state: SimState, ids: NDArray[np.intp]) -> None:
        """The particles' mean velocity and its std per axis (fixed-order sums, :func:`sin_cos`) of envs ``ids``."""
        m = state.n_particles
        own = TrackState.of(state)
        speed = state.shape_particles[ids, 0].astype(np.float64)
        sin, cos = sin_cos(state.shape_particles[ids, 1])
        total = np.empty(len(ids))
        for d, v in enumerate((speed * cos, speed * sin)):
            row_sums(v, total)
            mu = total / m
            dev = v - mu[:, None]
            row_sums(dev * dev, total)
            own.velocity_mean_mm[ids, d] = mu
            own.velocity_std_mm[ids, d] = np.sqrt(total / m)

    # ---- what agents predict ----------------------------------------------------------------------
    def _predicted(self, state: SimState, i: int, particles: NDArray) -> NDArray:
        """(…, M, 4) hypotheses after one step of their velocities (:func:`velocity_step`), in their dtype."""
        p = np.asarray(particles)
        x, y, h = velocity_step(p[..., 0], p[..., 1], p[..., 2], p[..., 3], state.half_mm[i])
        out = p.copy()
        out[..., 0], out[..., 1], out[..., 3] = x, y, h
        return out

    def particles_after_move(self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """The hypotheses when the next reading is taken, once per move: unchanged (the random walk's step is
        already in the cloud; the static target does not move), or with the swimmer filter each (x, y, speed,
        heading) stepped by its velocity (the engine's own step).
        """
        if not self.velocity:
            return super().particles_after_move(state, i, particles, moves_mm)
        p = self._predicted(state, i, particles)
        return np.broadcast_to(p, moves_mm.shape[:-1] + p.shape).copy()

    def offsets_after_move(self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Target hypothesis when the next reading is taken (:meth:`particles_after_move`) − the carriage after
        the move.
        """
        if self.velocity:
            particles = self._predicted(state, i, particles)
        return super().offsets_after_move(state, i, particles, moves_mm)

    # ---- reward, flags, info ----------------------------------------------------------------------
    @staticmethod
    def _error_mm(state: SimState, sel: Any) -> NDArray[np.float64]:
        d = state.mean_mm[sel] - state.target_mm[sel]
        return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])

    def rewards(self, state: SimState) -> NDArray[np.float64]:
        """(N,) −(belief mean's distance to the target)/:data:`CAPTURE_DISTANCE_MM` after this step's reading."""
        return -self._error_mm(state, slice(None)) / CAPTURE_DISTANCE_MM

    def flags(self, state: SimState) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Never terminated; truncated after ``max_observations`` readings (or ``max_episode_steps`` steps)."""
        p = self.params
        truncated = state.n_observations >= p.max_observations
        if p.max_episode_steps is not None:
            truncated = truncated | (state.elapsed >= p.max_episode_steps)
        return np.zeros(state.num_envs, dtype=bool), truncated

    def observation(self, state: SimState, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """ElectroLoc-v0's observation; with the swimmer filter and ``observation="belief"``, the velocity's
        four entries appended (:data:`VELOCITY_OBS_DIM`: the mean velocity and its std per axis, over the
        speed prior's upper end, clipped to [−1, 1]).
        """
        obs = super().observation(state, ids)
        if not self.velocity or self.params.observation != "belief":
            return obs
        sel = slice(None) if ids is None else ids
        own = TrackState.of(state)
        v = np.concatenate([own.velocity_mean_mm[sel], own.velocity_std_mm[sel]], axis=1) / self.velocity_scale_mm
        return np.concatenate([obs, np.clip(v, -1.0, 1.0).astype(np.float32)], axis=1)

    def task_info(self, state: SimState, sel: Any) -> dict[str, NDArray[Any]]:
        """:data:`TRACK_INFO_KEYS` of envs ``sel`` (and :data:`VELOCITY_INFO_KEYS` with the swimmer filter)."""
        own = TrackState.of(state)
        count = own.track_error_count[sel]
        now = self._error_mm(state, sel)
        mean = np.where(count > 0, own.track_error_sum_mm[sel] / np.maximum(count, 1), now)
        d = state.position_mm[sel] - state.target_mm[sel]
        dist = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
        out = {
            "target_mm": state.target_mm[sel].copy(),
            "tracking_error_mm": mean,
            "carriage_distance_mm": dist,
            "captured": dist <= CAPTURE_DISTANCE_MM,
        }
        if self.velocity:
            std = own.velocity_std_mm[sel]
            out["velocity_mean_mm"] = own.velocity_mean_mm[sel].copy()
            out["velocity_spread_mm"] = np.sqrt(std[:, 0] * std[:, 0] + std[:, 1] * std[:, 1])
        return out


# ---- what the layers above the engine report of the moving target ----------------------------------------
#: The capture rate's interval: a 95 % Wilson score interval.
CAPTURE_CONFIDENCE = 0.95
_DISTANCE_BOUND_MM = 2000.0  # the largest distance a record holds (the tank is well under a metre across)


def _values(values: Any) -> NDArray[np.float64]:
    return np.asarray([float(v) for v in values if v is not None], dtype=float)


def tracking_statistics(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The tracking over a group of trial records (empty when none holds tracking results): the tracking
    error's median, interquartile range and mean, the carriage's median distance at the end, and the capture
    rate with its 95 % Wilson interval (:data:`CAPTURE_CONFIDENCE`).
    """
    results = [r["shape"] for r in records if r.get("shape") and "tracking_error_mm" in r["shape"]]
    if not results:
        return {}
    err = _values(s["tracking_error_mm"] for s in results)
    captures = sum(bool(s["captured"]) for s in results)
    lo, hi = wilson_interval(captures, len(results), CAPTURE_CONFIDENCE)
    q25, q50, q75 = (float(q) for q in np.quantile(err, [0.25, 0.5, 0.75]))
    distance = _values(s["carriage_distance_mm"] for s in results)
    return {
        "tracking_trials": len(results),
        "tracking_error_median_mm": q50,
        "tracking_error_q25_mm": q25,
        "tracking_error_q75_mm": q75,
        "tracking_error_mean_mm": float(err.mean()),
        "carriage_distance_median_mm": float(np.median(distance)) if distance.size else None,
        "captures": captures,
        "capture_rate": captures / len(results),
        "capture_rate_lo": lo,
        "capture_rate_hi": hi,
    }


def _captured_of_info(info: Mapping[str, Any]) -> float:
    return float(bool(info["captured"]))


def _captured_of_record(record: Mapping[str, Any]) -> float:
    return float(bool(record["shape"]["captured"]))


def _tracking_outcome(info: Mapping[str, Any]) -> str:
    what = "captured" if bool(info["captured"]) else "not captured"
    return f"{what}, tracking error {float(info['tracking_error_mm']):.1f} mm"


def _tracking_errors(infos: Sequence[Mapping[str, Any]]) -> NDArray[np.float64]:
    return np.asarray([float(i["tracking_error_mm"]) for i in infos], dtype=float)


#: What ElectroLocTrack-v0 reports (:class:`~electroloc_gym.contract.task_spec.TaskMetrics`): no success
#: criterion (every trial runs its readings); ranked by the mean tracking error, with the capture rate.
TRACK_METRICS = TaskMetrics(
    record=(
        RecordField(
            "tracking_error_mm",
            "the belief mean's mean distance to the target over the second half",
            "mm",
            low=0.0,
            high=_DISTANCE_BOUND_MM,
        ),
        RecordField(
            "carriage_distance_mm",
            "the carriage's distance to the target at the end",
            "mm",
            low=0.0,
            high=_DISTANCE_BOUND_MM,
        ),
        RecordField("captured", "the carriage within the capture distance at the end", kind="bool"),
    ),
    statistics=tracking_statistics,
    statistic_keys=(
        "tracking_trials",
        "tracking_error_median_mm",
        "tracking_error_q25_mm",
        "tracking_error_q75_mm",
        "tracking_error_mean_mm",
        "carriage_distance_median_mm",
        "captures",
        "capture_rate",
        "capture_rate_lo",
        "capture_rate_hi",
    ),
    columns=(
        Column("tracking_trials", "Trials", format="{tracking_trials}"),
        Column("tracking_error_median_mm", "Tracking error median (mm)", better="lower"),
        Column(
            "tracking_error_median_mm",
            "IQR (mm)",
            format="{tracking_error_q25_mm:.1f}–{tracking_error_q75_mm:.1f}",
            interval=("tracking_error_q25_mm", "tracking_error_q75_mm"),
        ),
        Column("captures", "Captures", better="higher", format="{captures} ({capture_rate!p:.0f} %)"),
        Column(
            "capture_rate",
            "Capture rate 95 % CI",
            better="higher",
            format="{capture_rate_lo!p:.0f}–{capture_rate_hi!p:.0f} %",
            interval=("capture_rate_lo", "capture_rate_hi"),
        ),
        Column("decision_ms_median", "Decision ms", format="{decision_ms_median:.2f}"),
    ),
    table=Table(
        title="Tracking (moving target)",
        text=(
            "A target sphere that swims during the episode: {trials} trials per condition and agent, seed {seed}, "
            "sensor model `{sensor_model}`, signal `{signal}`, {n_particles} particles, {max_observations} "
            "readings per episode. *Tracking error*: the mean distance from the belief's mean to the true target "
            "over the episode's second half, per trial; its median and interquartile range over the trials. "
            f"*Capture*: the carriage within {CAPTURE_DISTANCE_MM:g} mm of the target after the last reading; the "
            "rate with its 95 % Wilson interval. The *All conditions* rows pool the trials."
        ),
        count="tracking_trials",
        replaces=True,
    ),
    score=Score("tracking_error_mm", "lower", "tracking error", "mm", name="tracking_error"),
    rate=Score(
        "captured", "higher", "capture rate", name="capture", episode=_captured_of_info, record=_captured_of_record
    ),
    outcome=_tracking_outcome,
    curves=(
        CurvePanel(
            "capture_rate", f"capture rate (carriage within {CAPTURE_DISTANCE_MM:g} mm at the end)", ylim=(0.0, 1.02)
        ),
        CurvePanel("mean_tracking_error_mm", "mean tracking error (mm)"),
    ),
    eval_columns={
        "mean_tracking_error_mm": lambda infos: float(_tracking_errors(infos).mean()),
        "median_tracking_error_mm": lambda infos: float(np.median(_tracking_errors(infos))),
        "capture_rate": lambda infos: float(np.mean([_captured_of_info(i) for i in infos])),
    },
    success_criterion=False,
)
TrackTask.metrics = TRACK_METRICS
