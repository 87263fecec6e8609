"""The ``global`` task (ElectroLocGlobal-v0): the robot localises itself in a mapped tank (paper §6.5).

Hidden state: the robot's own carriage position in the map frame; every commanded move shifts it, and
shifts every particle by the same move, kept in the box as the true carriage is (deterministic motion,
paper §4.1). The sensor-model offset of particle i is map origin − carriage hypothesis = −particle_i.
The episode's world is a :class:`~electroloc_gym.world.scene.Scene` (the fixed benchmark map, a given one, or
a new seeded six-cylinder map per episode). Observation entries 0–1 carry the odometry (the sum of the
commanded moves), the belief's frame is the map's (histogram over the whole map box).

(The module is ``global_task`` because ``global`` is a Python keyword; the task, the env id, the env
class and ``electroloc bench --env`` all say "global".)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.motion import carriage_after_move_mm
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.contract.task_spec import Choice, Real, TaskOptions, option
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.engines.numba_core.task import Task
from electroloc_gym.engines.numba_core.worlds import descriptor, group_by_world, scene_condition
from electroloc_gym.kernels import bilinear_coefficients
from electroloc_gym.sensor_models import calibration_grid_for, coefficient_rows, grid_points_bound
from electroloc_gym.sensor_models.calibrated import CalibratedSensorModel
from electroloc_gym.sensor_models.map import DEFAULT_POSITION_BLUR_MM, make_map_sensor_model
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.scene import BENCHMARK_SCENE, Scene, random_cylinder_layout

__all__ = ["GlobalTask", "GlobalOptions", "LAYOUTS", "MAX_POSITION_BLUR_MM"]

#: Named maps: the fixed benchmark map, or a new seeded six-cylinder map per episode.
LAYOUTS = ("benchmark", "random")
#: The map sensor models' largest position blur, mm (the map's box is ±80 mm).
MAX_POSITION_BLUR_MM = 100.0


def _layout(name: str, value: Any) -> Any:
    """A :class:`~electroloc_gym.world.scene.Scene` as it is, else one of :data:`LAYOUTS`."""
    return value if isinstance(value, Scene) else Choice(LAYOUTS)(name, value)


@dataclass(frozen=True)
class GlobalOptions(TaskOptions):
    """ElectroLocGlobal-v0's own options.

    Attributes:
        layout: ``"benchmark"`` (the fixed map), ``"random"`` (a new six-cylinder map per episode) or a
            :class:`~electroloc_gym.world.scene.Scene`.
        position_blur_mm: the map sensor models' position blur b, mm (in [0, :data:`MAX_POSITION_BLUR_MM`]).
    """

    layout: Any = option("benchmark", doc="the map: 'benchmark', 'random' (one per episode) or a Scene", check=_layout)
    position_blur_mm: float = option(
        DEFAULT_POSITION_BLUR_MM,
        doc="the map sensor models' position blur",
        check=Real(0.0, MAX_POSITION_BLUR_MM, inclusive=True),
        unit="mm",
    )


def _shift_in_box(points: NDArray, shift: NDArray, half: Any) -> NDArray:
    """``clip(points + shift, −half, half)``: the deterministic motion of position hypotheses, the carriage's
    rule (:func:`~electroloc_gym.contract.motion.carriage_after_move_mm`).
    """
    return carriage_after_move_mm(np, points, shift, half)


class GlobalTask(Task):
    """ElectroLocGlobal-v0 (module docstring)."""

    belief_frame = "robot"
    hidden_keys = ("true_x_mm", "true_y_mm")

    offset_sign = np.float32(-1.0)
    Options = GlobalOptions
    options: GlobalOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.options = params.options_as(GlobalOptions)
        layout = self.options.layout
        self.fixed_scene: Scene | None = (
            layout if isinstance(layout, Scene) else (BENCHMARK_SCENE if layout == "benchmark" else None)
        )
        self.scene_template = self.fixed_scene if self.fixed_scene is not None else BENCHMARK_SCENE
        self.blur_mm = self.options.position_blur_mm

    def default_world(self) -> Scene:
        """The world before the first reset: the fixed map (the benchmark map for random layouts)."""
        return self.scene_template

    def calibration_points(self) -> int:
        """The calibration grid's points per axis (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        return grid_points_bound(self.protocol, self.scene_template.allowed_half_width_mm)

    def table_cells(self) -> int:
        """Coefficient rows per env (0 without a calibrated model)."""
        if not self.calibrated:
            return 0
        self.cells_per_gain = coefficient_rows(
            calibration_grid_for(scene_condition(self.scene_template), self.protocol)
        )
        return self.cells_per_gain

    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in order: layout (``"random"``), calibration seed (unless fixed),
        start position, particles.
        """
        if self.fixed_scene is None:  # a new map: a new world key (State.worlds_drawn counts them)
            scene = BENCHMARK_SCENE.replace(name="random-six-cylinders", objects=random_cylinder_layout(g))
            state.worlds_drawn += 1
            key = state.worlds_drawn
        else:
            scene, key = self.fixed_scene, 0
        condition = scene_condition(scene)
        self._set_world(state, i, scene, key, condition, descriptor(condition))
        seed = self._cal_seed(g)
        state.cal_seed[i] = seed
        model = make_map_sensor_model(self.params.sensor_model, scene, seed, self.blur_mm, self.protocol)
        state.model[i] = model
        if self.calibrated:
            if not isinstance(model, CalibratedSensorModel):
                raise TypeError(f"a calibrated map needs a CalibratedSensorModel, got {type(model).__name__}")
            rows = self._set_grid(state, i, model.grid_mm, model.grid_step_mm)
            bilinear_coefficients(model.mean_table_V, model.std_table_V, model.noise_std_V, rows)
        self._place(state, i, g, scene.start_half_width_mm)

    def move(self, state: State, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The carriage moves (kept in the box); the odometry adds the commanded move; every position
        hypothesis moves by it and is kept in the box, as the true carriage is.
        """
        super().move(state, ids, moves_mm)
        state.odometry_mm[ids] = state.odometry_mm[ids] + moves_mm
        h = state.half_mm[ids].astype(np.float32)[:, None, None]
        state.particles_mm[ids] = _shift_in_box(state.particles_mm[ids], moves_mm.astype(np.float32)[:, :, None], h)

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

    def belief_origin_mm(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) zeros: the map origin (the histogram covers the whole map box)."""
        return np.zeros((len(state.half_mm[ids]), 2))

    def reference_mm(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) the odometry: the sum of the commanded moves since reset, mm (the carriage is unknown)."""
        return state.odometry_mm[ids]

    def observation(self, state: State, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """The shared layouts; the belief observation's entries 0–1 are the odometry / H (clipped), its
        entries 4–5 the belief mean in the map frame.
        """
        obs = super().observation(state, ids)
        if self.params.observation == "belief":
            sel = slice(None) if ids is None else ids
            half = state.half_mm[sel]
            obs[:, 0:2] = np.minimum(np.maximum(self.reference_mm(state, sel) / half[:, None], -1.0), 1.0)
        return obs

    def truth_mm(self, state: State, ids: NDArray[np.intp] | slice) -> NDArray[np.float64]:
        """(k, 2) what the belief estimates: the true carriage position, mm."""
        return state.position_mm[ids]

    def sensor_model(self, state: State, i: int, level: int | None = None) -> Any:
        """Env ``i``'s map sensor model (built at reset; the map has one gain)."""
        return state.model[i]

    def particles_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Every position hypothesis moved by the commanded move and kept in the box (as :meth:`move`)."""
        t = particles.dtype.type
        return _shift_in_box(particles, moves_mm.astype(particles.dtype)[..., None, :], t(state.half_mm[i]))

    def offsets_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Map origin − carriage hypothesis after the move."""
        return -self.particles_after_move(state, i, particles, moves_mm)

    def world_condition(self, world: Any) -> Condition:
        """The map's amplifier, water and boxes as a ``Condition`` (its target a nominal stand-in)."""
        return scene_condition(world)
