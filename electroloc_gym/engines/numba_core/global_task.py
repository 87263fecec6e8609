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
    """The env ElectroLocGlobal-v0: what it simulates, its spaces, reward, episode end, info and arguments.

    ## Description

    Global self-localisation of the electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008,
    §6.5, Fig. 13–14, Table 2). The tank holds six vertical cylinders of different diameters and
    conductivities within ±80 mm; their EEV map (Fig. 14) is known to the robot. The robot does
    *not* know where it is: the particle belief (2500 particles, uniform over the tank box at start)
    is over the carriage's own position in the map frame. Every commanded move shifts all particles
    by the move (deterministic motion, :meth:`electroloc_gym.engines.numba_core.global_task.GlobalTask.move`: clipped
    at the
    walls exactly as the true carriage is); every reading reweights them with the map's sensor model.
    The agent moves the carriage until the belief is tight: √trace Σ ≤ 10 mm. The filter, sensor-model machinery, action
    space, success rule, observation cap and observation layout are those of ``ElectroLoc-v0`` (the
    same simulation core, :mod:`electroloc_gym.engines.numba_core`): the hidden state differs, the machinery does not.

    The map (``layout="benchmark"``): :data:`electroloc_gym.world.scene.BENCHMARK_SCENE`, six cylinders
    (Ø 6.35–38.1 mm; steel, brass, aluminium, Delrin, PVC and a 1000 µS/cm gel) in fresh water
    (160 µS/cm) with the fresh-water amplifier (G = 191, σ_s = 0.25 mV RMS) and signal scale 1;
    carriage box ±80 mm, start box ±70 mm. See :mod:`electroloc_gym.world.scene` for the physics and
    :mod:`electroloc_gym.sensor_models.map` for the map's sensor models.

    ## Action Space

    As ``ElectroLoc-v0``: ``Box(-1, 1, (2,), float32)`` scaled to a move of at most 10 mm per axis
    (``action_type="discrete"``: ``Discrete(9)``). The true carriage is kept inside the box (truncated
    at the walls); the robot is not told when that happens.

    ## Observation Space

    ``observation="belief"`` (default): ``Box(-1, 1, (81,), float32)``, the layout of ``ElectroLoc-v0``
    (:mod:`electroloc_gym.contract.observation`) built by the same code with the *map origin* as the
    reference point instead of the (here unknown) carriage. What differs: entries 0–1 are the odometry
    (the sum of the commanded moves since reset, start = 0) / H, clipped; entries 4–5 the belief mean,
    i.e. the estimated carriage position in the map frame, / 2H; entries 12–75 the histogram of the
    particles over the map box ±H (allocentric); entries 76–80 the descriptor of ``condition`` (mean
    radius, χ*, gain, noise, scale).

    χ* is the sphere contrast of the first object's conductivity (``condition``'s stand-in target).
    H = 80 mm for the benchmark map. ``observation="raw"``: ``[odometry_x/H, odometry_y/H, Φ/10 V]``
    (no belief; the true position is never observed).

    ## Rewards

    −1 per step (every new reading), as ``ElectroLoc-v0``.

    ## Starting State

    The carriage starts uniformly in the start box (±70 mm); the particles are uniform over the
    allowed box (±80 mm). reset() takes and fuses the first reading (observation count 1).

    ## Episode End

    * Termination: the belief's spread √trace Σ ≤ ``success_spread_mm`` (10 mm): success.
    * Truncation: ``max_observations`` readings (35) fused without success: failure.

    ## Info

    As ``ElectroLoc-v0``: ``position_mm`` (the TRUE carriage position in the map frame, for
    evaluation), ``estimate_mm`` (belief mean), ``error_mm`` (|estimate − true position|),
    ``spread_mm``, ``reading_V``, ``n_observations``, ``success``, ``condition`` (the scene's name).
    ``position_mm`` and ``error_mm`` use the ground truth: agents must not act on them.

    ## Accessors (read-only, on ``env.unwrapped``)

    ``belief`` (over the carriage position, map frame), ``sensor_model`` (the map model: ``mean_std`` /
    ``log_likelihood`` of offsets = map origin − carriage = −position), ``scene`` (the map),
    ``condition`` (amplifier, water, boxes as a Condition; its target is a nominal stand-in),
    ``allowed_box_mm``, ``move_bounds_mm`` (±10 mm: the robot cannot know where the walls are),
    ``odometry_mm``, ``n_observations``, ``last_reading_V``, ``path_mm`` (true path, for plots),
    ``position_mm`` (ground truth, evaluation only), and the shared
    ``predicted_reading_model(particles_mm, moves_mm)`` → (mean_V, std_V) of the reading each
    position hypothesis predicts after a commanded move (carriage_i = clip(particle_i + move)) and
    ``predicted_particles_mm`` (the hypotheses after the move).

    ## Arguments

    ```python
    gym.make("ElectroLocGlobal-v0", layout="benchmark", observation="belief",
             sensor_model="calibrated", n_particles=2500, max_observations=35,
             success_spread_mm=10.0, action_type="continuous", calibration_seed=None,
             calibration=DEFAULT_CALIBRATION, position_blur_mm=2.0, max_episode_steps=None,
             render_mode=None)
    ```

    Every argument is a field of :class:`electroloc_gym.contract.params.EnvParams`; any other argument
    (``condition``, for instance), or a value out of range, is a ValueError naming it.

    * ``layout``: ``"benchmark"`` (the fixed map), ``"random"`` (a new six-cylinder map per episode,
      drawn from the env's seeded generator by :func:`electroloc_gym.world.scene.random_cylinder_layout`),
      or a :class:`~electroloc_gym.world.scene.Scene`.
    * ``sensor_model``: ``"analytic"`` or ``"calibrated"`` (the paper's 4 mm grid of 10 readings over
      the carriage box, drawn per episode from ``calibration_seed`` or the env's generator).
    * ``position_blur_mm``: the map sensor model's position blur b (std ⊕ |∇Φ|·b), 2 mm by default;
      0 gives the bare model, with which 2500 particles often converge on a wrong place (see
      :mod:`electroloc_gym.sensor_models.map`).

    ## Version History

    * v0: initial version.
    """

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
