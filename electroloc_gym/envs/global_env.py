"""ElectroLocGlobal-v0: the robot localises itself in a pre-mapped tank of six cylinders (paper §6.5).

A thin adapter (:class:`~electroloc_gym.envs.adapter.CoreEnv`) over the simulation core with one env
of the ``"global"`` task (:mod:`electroloc_gym.engines.numba_core.global_task`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.params import MAX_STEP_MM
from electroloc_gym.engines.numba_core.global_task import GlobalOptions, GlobalTask
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.world.scene import Scene

__all__ = ["GlobalEnv"]


class GlobalEnv(CoreEnv):
    """
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

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(render_mode, **kwargs)

    @property
    def layout(self) -> str:
        """``"benchmark"``, ``"random"`` or ``"custom"`` (a Scene)."""
        layout = self.params.options_as(GlobalOptions).layout
        return layout if isinstance(layout, str) else "custom"

    @property
    def position_blur_mm(self) -> float:
        """The map sensor models' position blur b, mm."""
        return self.params.options_as(GlobalOptions).position_blur_mm

    @property
    def calibration_seed(self) -> int | None:
        """The fixed calibration seed, or None (a new calibration per episode)."""
        return self.params.calibration_seed

    @property
    def scene(self) -> Scene:
        """The current episode's map."""
        w = self._state.world[0]
        if w is not None:
            return w
        task = self._task
        if not isinstance(task, GlobalTask):
            raise TypeError(f"{type(self).__name__} runs a GlobalTask, got {type(task).__name__}")
        return task.scene_template

    @property
    def odometry_mm(self) -> NDArray[np.float64]:
        """Sum of the commanded moves since reset, mm (what the robot knows of its own motion)."""
        return self._state.odometry_mm[0].copy()

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(−10, −10), (10, 10) mm: the robot does not know where it is, hence not where the walls are."""
        return np.full(2, -MAX_STEP_MM), np.full(2, MAX_STEP_MM)

    def _make_renderer(self, render_mode: str) -> Any:
        from electroloc_gym.views.render import GlobalEpisodeRenderer

        return GlobalEpisodeRenderer(render_mode)
