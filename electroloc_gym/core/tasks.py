"""What differs between the two tasks: the hidden state, the world, the motion and the sensor-model offsets.

=====================  =======================================  ==========================================
task                   hidden state (particles)                 sensor-model offsets of particle i
=====================  =======================================  ==========================================
``localize``           target position (world frame), static    particle_i − carriage (carriage known)
(ElectroLoc-v0)
``global``             the robot's own carriage position (map   −particle_i (map origin − carriage); every
(ElectroLocGlobal-v0)  frame), moves with every commanded move  commanded move shifts the particles
=====================  =======================================  ==========================================

A task draws an env's episode (:meth:`~TargetTask.begin_episode`, in the documented draw order),
gives the noise-free true reading (:meth:`~TargetTask.true_mean_V`), moves the carriage
(:meth:`~TargetTask.move`) and builds the sensor models. Everything else — draws per step, the
belief update, observation, reward, termination, info, autoreset — is the same for both and lives
in :mod:`electroloc_gym.core.step`. Batched numpy work here is grouped by world (one call for all
envs sharing a condition or map) and uses only exact operations, so every env's values are those
it would get alone (docs/design.md).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.conditions import Condition
from electroloc_gym.core.params import EnvParams
from electroloc_gym.core.state import State
from electroloc_gym.draws import uniform_in_box
from electroloc_gym.envs.observation import condition_descriptor
from electroloc_gym.kernels import bilinear_coefficients
from electroloc_gym.scene import BENCHMARK_SCENE, Scene, random_cylinder_layout
from electroloc_gym.sensor import expected_reading
from electroloc_gym.sensor_models import (
    AnalyticSensorModel,
    CalibrationProtocol,
    calibration_coefficients,
    calibration_grid_for,
    make_sensor_model,
)
from electroloc_gym.sensor_models.map import make_map_sensor_model

__all__ = ["TargetTask", "MapTask", "make_task", "group_by_world"]

_SEED_BOUND = 2**31 - 1  # calibration seeds are drawn in [0, 2**31 − 1)


def group_by_world(state: State, ids: NDArray[np.intp], by_gain: bool = False) -> list[tuple[Any, NDArray[np.intp]]]:
    """``[(world, positions in ids)]``: the envs of ``ids`` sharing one world (and, ``by_gain``, one gain
    level), in order of the keys.
    """
    keys = state.world_key[ids]
    if by_gain:  # (world, level) as one key: world · (levels in use) + level
        levels = state.gain_index[ids]
        keys = keys * (int(levels.max()) + 1) + levels
    if len(ids) == 1 or (keys == keys[0]).all():
        return [(state.world[int(ids[0])], np.arange(len(ids)))]
    out = []
    for key in np.unique(keys):
        rows = np.flatnonzero(keys == key)
        out.append((state.world[int(ids[rows[0]])], rows))
    return out


@functools.lru_cache(maxsize=256)
def _descriptor(condition: Condition) -> NDArray[np.float32]:
    return condition_descriptor(condition)


@functools.lru_cache(maxsize=64)
def _fixed_coefficients(condition: Condition, seed: int, protocol: CalibrationProtocol) -> NDArray[np.float32]:
    cells = _cells(calibration_grid_for(condition, protocol))
    coef = calibration_coefficients(condition, seed, protocol, out=np.empty((cells, 8), dtype=np.float32))
    coef.flags.writeable = False
    return coef


@functools.lru_cache(maxsize=256)
def _with_gain_factor(condition: Condition, factor: float) -> Condition:
    return condition.replace(amplifier=condition.amplifier.with_gain(condition.amplifier.gain * factor))


@functools.lru_cache(maxsize=64)
def _scene_condition(scene: Scene) -> Condition:
    return scene.as_condition()


def _cells(grid_mm: NDArray[np.float64]) -> int:
    return (grid_mm.size - 1) ** 2 + 1


def _grid_points_bound(protocol: CalibrationProtocol, allowed_half_width_mm: float) -> int:
    """An upper bound of a calibration grid's points per axis, computed without building the grid (any
    ``grid_extent`` covers at most twice the allowed box).
    """
    half = 2.0 * allowed_half_width_mm if protocol.half_span_mm is None else protocol.half_span_mm
    return int(min(2.0 * half / protocol.grid_step_mm, 2.0**62)) + 2


class _Task:
    """The shared part of the two tasks (see the module docstring)."""

    #: Offsets = sign · (particle − origin): +1 target hypothesis − carriage, −1 −(carriage hypothesis).
    offset_sign = np.float32(1.0)

    def __init__(self, params: EnvParams) -> None:
        self.params = params
        self.protocol: CalibrationProtocol = params.calibration
        self.calibrated = params.sensor_model == "calibrated"
        #: The gain factors of the readings (dynamic gain; (1,) without).
        self.gains = params.gains
        self._gain_array = np.asarray(self.gains, dtype=np.float64)
        #: Calibration rows per gain level (each level has its own calibration; set by ``table_cells``).
        self.cells_per_gain = 0

    def set_gain(self, state: State, ids: NDArray[np.intp], levels: NDArray[np.intp] | int) -> None:
        """Envs ``ids`` read at gain level(s) ``levels`` from now on: the reading noise and the
        observation's amplifier entries (78–79) follow the level's gain.
        """
        state.gain_index[ids] = levels
        if len(self.gains) == 1:
            return
        for i in np.asarray(ids).tolist():
            c = self.at_gain(state.world[i], int(state.gain_index[i]))
            state.noise_V[i] = c.noise_std_V
            state.descriptor[i, 2:4] = _descriptor(c)[2:4]

    def at_gain(self, condition: Condition, level: int) -> Condition:
        """``condition`` with its amplifier at gain level ``level`` (G times the level's factor)."""
        f = self.gains[level]
        return condition if f == 1.0 else _with_gain_factor(condition, f)

    def gain_seed(self, seed: int, level: int) -> int:
        """The calibration seed of gain level ``level``: the episode's own at the preset level (so that
        reading at the preset gain reproduces the env without dynamic gain), its own draws at the others.
        """
        preset = self.params.reset_gain_index
        return seed if level == preset else (seed + 7919 * (level + 1)) % _SEED_BOUND

    def _set_world(self, state: State, i: int, world: Any, key: int, condition: Condition,
                   descriptor: NDArray[np.float32]) -> None:
        state.world[i] = world
        state.world_key[i] = key
        state.half_mm[i] = condition.allowed_half_width_mm
        state.noise_V[i] = condition.noise_std_V
        state.saturation_V[i] = condition.saturation_V
        state.descriptor[i] = descriptor
        state.names[i] = world.name

    def _cal_seed(self, g: np.random.Generator) -> int:
        s = self.params.calibration_seed
        return s if s is not None else int(g.integers(_SEED_BOUND))

    def _set_grid(self, state: State, i: int, grid_mm: NDArray[np.float64], step_mm: float,
                  level: int = 0) -> NDArray[np.float32]:
        """Env ``i``'s grid arguments of the lookup kernel; returns its rows of the coefficient table
        (those of gain level ``level``).
        """
        state.grid_lo_mm[i] = np.float32(grid_mm[0])
        state.grid_inv_mm[i] = np.float32(1.0 / step_mm)
        state.grid_cells[i] = grid_mm.size - 1
        start = int(state.table_row[i]) + level * self.cells_per_gain
        return state.table[start:start + _cells(grid_mm)]

    def table_rows(self, state: State, sel: Any) -> NDArray[np.int64]:
        """(k,) first coefficient row of each env's current gain level (the lookup kernel's ``base``)."""
        if len(self.gains) == 1:
            return state.table_row[sel]
        return state.table_row[sel] + state.gain_index[sel] * self.cells_per_gain

    def _place(self, state: State, i: int, g: np.random.Generator, start_half_mm: float) -> None:
        """The start position (2 uniforms) and the uniform particle cloud (M·2 uniforms)."""
        state.position_mm[i] = g.uniform(-start_half_mm, start_half_mm, size=2)
        state.odometry_mm[i] = 0.0
        h = state.half_mm[i]
        uniform_in_box(g, np.array([-h, -h]), np.array([h, h]), state.n_particles,
                       out_xy=(state.particles_mm[i, 0], state.particles_mm[i, 1]))
        state.n_observations[i] = 0
        state.elapsed[i] = 0

    def move(self, state: State, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The carriage moves by the commanded moves (k, 2), kept inside the allowed box (truncated at the walls)."""
        h = state.half_mm[ids][:, None]
        state.position_mm[ids] = np.minimum(np.maximum(state.position_mm[ids] + moves_mm, -h), h)

    def histogram_origin(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float32]:
        """(k, 2) float32: the offsets' origin and the histogram's centre (the carriage here)."""
        return state.position_mm[ids].astype(np.float32)

    def offsets_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Sensor-model offsets (…, M, 2) of env ``i``'s hypotheses ``particles`` (M, 2) after commanded
        moves (2,) or (C, 2), mm, by the env's own motion rule (what an agent predicts, paper Algorithm 1).
        """
        raise NotImplementedError

    def particles_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Env ``i``'s hypotheses (…, M, 2) after commanded moves (2,) or (C, 2), mm."""
        raise NotImplementedError

    #: Coordinates of a hypothesis an agent passes to the predictions (position only here).
    particle_dims = 2

    def predicted_mean_std(self, state: State, i: int, particles: NDArray, moves_mm: NDArray,
                           level: int | None = None) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of the reading each hypothesis predicts after the moves (at gain
        level ``level``; default the current one).
        """
        return self.sensor_model(state, i, level).mean_std(self.offsets_after_move(state, i, particles, moves_mm))


class TargetTask(_Task):
    """ElectroLoc-v0: a target sphere (or a pool of conditions) whose position the particles estimate."""

    name = "localize"

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.pool: tuple[Condition, ...] = params.conditions()
        self._analytic = [[AnalyticSensorModel(self.at_gain(c, j)) for j in range(len(self.gains))]
                          for c in self.pool]
        self._descriptors = [condition_descriptor(c) for c in self.pool]
        self._grids: list[NDArray[np.float64]] = []  # built after the memory check (table_cells)

    def calibration_points(self) -> int:
        """The largest calibration grid's points per axis (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        return max(_grid_points_bound(self.protocol, c.allowed_half_width_mm) for c in self.pool)

    def table_cells(self) -> int:
        """Coefficient rows per env (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        self._grids = [calibration_grid_for(c, self.protocol) for c in self.pool]
        self.cells_per_gain = max(_cells(g) for g in self._grids)
        return self.cells_per_gain * len(self.gains)

    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in order: condition (pool of several), calibration seed (unless
        fixed), target (``randomize_target``), start position, particles.
        """
        pool = self.pool
        k = int(g.integers(len(pool))) if len(pool) > 1 else 0
        c = pool[k]
        self._set_world(state, i, c, k, c, self._descriptors[k])
        seed = self._cal_seed(g)
        state.cal_seed[i] = seed
        state.model[i] = [None] * len(self.gains) if self.calibrated else self._analytic[k]
        if self.calibrated:
            for j in range(len(self.gains)):  # the robot calibrates at every gain level
                rows = self._set_grid(state, i, self._grids[k], self.protocol.grid_step_mm, j)
                cj, sj = self.at_gain(c, j), self.gain_seed(seed, j)
                if self.params.calibration_seed is not None:
                    rows[:] = _fixed_coefficients(cj, sj, self.protocol)
                else:
                    calibration_coefficients(cj, sj, self.protocol, out=rows)
        s = c.start_half_width_mm
        if self.params.randomize_target:
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
        h = state.half_mm[i]
        carriage = np.minimum(np.maximum(state.position_mm[i] + moves_mm, -h), h).astype(particles.dtype)
        return particles - carriage[..., None, :]

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
            models[j] = make_sensor_model("calibrated", self.at_gain(state.world[i], j),
                                          self.gain_seed(int(state.cal_seed[i]), j), self.protocol)
        return models[j]


class MapTask(_Task):
    """ElectroLocGlobal-v0: the robot localises itself in a mapped tank (paper §6.5)."""

    name = "global"
    offset_sign = np.float32(-1.0)

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        layout = params.layout
        self.fixed_scene: Scene | None = layout if isinstance(layout, Scene) else (
            BENCHMARK_SCENE if layout == "benchmark" else None)
        self.scene_template = self.fixed_scene if self.fixed_scene is not None else BENCHMARK_SCENE
        self.blur_mm = params.position_blur_mm
        self._episodes = 0  # world keys of random layouts: one per episode

    def calibration_points(self) -> int:
        """The calibration grid's points per axis (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        return _grid_points_bound(self.protocol, self.scene_template.allowed_half_width_mm)

    def table_cells(self) -> int:
        """Coefficient rows per env (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        self.cells_per_gain = _cells(calibration_grid_for(_scene_condition(self.scene_template), self.protocol))
        return self.cells_per_gain

    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in order: layout (``"random"``), calibration seed (unless fixed),
        start position, particles.
        """
        if self.fixed_scene is None:
            scene = BENCHMARK_SCENE.replace(name="random-six-cylinders", objects=random_cylinder_layout(g))
            self._episodes += 1
            key = self._episodes
        else:
            scene, key = self.fixed_scene, 0
        condition = _scene_condition(scene)
        self._set_world(state, i, scene, key, condition, _descriptor(condition))
        seed = self._cal_seed(g)
        state.cal_seed[i] = seed
        model = make_map_sensor_model(self.params.sensor_model, scene, seed, self.blur_mm, self.protocol)
        state.model[i] = model
        if self.calibrated:
            rows = self._set_grid(state, i, model.grid_mm, model.grid_step_mm)
            bilinear_coefficients(model.mean_table_V, model.std_table_V, model.noise_std_V, rows)
        self._place(state, i, g, scene.start_half_width_mm)

    def move(self, state: State, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The carriage moves (kept in the box); the odometry adds the commanded move; every position
        hypothesis moves by it and is kept in the box, as the true carriage is (deterministic motion,
        paper §4.1).
        """
        super().move(state, ids, moves_mm)
        state.odometry_mm[ids] = state.odometry_mm[ids] + moves_mm
        h = state.half_mm[ids].astype(np.float32)[:, None, None]
        state.particles_mm[ids] = _shift_in_box(state.particles_mm[ids], moves_mm.astype(np.float32)[:, :, None], h)

    def particles_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Every position hypothesis moved by the commanded move and kept in the box (as :meth:`move`)."""
        t = particles.dtype.type
        return _shift_in_box(particles, moves_mm.astype(particles.dtype)[..., None, :], t(state.half_mm[i]))

    def offsets_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Map origin − carriage hypothesis after the move."""
        return -self.particles_after_move(state, i, particles, moves_mm)

    def true_mean_V(self, state: State, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) noise-free, unsaturated true readings of envs ``ids`` (the map's superposition), V."""
        position = state.position_mm[ids]
        groups = group_by_world(state, ids)
        if len(groups) == 1:
            return groups[0][0].expected_reading(position, saturate=False)
        out = np.empty(len(ids))
        for scene, rows in groups:
            out[rows] = scene.expected_reading(position[rows], saturate=False)
        return out

    def histogram_origin(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float32]:
        """(k, 2) float32 zeros: the map origin (the histogram covers the whole map box)."""
        return np.zeros((len(state.half_mm[ids]), 2), dtype=np.float32)

    def truth_mm(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) what the belief estimates: the true carriage position, mm."""
        return state.position_mm[ids]

    def sensor_model(self, state: State, i: int, level: int | None = None) -> Any:
        """Env ``i``'s map sensor model (built at reset; the map has one gain)."""
        return state.model[i]


def _shift_in_box(points: NDArray, shift: NDArray, half: Any) -> NDArray:
    """``min(max(points + shift, −half), half)``: the deterministic motion of position hypotheses."""
    return np.minimum(np.maximum(points + shift, -half), half)


def make_task(params: EnvParams) -> TargetTask | MapTask:
    """The task object of ``params.task``."""
    if params.task == "unknown":
        from electroloc_gym.core.unknown import UnknownTargetTask

        return UnknownTargetTask(params)
    return TargetTask(params) if params.task == "localize" else MapTask(params)
