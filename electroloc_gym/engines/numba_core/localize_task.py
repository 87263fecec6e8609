"""The ``localize`` task (ElectroLoc-v0): the particles are hypotheses of a static target's position.

Hidden state: the target centre (world frame), which does not move; the carriage is known. The
sensor-model offset of particle i is particle_i − carriage. The episode's world is a ``Condition`` of
the pool (one, or the eight presets with ``condition="random"``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.motion import carriage_after_move_mm
from electroloc_gym.contract.observation import condition_descriptor
from electroloc_gym.contract.params import EnvParams, LocalizeOptions
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.engines.numba_core.task import Task
from electroloc_gym.engines.numba_core.worlds import group_by_world
from electroloc_gym.sensor_models import (
    AnalyticSensorModel,
    calibration_coefficients,
    calibration_grid_for,
    coefficient_rows,
    fixed_coefficients,
    grid_points_bound,
    make_sensor_model,
)
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import expected_reading

__all__ = ["LocalizeTask"]


class LocalizeTask(Task):
    """ElectroLoc-v0: a target sphere (or a pool of conditions) whose position the particles estimate."""

    Options = LocalizeOptions
    options: LocalizeOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.options = params.options_as(LocalizeOptions)
        self.pool: tuple[Condition, ...] = self.options.conditions()
        self._analytic = [[AnalyticSensorModel(self.at_gain(c, j)) for j in range(len(self.gains))] for c in self.pool]
        self._descriptors = [condition_descriptor(c) for c in self.pool]
        self._grids: list[NDArray[np.float64]] = []  # built after the memory check (table_cells)

    def default_world(self) -> Condition:
        """The world before the first reset: the first condition of the pool."""
        return self.pool[0]

    def calibration_points(self) -> int:
        """The largest calibration grid's points per axis (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        return max(grid_points_bound(self.protocol, c.allowed_half_width_mm) for c in self.pool)

    def table_cells(self) -> int:
        """Coefficient rows per env (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        self._grids = [calibration_grid_for(c, self.protocol) for c in self.pool]
        self.cells_per_gain = max(coefficient_rows(g) for g in self._grids)
        return self.cells_per_gain * len(self.gains)

    def _draw_condition(self, state: State, i: int, g: np.random.Generator) -> Condition:
        """The episode's condition (one draw from a pool of several) set as env ``i``'s world."""
        pool = self.pool
        k = int(g.integers(len(pool))) if len(pool) > 1 else 0
        c = pool[k]
        self._set_world(state, i, c, k, c, self._descriptors[k])
        return c

    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in order: condition (pool of several), calibration seed (unless
        fixed), target (``randomize_target``), start position, particles.
        """
        c = self._draw_condition(state, i, g)
        k = int(state.world_key[i])
        seed = self._cal_seed(g)
        state.cal_seed[i] = seed
        state.model[i] = [None] * len(self.gains) if self.calibrated else self._analytic[k]
        if self.calibrated:
            for j in range(len(self.gains)):  # the robot calibrates at every gain level
                rows = self._set_grid(state, i, self._grids[k], self.protocol.grid_step_mm, j)
                cj, sj = self.at_gain(c, j), self.gain_seed(seed, j)
                if self.params.calibration_seed is not None:
                    rows[:] = fixed_coefficients(cj, sj, self.protocol)
                else:
                    calibration_coefficients(cj, sj, self.protocol, out=rows)
        s = c.start_half_width_mm
        if self.options.randomize_target:
            state.target_mm[i] = g.uniform(-s, s, size=2)
        else:
            state.target_mm[i] = c.target_xy_mm
        self._place(state, i, g, s)

    def true_mean_V(self, state: State, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) noise-free, unsaturated true readings of envs ``ids``, V (float64)."""
        offsets = state.target_mm[ids] - state.position_mm[ids]
        groups = group_by_world(state, ids)
        if len(groups) == 1:
            out = expected_reading(groups[0][0], offsets, saturate=False)
        else:
            out = np.empty(len(ids))
            for c, rows in groups:
                out[rows] = expected_reading(c, offsets[rows], saturate=False)
        return out if len(self.gains) == 1 else out * self._gain_array[state.gain_index[ids]]

    def truth_mm(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) what the belief estimates: the target centre, mm."""
        return state.target_mm[ids]

    def offsets_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Target hypothesis − the carriage after the move (kept in the box, as :meth:`move`)."""
        carriage = carriage_after_move_mm(np, state.position_mm[i], moves_mm, state.half_mm[i]).astype(particles.dtype)
        return particles[..., :2] - carriage[..., None, :]

    def particles_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """The target does not move: the hypotheses unchanged, once per move."""
        return np.broadcast_to(particles, moves_mm.shape[:-1] + particles.shape).copy()

    def sensor_model(self, state: State, i: int, level: int | None = None) -> Any:
        """Env ``i``'s sensor model object for the agent at gain level ``level`` (default: the current
        one; the calibrated ones built on first use).
        """
        j = int(state.gain_index[i]) if level is None else level
        models = state.model[i]
        if models[j] is None:
            models[j] = make_sensor_model(
                "calibrated", self.at_gain(state.world[i], j), self.gain_seed(int(state.cal_seed[i]), j), self.protocol
            )
        return models[j]
