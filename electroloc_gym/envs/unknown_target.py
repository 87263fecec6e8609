"""ElectroLocUnknownTarget-v0: localise a sphere whose size and material the robot does not know (paper §7).

A thin adapter over the simulation core with one env of the ``"unknown"`` task
(:mod:`electroloc_gym.engines.numba_core.unknown`).
"""

from __future__ import annotations

from typing import Any

from electroloc_gym.engines.numba_core.unknown import UnknownTargetOptions, UnknownTargetTask
from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.world.conditions import Condition

__all__ = ["UnknownTargetEnv"]


class UnknownTargetEnv(ElectroLocEnv):
    """
    ## Description

    ElectroLoc-v0 with a hidden target: §7 of the paper proposes that "the conductivity and diameter
    of the target could be two more dimensions in the search space". Each episode's sphere has a
    radius and a material the agent is not told; the belief's particles (5000 by default) are hypotheses
    (x, y, radius, χ) and the sensor model is the theoretical EEV of each hypothesis' sphere (§7's
    proposal that a theoretical EEV replace calibration) or, with ``sensor_model="interpolated"``,
    an EEV interpolated from calibrated EEVs at a few known radii
    (:mod:`electroloc_gym.sensor_models.shape`). Success stays the position criterion
    (√trace Σ of the x–y belief ≤ 10 mm); the size and material estimates are reported beside it.

    ## Action Space, Rewards, Episode End

    As ElectroLoc-v0 (``Box(-1, 1, (2,))`` × 10 mm or ``Discrete(9)``; −1 per reading; success or
    ``max_observations`` readings).

    ## Observation Space

    As ElectroLoc-v0 (81 belief features, or 3 raw), except entries 76–77, which carry the belief's
    mean radius / 25 mm and mean χ instead of the true ones. Entries 78–80 (gain, noise, signal scale)
    are the tank's: they are the amplifier settings of the paper's trial, which the paper chose per
    sphere size, so they hint at the size class; the belief's prior does not use them.

    ## Starting State

    The tank (water, amplifier, workspace, signal scale) is drawn from the ``condition`` pool (default
    ``"random"``: the eight presets). ``target_draw="prior"`` (default) draws the sphere: radius uniform
    in ``radius_range_mm`` (default 5–20 mm, which covers the paper's 6.35 and 19.05 mm), and
    ``contrast="binary"`` (default) a conductor (χ = +1) or an insulator (χ = −½) with equal
    probability, or ``contrast="continuous"`` χ uniform in [−½, 1]. ``target_draw="condition"`` keeps the
    condition's own sphere (hidden): the benchmark over the paper's eight sphere/water pairs.
    Particles: positions uniform over the allowed box, radii uniform in ``radius_range_mm``, χ from the
    same prior as the target.

    ## Info

    ElectroLoc-v0's keys plus ``radius_estimate_mm`` (the particles' median radius), ``radius_mean_mm``,
    ``radius_spread_mm`` (their std), ``chi_estimate``, ``chi_spread``, ``p_conductor`` (fraction of
    particles with χ > 0),
    ``material_estimate`` (``"conductor"`` if ``p_conductor`` > ½, else ``"insulator"``), and the ground
    truth for evaluation (agents must not act on it): ``target_radius_mm``, ``target_chi``,
    ``radius_error_frac`` (|estimate − true| / true) and ``material_correct``.

    ## Accessors

    As ElectroLoc-v0. ``belief.particles`` is (M, 4): x, y (mm), radius (mm), χ;
    ``predicted_reading_model(particles, moves)`` takes such (M, 4) hypotheses (min-var votes on the
    x–y variance of this cloud). ``condition`` is the episode's tank with its hidden sphere (ground
    truth, for evaluation and rendering only).

    ## Arguments

    ```python
    gym.make("ElectroLocUnknownTarget-v0", condition="random", target_draw="prior",
             radius_range_mm=(5.0, 20.0), contrast="binary", sensor_model="analytic",
             eev_radii_mm=(5.0, 7.5, …, 20.0), observation="belief", n_particles=5000,
             max_observations=35, success_spread_mm=10.0, signal=<get_condition's default>,
             action_type="continuous", randomize_target=False, calibration_seed=None,
             calibration=DEFAULT_CALIBRATION, max_episode_steps=None, render_mode=None)
    ```

    Every argument is a field of :class:`electroloc_gym.contract.params.EnvParams`; any other argument, or a
    value out of range, is a ValueError naming it. ``sensor_model`` is ``"analytic"`` (the theoretical
    EEV) or ``"interpolated"`` (calibrated steel and Delrin EEVs at ``eev_radii_mm``, the paper's
    protocol ``calibration``, seeded per episode as ElectroLoc-v0's calibration).

    ## Version History

    * v0: initial version.
    """

    @property
    def condition(self) -> Condition:
        """The episode's tank with its hidden sphere (ground truth; before the first reset: the first tank)."""
        if self._state.world[0] is None:
            return self._task.default_world()
        task = self._task
        if not isinstance(task, UnknownTargetTask):
            raise TypeError(f"{type(self).__name__} runs an UnknownTargetTask, got {type(task).__name__}")
        return task.true_condition(self._state, 0)

    @property
    def target_draw(self) -> str:
        """``"prior"`` or ``"condition"``."""
        return self.params.options_as(UnknownTargetOptions).target_draw

    @property
    def radius_range_mm(self) -> tuple[float, float]:
        """The radius prior's range, mm."""
        return self.params.options_as(UnknownTargetOptions).radius_range_mm

    @property
    def contrast(self) -> str:
        """``"binary"`` or ``"continuous"``."""
        return self.params.options_as(UnknownTargetOptions).contrast

    def _make_renderer(self, render_mode: str) -> Any:
        from electroloc_gym.views.render import EpisodeRenderer

        return EpisodeRenderer(render_mode)
