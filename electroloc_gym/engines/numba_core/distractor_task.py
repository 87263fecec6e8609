"""The ``localize`` task with distractors (ElectroLoc-v0's ``distractors=`` argument).

Distractors are objects in the tank that are not the target (the physics, their draws and layouts:
:mod:`electroloc_gym.world.distractors`). This task is
:class:`~electroloc_gym.engines.numba_core.localize_task.LocalizeTask`
with two changes, and only these:

* **episode draws** (:meth:`LocalizeDistractorsTask.begin_episode`): after the plain task's draws
  (condition, calibration seed, target, start position, particles), the episode's distractor set —
  drawn from the env's generator clear of the target (``distractors=D``: per object shape, diameter,
  material, then centres by rejection, the column construction where that fails), or the explicit
  layout itself (no draws). With D = 0 nothing
  is drawn: the generator's stream, and so every episode, is the plain task's bit for bit. A count mix
  (``distractors=(0, 1, 2)``) first draws the episode's count.
* **true reading** (:meth:`LocalizeDistractorsTask.true_mean_V`): the target's noise-free reading plus
  the distractors' perturbations, superposed in the world's water, amplifier, signal scale and
  geometry (and times the gain factor of the reading with dynamic gain). Without distractors it returns
  the plain task's array itself.

The agent's sensor model, the belief update, the predictions agents make and the observation know
only the target: the distractors are the model mismatch a real tank imposes. The info gains
``distractors_mm`` — each env's centres, mm, a fixed (D, 2) array padded with zero rows past the
episode's count (NaN would make equal infos compare unequal), D the most distractors the env can have —
and ``distractors_count``, the episode's count, for
renderers and evaluation only (like ``target_mm``: agents must not act on them); fixed shapes, so a count
mix keeps every info shape from episode to episode. The plain env (D = 0) keeps the plain info keys.

An explicit layout is checked once, at construction, against every condition of the pool (centres in
the allowed box, footprints clear of the condition's target); it needs ``randomize_target=False``,
since a drawn target could land on a fixed distractor. A draw is checked once too: its count must fit
beside every target the env can draw (:meth:`~electroloc_gym.world.distractors.DistractorDraw.check_fits`),
so that every episode's draw finishes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.params import EnvParams, LocalizeOptions
from electroloc_gym.contract.task_spec import option
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.world.distractors import DistractorDraw, DistractorSet, resolve_distractors

__all__ = ["LocalizeDistractorsTask", "DistractorOptions", "DISTRACTOR_INFO_KEY", "DISTRACTOR_COUNT_INFO_KEY"]

#: The info key of the distractors' centres ((D, 2) per env, mm; zero rows past the episode's count).
DISTRACTOR_INFO_KEY = "distractors_mm"
#: The info key of the episode's distractor count (per env; at most D).
DISTRACTOR_COUNT_INFO_KEY = "distractors_count"


def _distractors(name: str, value: Any) -> DistractorDraw | DistractorSet:
    """The distractors resolved (a draw or a layout; one error naming ``distractors``)."""
    return resolve_distractors(value)


@dataclass(frozen=True)
class DistractorOptions(LocalizeOptions):
    """The distractors' option (ElectroLoc-v0's), beside the tank's.

    Attributes:
        distractors: objects that are not the target, in the true reading only: a count D drawn per episode,
            a ``DistractorDraw``, a dict of its fields, or an explicit layout (a ``DistractorSet`` or a sequence
            of ``SceneObject``); stored resolved (0: none, the plain env).
    """

    distractors: Any = option(
        0, doc="objects that are not the target: a count, a DistractorDraw or a layout", check=_distractors
    )


class LocalizeDistractorsTask(LocalizeTask):
    """ElectroLoc-v0: the localize task, with ``distractors`` in the true reading (module docstring).

    Raises:
        ValueError: an explicit layout with ``randomize_target=True``, or one that leaves a condition's
            allowed box or overlaps its target (naming ``distractors`` and the object); a draw whose count
            cannot always fit beside the targets the env draws.
    """

    Options = DistractorOptions
    options: DistractorOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.options = params.options_as(DistractorOptions)
        spec = self.options.distractors
        self.spec: DistractorDraw | DistractorSet = spec
        if isinstance(spec, DistractorSet) and len(spec):
            if self.options.randomize_target:
                raise ValueError(
                    "distractors: an explicit layout needs randomize_target=False (a drawn target "
                    "could overlap it); pass a count or a DistractorDraw to draw them per episode"
                )
            for c in self.pool:
                try:
                    spec.validate(c, c.target_xy_mm)
                except ValueError as exc:
                    raise ValueError(f"distractors in condition {c.name!r}: {exc}") from None
        if isinstance(spec, DistractorDraw):  # every target the env can draw must leave room for the draw
            for c in self.pool:
                try:
                    spec.check_fits(c, c.start_half_width_mm if self.options.randomize_target else None)
                except ValueError as exc:
                    raise ValueError(f"distractors: {exc}") from None
        #: D, the most distractors an episode has (0: the plain task).
        self.count = len(spec) if isinstance(spec, DistractorSet) else spec.max_count
        self.info_keys = tuple(self.info_keys) + (
            (DISTRACTOR_INFO_KEY, DISTRACTOR_COUNT_INFO_KEY) if self.count else ()
        )

    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """The plain task's draws (:meth:`LocalizeTask.begin_episode`), then the distractor set's (none for D = 0).

        The draw always finishes: construction refused any draw whose count could fail to fit
        (:meth:`~electroloc_gym.world.distractors.DistractorDraw.check_fits`).
        """
        super().begin_episode(state, i, g)
        if not self.count:
            return
        if len(state.distractor_scenes) != state.num_envs:
            state.distractor_scenes = [None] * state.num_envs
        c = state.world[i]
        spec = self.spec
        layout = spec if isinstance(spec, DistractorSet) else spec.draw(c, state.target_mm[i], g)
        state.distractor_scenes[i] = layout.scene(c)

    def true_mean_V(self, state: State, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) noise-free, unsaturated true readings, V: the target's plus the distractors' (superposition)."""
        out = super().true_mean_V(state, ids)
        if not self.count:
            return out
        scenes = state.distractor_scenes
        extra = np.array(
            [
                0.0 if scenes[i] is None else scenes[i].expected_reading(state.position_mm[i], saturate=False)
                for i in ids.tolist()
            ],
            dtype=np.float64,
        )
        if len(self.gains) > 1:
            extra *= self._gain_array[state.gain_index[ids]]
        return out + extra

    def task_info(self, state: State, sel: Any) -> dict[str, NDArray[Any]]:
        """``distractors_mm``: (k, D, 2) float64 distractor centres, mm, D the env's most distractors (fixed per
        env), rows past the episode's own count 0 (read only the first ``distractors_count``);
        ``distractors_count``: (k,) int64, the episode's count
        (with D > 0). The shapes never change between episodes, as Gymnasium's vector envs need.
        """
        base = super().task_info(state, sel)
        if not self.count:
            return base
        ids = np.arange(state.num_envs)[sel]
        xy = np.zeros((len(ids), self.count, 2))
        n = np.zeros(len(ids), dtype=np.int64)
        for row, i in enumerate(ids.tolist()):
            scene = state.distractor_scenes[i]
            if scene is not None:
                n[row] = len(scene.objects)
                xy[row, : n[row]] = [o.xy_mm for o in scene.objects]
        return {**base, DISTRACTOR_INFO_KEY: xy, DISTRACTOR_COUNT_INFO_KEY: n}

    def distractor_scene(self, state: State, i: int) -> Any:
        """Env ``i``'s episode distractors as a :class:`~electroloc_gym.world.scene.Scene` (None without)."""
        return state.distractor_scenes[i] if self.count else None
