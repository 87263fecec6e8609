"""The self-localising family's env: the robot's own position in a mapped tank, its accessors and renderer.

:class:`SelfLocalizeEnv` (single) and :class:`SelfLocalizeVectorEnv` (native vector) add what a task whose belief
is over the robot's own position (``Task.belief_frame == "robot"``: the paper's global localisation, §6.5) shows
beyond :class:`~electroloc_gym.envs.adapter.CoreEnv`: the map, the odometry, move bounds the robot can know
(±10 mm: it does not know where the walls are) and the map renderer. An entry's own env classes are built on
them (:mod:`.generic`); their documentation is the task class's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.params import MAX_STEP_MM
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.envs.vector import CoreVectorEnv
from electroloc_gym.world.scene import Scene

__all__ = ["SelfLocalizeEnv", "SelfLocalizeVectorEnv"]


class SelfLocalizeEnv(CoreEnv):
    """One env of a self-localising task (module docstring): ``CoreEnv``'s accessors, and ``scene``,
    ``odometry_mm``, ``calibration_seed``, ``move_bounds_mm``.
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(render_mode, **kwargs)

    @property
    def calibration_seed(self) -> int | None:
        """The fixed calibration seed, or None (a new calibration per episode)."""
        return self.params.calibration_seed

    @property
    def scene(self) -> Scene:
        """The current episode's map (before the first reset: the task's default map)."""
        w = self._state.world[0]
        return w if w is not None else self._task.default_world()

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


class SelfLocalizeVectorEnv(CoreVectorEnv):
    """``num_envs`` envs of a self-localising task stepped as one core (:mod:`electroloc_gym.envs.vector`), with
    their odometry; any map, ``"random"`` included (every sub-env draws its own map per episode).
    """

    @property
    def odometry_mm(self) -> NDArray[np.float64]:
        """Sum of the commanded moves since each sub-env's reset (N, 2), mm (a copy)."""
        return np.copy(self._state.odometry_mm, order="C")
