"""ElectroLocTrack-v0: follow a target sphere that swims during the episode (the prey-capture task).

A thin adapter over the simulation core with one env of the ``"track"`` task
(:mod:`electroloc_gym.engines.numba_core.track_task`), and its native vector env.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.engines.numba_core.track_task import TrackOptions
from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.envs.vector import CoreVectorEnv

__all__ = ["TrackEnv", "TrackVectorEnv"]


class TrackEnv(ElectroLocEnv):
    """
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

    @property
    def target_motion(self) -> str:
        """The target's true motion, ``"random_walk"`` or ``"swimmer"`` (a setting, not the state)."""
        return self.params.options_as(TrackOptions).target_motion

    @property
    def target_speed_mm(self) -> float:
        """The target's speed, mm per reading (a setting)."""
        return self.params.options_as(TrackOptions).target_speed_mm

    @property
    def motion_model(self) -> str:
        """The filter's motion model, ``"random_walk"``, ``"static"`` or ``"swimmer"``."""
        return self.params.options_as(TrackOptions).motion_model

    @property
    def motion_step_mm(self) -> float:
        """The filter's RMS Gaussian step per reading, mm (``target_speed_mm`` unless given; 0 with ``"static"``
        and ``"swimmer"``, whose particles step by their velocities).
        """
        p = self.params.options_as(TrackOptions)
        if p.motion_model != "random_walk":
            return 0.0
        return p.target_speed_mm if p.motion_step_mm is None else p.motion_step_mm


class TrackVectorEnv(CoreVectorEnv):
    """``num_envs`` copies of ElectroLocTrack-v0 stepped as one core (:mod:`electroloc_gym.envs.vector`); the
    info adds the track keys (``target_mm`` (N, 2), ``tracking_error_mm``, ``carriage_distance_mm``,
    ``captured``).
    """

    @property
    def target_mm(self) -> NDArray[np.float64]:
        """Every sub-env's true target now (N, 2), mm (a copy): ground truth, for evaluation."""
        return np.copy(self._state.target_mm, order="C")
