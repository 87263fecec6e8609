"""The task interface: what a task of the simulation core provides, and the machinery tasks share.

The step (:mod:`electroloc_gym.engines.numba_core.step`) is the same for every env: draws, reading, belief update,
reward, flags, autoreset. What differs between envs is a :class:`Task`, which the step calls and
never asks its name:

==========================  ====================================================================
the step needs              the task provides
==========================  ====================================================================
sizes                       :attr:`~Task.particle_dims`, :attr:`~Task.n_readings`,
                            :meth:`~Task.calibration_points`, :meth:`~Task.table_cells`
episode draws               :meth:`~Task.begin_episode` (in its documented draw order)
gain of the next reading    :meth:`~Task.set_gain`
motion                      :meth:`~Task.move`
true reading                :meth:`~Task.true_mean_V` (noise-free, unsaturated)
belief update               :meth:`~Task.assimilate` (through the kernels)
statistics                  :meth:`~Task.update_statistics` (mean, covariance, histogram, the
                            task's own)
reward and episode end      :meth:`~Task.rewards`, :meth:`~Task.flags` (the shared rule by default)
observation and info        :meth:`~Task.observation`, :meth:`~Task.info` (+ :attr:`~Task.info_keys`)
what agents predict         :meth:`~Task.sensor_model`, :meth:`~Task.particles_after_move`,
                            :meth:`~Task.offsets_after_move`, :meth:`~Task.predicted_mean_std`
==========================  ====================================================================

Every per-episode value lives in the :class:`~electroloc_gym.engines.numba_core.state.State`; a task holds only what
its parameters fix. :class:`Task` implements the parts shared by the three tasks — a belief over the
x–y position updated by the kernels, the observation layouts of :mod:`electroloc_gym.contract.observation`,
the dynamic gain — and leaves the rest abstract. A sensor array (K readings per step) enters through
:attr:`Task.n_readings` (the step draws K noises per env; ``true_mean_V``, ``assimilate`` and the
state's ``reading_V`` then carry (k, K) readings); distractors only change :meth:`Task.true_mean_V`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.belief_summary import belief_info_values
from electroloc_gym.contract.motion import carriage_after_move_mm
from electroloc_gym.contract.observation import (
    BELIEF_OBS_DIM,
    HIST_BINS,
    INFO_KEYS,
    RAW_OBS_DIM,
    STEP_REWARD,
    belief_observation,
    condition_index,
    episode_flags,
    raw_observation,
)
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.contract.task_spec import CurvePanel, Score, TaskMetrics, TaskOptions, TaskState
from electroloc_gym.engines.numba_core.state import State as SimState
from electroloc_gym.engines.numba_core.worlds import SEED_BOUND, descriptor, group_by_world, with_gain_factor
from electroloc_gym.kernels import calibrated_assimilate, egocentric_counts, loglik_assimilate, mean_cov_rows
from electroloc_gym.kernels.streams import uniform_in_box
from electroloc_gym.sensor_models import CalibrationProtocol, coefficient_rows
from electroloc_gym.world.conditions import Condition

__all__ = ["Task", "LOCALIZATION_METRICS"]


class Task(ABC):
    """One task of the simulation core (module docstring): abstract methods are what each task defines.

    Args:
        params: the env's frozen parameters.
    """

    #: Coordinates of a hypothesis: x, y (mm), then the task's own (``shape_dims`` more, stored in
    #: ``State.shape_particles``); agents pass (M, particle_dims) hypotheses to the predictions.
    particle_dims = 2
    #: Readings per step (1: the paper's one electrode pair; K for an array of K pairs).
    n_readings = 1
    #: The info keys the task adds to :data:`~electroloc_gym.contract.observation.INFO_KEYS` (numbers or numeric
    #: arrays only).
    info_keys: tuple[str, ...] = ()
    #: The names of the task's integer-coded info keys: key → the name of each code, indexed by the code (the
    #: env's ``metadata["info_names"]``, :func:`~electroloc_gym.contract.observation.info_names`).
    info_names: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: Offsets = sign · (particle − origin): +1 target hypothesis − carriage, −1 −(carriage hypothesis).
    offset_sign = np.float32(1.0)
    #: What the belief's hypotheses are: ``"target"`` (a static target's position: they stay put when the
    #: robot moves) or ``"robot"`` (the carriage's own position: they move with every commanded move).
    belief_frame = "target"
    #: The names of the hidden state's entries (:meth:`hidden_state`), units in the names.
    hidden_keys: tuple[str, ...] = ("target_x_mm", "target_y_mm")
    #: The sphere's size and material are hidden from the agent (the belief estimates them): its agent view shows
    #: the episode's condition without them.
    hides_sphere = False
    #: What the layers above the engine report of the task: a
    #: :class:`~electroloc_gym.contract.task_spec.TaskMetrics` (default :data:`LOCALIZATION_METRICS`).
    metrics: ClassVar[TaskMetrics]
    #: The task's own options: a :class:`~electroloc_gym.contract.task_spec.TaskOptions` dataclass whose fields
    #: are the env's own keyword arguments (``EnvParams.options`` holds an instance; none by default).
    Options: ClassVar[type[TaskOptions]] = TaskOptions
    #: The task's own per-env arrays: a :class:`~electroloc_gym.contract.task_spec.TaskState` dataclass
    #: (the engine's ``State.task``; none by default).
    State: ClassVar[type[TaskState]] = TaskState

    def __init__(self, params: EnvParams) -> None:
        self.params = params
        #: The task's own options (``params.options``, an instance of :attr:`Options`).
        self.options: TaskOptions = params.options
        self.protocol: CalibrationProtocol = params.calibration
        self.calibrated = params.sensor_model == "calibrated"
        #: The gain factors of the readings (dynamic gain; (1,) without).
        self.gains = params.gains
        self._gain_array = np.asarray(self.gains, dtype=np.float64)
        self.dynamic_gain = params.gain_levels is not None
        #: Calibration rows per gain level (each level has its own calibration; set by ``table_cells``).
        self.cells_per_gain = 0
        #: The observation's length.
        self.obs_dim = BELIEF_OBS_DIM if params.observation == "belief" else RAW_OBS_DIM + int(self.dynamic_gain)

    @property
    def shape_dims(self) -> int:
        """Coordinates per hypothesis beyond x, y."""
        return self.particle_dims - 2

    # ---- sizes ------------------------------------------------------------------------------------
    @abstractmethod
    def calibration_points(self) -> int:
        """The largest calibration grid's points per axis (0 without a calibrated model; a memory bound)."""

    @abstractmethod
    def table_cells(self) -> int:
        """Coefficient rows per env of the calibrated lookup kernel (0 without a calibrated model)."""

    # ---- the episode ------------------------------------------------------------------------------
    @abstractmethod
    def default_world(self) -> Any:
        """The world an env shows before its first reset (a ``Condition`` or a ``Scene``)."""

    def world_condition(self, world: Any) -> Condition:
        """A world as a ``Condition`` (amplifier, water, boxes; what the adapters' ``condition`` shows)."""
        return world

    def episode_condition(self, state: SimState, i: int) -> Condition:
        """Env ``i``'s episode as the single env's ``condition`` shows it: its world's condition (before the
        first reset: the default world's).
        """
        w = state.world[i]
        return self.world_condition(self.default_world() if w is None else w)

    @abstractmethod
    def begin_episode(self, state: SimState, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws from its generator ``g`` (in the task's documented order): its world,
        calibration, hidden truth, start position and particles.
        """

    def set_gain(self, state: SimState, ids: NDArray[np.intp], levels: NDArray[np.intp] | int) -> None:
        """Envs ``ids`` read at gain level(s) ``levels`` from now on: the reading noise and the
        observation's amplifier entries (78–79) follow the level's gain.
        """
        state.gain_index[ids] = levels
        if len(self.gains) == 1:
            return
        for i in np.asarray(ids).tolist():
            c = self.at_gain(state.world[i], int(state.gain_index[i]))
            state.noise_V[i] = c.noise_std_V
            state.descriptor[i, 2:4] = descriptor(c)[2:4]

    def at_gain(self, condition: Condition, level: int) -> Condition:
        """``condition`` with its amplifier at gain level ``level`` (G times the level's factor)."""
        f = self.gains[level]
        return condition if f == 1.0 else with_gain_factor(condition, f)

    def gain_seed(self, seed: int, level: int) -> int:
        """The calibration seed of gain level ``level``: the episode's own at the preset level (so that
        reading at the preset gain reproduces the env without dynamic gain), its own draws at the others.
        """
        preset = self.params.reset_gain_index
        return seed if level == preset else (seed + 7919 * (level + 1)) % SEED_BOUND

    # ---- one step ---------------------------------------------------------------------------------
    def move(self, state: SimState, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The carriage moves by the commanded moves (k, 2), kept inside the allowed box (truncated at the walls;
        the rule both engines share, :func:`~electroloc_gym.contract.motion.carriage_after_move_mm`).
        """
        h = state.half_mm[ids][:, None]
        state.position_mm[ids] = carriage_after_move_mm(np, state.position_mm[ids], moves_mm, h)

    @abstractmethod
    def true_mean_V(self, state: SimState, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) noise-free, unsaturated true readings of envs ``ids``, V (float64; (k, K) for K readings)."""

    def assimilate(
        self,
        state: SimState,
        ids: NDArray[np.intp],
        reading: NDArray[np.float64],
        u0: NDArray[np.float64],
        jitter: NDArray[np.uint16],
        normal_table: NDArray[np.float32],
    ) -> int:
        """Fuse each env's reading into its x–y cloud in one compiled call (calibrated: the table lookup in
        the kernel; analytic: the sensor model's float32 log-likelihoods from numpy), ending with the
        statistics; returns −1, or the first env whose log-likelihood is NaN.

        Args:
            state: the state (updated in place).
            ids: the envs (all of them: ``state``'s arrays are updated in place by the kernel).
            reading: (k,) the readings, V.
            u0: (k,) the resampling offsets.
            jitter: (k, 2M) the jitter's normal-table indices.
            normal_table: the normal quantile table.
        """
        s = state
        k = len(ids)
        full = k == s.num_envs
        sel: Any = slice(None) if full else ids
        src = s.particles_mm if full else s.particles_mm[ids]  # full: updated in place
        origin = self.histogram_origin(s, sel)
        half = s.half_mm[sel].astype(np.float32)
        if full:  # the kernels write the statistics in place
            mean, cov, counts = s.mean_mm, s.cov_mm2, s.counts
        else:
            mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
        if self.calibrated:
            rows = self.table_rows(s, sel)  # each env's rows at its current gain level
            bad = calibrated_assimilate(
                src,
                origin,
                self.offset_sign,
                s.grid_lo_mm[sel],
                s.grid_inv_mm[sel],
                s.grid_cells[sel],
                rows,
                s.table,
                reading.astype(np.float32),
                u0,
                jitter,
                normal_table,
                half,
                src,
                mean,
                cov,
                2 * half,
                HIST_BINS,
                counts,
            )
        else:
            ll = self._analytic_log_likelihood(s, ids, src, origin, reading)
            bad = loglik_assimilate(
                ll, src, origin, u0, jitter, normal_table, half, src, mean, cov, 2 * half, HIST_BINS, counts
            )
        if bad < 0 and not full:
            s.particles_mm[ids] = src
            s.mean_mm[ids], s.cov_mm2[ids], s.counts[ids] = mean, cov, counts
        return bad

    def _analytic_log_likelihood(
        self,
        state: SimState,
        ids: NDArray[np.intp],
        src: NDArray[np.float32],
        origin: NDArray[np.float32],
        reading: NDArray[np.float64],
    ) -> NDArray[np.float32]:
        """(k, M) float32 log-likelihoods of the analytic models, one numpy evaluation per world (and gain
        level, with dynamic gain).
        """
        off = ((src - origin[:, :, None]) * self.offset_sign).transpose(0, 2, 1)  # (k, M, 2) offsets
        groups = group_by_world(state, ids, by_gain=self.dynamic_gain)
        if len(groups) == 1:
            model = self.sensor_model(state, int(ids[0]))
            return np.ascontiguousarray(model.log_likelihood(reading[:, None], off), dtype=np.float32)
        ll = np.empty((len(ids), src.shape[2]), dtype=np.float32)
        for _, rows in groups:
            model = self.sensor_model(state, int(ids[rows[0]]))
            ll[rows] = model.log_likelihood(reading[rows][:, None], off[rows])
        return ll

    def update_statistics(self, state: SimState, ids: NDArray[np.intp] | slice) -> None:
        """Recompute envs ``ids``' belief statistics from their particles (after the particles were set)."""
        s = state
        x, y = s.particles_mm[ids, 0], s.particles_mm[ids, 1]
        k = len(x)
        mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
        mean_cov_rows(x, y, mean, cov)
        egocentric_counts(x, y, self.histogram_origin(s, ids), 2 * s.half_mm[ids].astype(np.float32), HIST_BINS, counts)
        s.mean_mm[ids], s.cov_mm2[ids], s.counts[ids] = mean, cov, counts

    def rewards(self, state: SimState) -> NDArray[np.float64]:
        """(N,) every env's reward for this step's reading (the paper's tasks: ``STEP_REWARD``, −1 per reading)."""
        return np.full(state.num_envs, STEP_REWARD)

    def flags(self, state: SimState) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """(terminated, truncated) of every env after a step: the shared rule
        (:func:`~electroloc_gym.contract.observation.episode_flags`).
        """
        p = self.params
        return episode_flags(
            state.spread_mm(),
            state.n_observations,
            state.elapsed,
            p.success_spread_mm,
            p.max_observations,
            p.max_episode_steps,
        )

    # ---- what is reported -------------------------------------------------------------------------
    @abstractmethod
    def truth_mm(self, state: SimState, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) what the belief estimates (ground truth, for the info's error), mm."""

    def hidden_state(self, state: SimState, i: int) -> NDArray[np.float64]:
        """Env ``i``'s hidden state (:attr:`hidden_keys`), float64: ground truth, for evaluation and
        privileged critics only.
        """
        return np.asarray(self.truth_mm(state, np.array([i]))[0], dtype=np.float64).copy()

    def belief_origin_mm(self, state: SimState, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) the belief's frame origin, mm: the offsets' origin, the histogram's centre (the carriage)."""
        return state.position_mm[ids]

    def histogram_origin(self, state: SimState, ids: NDArray[np.intp] | slice) -> NDArray[np.float32]:
        """(k, 2) float32 :meth:`belief_origin_mm` (the kernels' argument)."""
        return self.belief_origin_mm(state, ids).astype(np.float32)

    def reference_mm(self, state: SimState, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) what the robot knows of its own position (observation entries 0–1): the carriage, mm."""
        return state.position_mm[ids]

    def observation(self, state: SimState, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """(k, obs_dim) float32 observations of envs ``ids`` (all if None), layouts of
        :mod:`electroloc_gym.contract.observation`.
        """
        s, sel = state, slice(None) if ids is None else ids
        p = self.params
        half, sat = s.half_mm[sel], s.saturation_V[sel]
        if p.observation == "raw":
            obs = raw_observation(self.reference_mm(s, sel), s.reading_V[sel], half, sat)
            if self.dynamic_gain:  # the reading's gain level, in [−1, 1]
                level = s.gain_index[sel] * (2.0 / max(len(self.gains) - 1, 1)) - 1.0
                obs = np.concatenate([obs, level.astype(np.float32)[:, None]], axis=1)
            return obs
        return belief_observation(
            self.belief_origin_mm(s, sel),
            s.reading_V[sel],
            s.mean_mm[sel],
            s.cov_mm2[sel],
            s.counts[sel] / s.n_particles,
            s.n_observations[sel],
            p.max_observations,
            half,
            s.noise_V[sel],
            sat,
            p.success_spread_mm,
            s.descriptor[sel],
        )

    def info(self, state: SimState, ids: NDArray[np.intp] | None = None) -> dict[str, NDArray[Any]]:
        """The info arrays of envs ``ids`` (all if None): :data:`~electroloc_gym.contract.observation.INFO_KEYS`,
        the task's :attr:`info_keys`, and ``gain`` with dynamic gain (the amplifier gain G of the last reading);
        the belief's error, spread and success by the rule both engines share
        (:func:`~electroloc_gym.contract.belief_summary.belief_info_values`).
        """
        s, sel = state, slice(None) if ids is None else ids
        est = s.mean_mm[sel]
        error, spread, success = belief_info_values(
            np, est, s.cov_mm2[sel], self.truth_mm(s, sel), self.params.success_spread_mm
        )
        values = (
            s.position_mm[sel].copy(),
            est.copy(),
            error,
            spread,
            s.reading_V[sel].copy(),
            s.n_observations[sel].copy(),
            success,
            condition_index(s.names[sel]),
        )
        out: dict[str, NDArray[Any]] = dict(zip(INFO_KEYS, values, strict=True))
        out.update(self.task_info(s, sel))
        if self.dynamic_gain:
            out["gain"] = (
                np.array([w.amplifier.gain for w in s.world], dtype=np.float64)[sel]
                * self._gain_array[s.gain_index[sel]]
            )
        return out

    def task_info(self, state: SimState, sel: Any) -> dict[str, NDArray[Any]]:
        """The task's own info arrays (keys :attr:`info_keys`) of envs ``sel``."""
        return {}

    # ---- what agents predict ----------------------------------------------------------------------
    @abstractmethod
    def sensor_model(self, state: SimState, i: int, level: int | None = None) -> Any:
        """Env ``i``'s sensor model object for the agent at gain level ``level`` (default: the current one)."""

    @abstractmethod
    def particles_after_move(self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Env ``i``'s hypotheses (…, M, particle_dims) after commanded moves (2,) or (C, 2), mm."""

    @abstractmethod
    def offsets_after_move(self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Sensor-model offsets (…, M, 2) of env ``i``'s hypotheses after commanded moves (2,) or (C, 2),
        mm, by the env's own motion rule (what an agent predicts, paper Algorithm 1).
        """

    def predicted_mean_std(
        self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray, level: int | None = None
    ) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of the reading each hypothesis predicts after the moves (at gain
        level ``level``; default the current one).
        """
        return self.sensor_model(state, i, level).mean_std(self.offsets_after_move(state, i, particles, moves_mm))

    # ---- shared helpers of the episode draws ------------------------------------------------------
    def _set_world(
        self, state: SimState, i: int, world: Any, key: int, condition: Condition, world_descriptor: NDArray[np.float32]
    ) -> None:
        state.world[i] = world
        state.world_key[i] = key
        state.half_mm[i] = condition.allowed_half_width_mm
        state.noise_V[i] = condition.noise_std_V
        state.saturation_V[i] = condition.saturation_V
        state.descriptor[i] = world_descriptor
        state.names[i] = world.name

    def _cal_seed(self, g: np.random.Generator) -> int:
        s = self.params.calibration_seed
        return s if s is not None else int(g.integers(SEED_BOUND))

    def _set_grid(
        self, state: SimState, i: int, grid_mm: NDArray[np.float64], step_mm: float, level: int = 0
    ) -> NDArray[np.float32]:
        """Env ``i``'s grid arguments of the lookup kernel; returns its rows of the coefficient table
        (those of gain level ``level``).
        """
        state.grid_lo_mm[i] = np.float32(grid_mm[0])
        state.grid_inv_mm[i] = np.float32(1.0 / step_mm)
        state.grid_cells[i] = grid_mm.size - 1
        start = int(state.table_row[i]) + level * self.cells_per_gain
        return state.table[start : start + coefficient_rows(grid_mm)]

    def table_rows(self, state: SimState, sel: Any) -> NDArray[np.int64]:
        """(k,) first coefficient row of each env's current gain level (the lookup kernel's ``base``)."""
        if len(self.gains) == 1:
            return state.table_row[sel]
        return state.table_row[sel] + state.gain_index[sel] * self.cells_per_gain

    def _place(self, state: SimState, i: int, g: np.random.Generator, start_half_mm: float) -> None:
        """The start position (2 uniforms) and the uniform particle cloud (M·2 uniforms)."""
        state.position_mm[i] = g.uniform(-start_half_mm, start_half_mm, size=2)
        state.odometry_mm[i] = 0.0
        h = state.half_mm[i]
        uniform_in_box(
            g,
            np.array([-h, -h]),
            np.array([h, h]),
            state.n_particles,
            out_xy=(state.particles_mm[i, 0], state.particles_mm[i, 1]),
        )
        state.n_observations[i] = 0
        state.elapsed[i] = 0


# ---- what the layers above the engine report: the paper's localisation metrics ---------------------------
# Every task's unless it declares its own (``metrics``, a class attribute): readings to success (a failure
# counted as the cap; lower better), the success rate, "success"/"failure" (contract/task_spec.py).


def _readings_of_info(info: Mapping[str, Any]) -> float:
    return float(info["n_observations"])


def _readings_of_record(record: Mapping[str, Any]) -> float:
    return float(record["readings"] if record["success"] else record["max_observations"])


def _return_of_readings(readings: float) -> float:
    """An episode's return for its readings: 1 − R (reward −1 per reading after the reset's first one); the
    datasets' reference scores are on this scale (:mod:`electroloc_gym.dataset.seed_protocol`).
    """
    return 1.0 - float(readings)


def _success_of_info(info: Mapping[str, Any]) -> float:
    return float(bool(info["success"]))


def _success_of_record(record: Mapping[str, Any]) -> float:
    return float(bool(record["success"]))


def _localisation_outcome(info: Mapping[str, Any]) -> str:
    return "success (spread ≤ threshold)" if bool(info["success"]) else "failure (observation cap)"


#: The paper's localisation metrics (Appendix B): the default :attr:`Task.metrics`.
LOCALIZATION_METRICS = TaskMetrics(
    score=Score(
        "readings",
        "lower",
        "readings to success (a failure counted as the cap)",
        episode=_readings_of_info,
        record=_readings_of_record,
        best="fewest mean readings to localise (failures count as the cap)",
        reference=_return_of_readings,
    ),
    rate=Score("success", "higher", "success rate", episode=_success_of_info, record=_success_of_record),
    outcome=_localisation_outcome,
    curves=(
        CurvePanel("success_rate", "success rate (spread ≤ 10 mm within 35 obs.)", ylim=(0.0, 1.02)),
        CurvePanel("median_readings", "median readings to localise", ylim=(0.0, 36.0)),
    ),
)
#: What the task reports (:class:`~electroloc_gym.contract.task_spec.TaskMetrics`; a task declares its own).
Task.metrics = LOCALIZATION_METRICS
