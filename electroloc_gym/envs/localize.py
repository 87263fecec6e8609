"""The localise family's env: one target in a tank, its accessors and renderer (every task of :class:`LocalizeTask`).

:class:`LocalizeEnv` (single) and :class:`LocalizeVectorEnv` (native vector) add what every task of the localise
family (:class:`~electroloc_gym.engines.numba_core.localize_task.LocalizeTask`: a target sphere in a tank of the
paper's conditions, the carriage, the sensor and the particle belief) shows beyond
:class:`~electroloc_gym.envs.adapter.CoreEnv`: the true target, the sensor layout, the carriage's move bounds and
the episode renderer. An entry's own env classes are built on them (:mod:`.generic`); their documentation is
the task class's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.params import MAX_STEP_MM, LocalizeOptions
from electroloc_gym.engines.numba_core.array import ArrayLocalizeTask
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.envs.vector import CoreVectorEnv
from electroloc_gym.registry import env_class_named
from electroloc_gym.world.sensor_array import SensorLayout

__all__ = ["LocalizeEnv", "LocalizeVectorEnv"]


class LocalizeEnv(CoreEnv):
    """One env of a localise-family task (module docstring): ``CoreEnv``'s accessors, and ``target_mm``,
    ``randomize_target``, ``calibration_seed``, ``sensor_layout``, ``fixed_carriage``, ``move_bounds_mm``.
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(render_mode, **kwargs)

    @property
    def randomize_target(self) -> bool:
        """Whether the target is drawn uniformly in the start box per episode."""
        return self.params.options_as(LocalizeOptions).randomize_target

    @property
    def calibration_seed(self) -> int | None:
        """The fixed calibration seed, or None (a new calibration per episode)."""
        return self.params.calibration_seed

    @property
    def target_mm(self) -> NDArray[np.float64]:
        """True target centre (x, y), mm (a copy): ground truth for evaluation and rendering, not for agents."""
        return self._state.target_mm[0].copy()

    @property
    def sensor_layout(self) -> SensorLayout:
        """The carriage's sensing pairs (K, 2, 2 electrode offsets in mm: ``.electrodes``, ``.n_pairs``)."""
        task = self._task
        if not isinstance(task, ArrayLocalizeTask):  # the unknown-target task has one fixed pair, no layout
            raise AttributeError(f"{type(self).__name__} has no sensor_layout")
        return task.sensor_layout

    @property
    def fixed_carriage(self) -> bool:
        """Whether the carriage never moves (the stationary array: every move is ignored)."""
        task = self._task
        return isinstance(task, ArrayLocalizeTask) and task.fixed_carriage

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lo, hi) moves, mm, within ±10 mm that keep the carriage in the allowed box (0 always inside; both 0
        with ``fixed_carriage``).
        """
        if self.fixed_carriage:
            return np.zeros(2), np.zeros(2)
        low, high = self.allowed_box_mm
        p = self._state.position_mm[0]
        lo = np.minimum(np.maximum(-MAX_STEP_MM, low - p), 0.0)
        hi = np.maximum(np.minimum(MAX_STEP_MM, high - p), 0.0)
        return lo, hi

    def _make_renderer(self, render_mode: str) -> Any:
        from electroloc_gym.views.render import EpisodeRenderer

        return EpisodeRenderer(render_mode)


class LocalizeVectorEnv(CoreVectorEnv):
    """``num_envs`` envs of a localise-family task stepped as one core (:mod:`electroloc_gym.envs.vector`), with
    the true targets.
    """

    @property
    def target_mm(self) -> NDArray[np.float64]:
        """Every sub-env's true target now (N, 2), mm (a copy): ground truth, for evaluation."""
        return np.copy(self._state.target_mm, order="C")


def __getattr__(name: str) -> Any:
    """An entry's env class by its name (recorded entry points name this module), else a name that moved out
    (``registry.env_class_named``).
    """
    return env_class_named(__name__, name)
