"""The unknown-target task (ElectroLocUnknownTarget-v0): position, radius and contrast estimated together.

The belief estimates the sphere's position, radius and contrast together (paper §7).

Each particle is a hypothesis (x, y, a, χ): position (mm), radius a (mm) and contrast χ (Eq. 4). The
position is stored as in the other tasks (``State.particles_mm``), the shape beside it
(``State.shape_particles``: radius, χ). The tank of an episode — water, amplifier, workspace, signal
scale — is a condition of the pool (by default the eight presets); its sphere is hidden: with
``target_draw="condition"`` the true sphere is the condition's own (the benchmark over the paper's
eight pairs), with ``"prior"`` it is drawn from the belief's prior (radius uniform in
``radius_range_mm``; ``contrast="binary"``: a conductor, χ = +1, or an insulator, χ = −½, with equal
probability; ``"continuous"``: χ uniform in [−½, 1]).

**Measurement update.** The log-likelihood of every hypothesis comes from the shape sensor model
(:mod:`electroloc_gym.sensor_models.shape`; exact elementwise numpy operations, as the analytic
models' of the other tasks), then the kernel layer does the rest as for the x–y clouds: the systematic
resampling indices (:func:`~electroloc_gym.kernels.resample_indices`), the resampling of position and
shape with the same indices, the jitter and the clip (:func:`~electroloc_gym.kernels.jitter_resampled`),
the statistics (:func:`~electroloc_gym.kernels.mean_cov_rows`, ``egocentric_counts``, ``row_sums``).
The one-pass x–y kernels (``loglik_assimilate``) are not used because they carry two coordinates
per particle; the two passes here carry any number. Jitter: N(0, 1 mm²) per position axis (as
the other tasks), N(0, (0.5 mm)²) on the radius, N(0, 0.02²) on a continuous χ (none on a binary
one); each coordinate is clipped to its range (the box, the radius range, [−½, 1]). The draws per
step: the reading's noise, U, then 4·M normal-table indices (x, y of particle j at 2j, 2j + 1; radius,
χ at 2M + 2j, 2M + 2j + 1). The statistics — position mean and covariance, histogram, the shape's
means and stds, the conductor fraction — come from the kernels' fixed-order sums, so every env's
values are those it gets alone, whatever N and the CPU.

**Reported estimates.** Radius: the particles' median radius. The posterior of the radius is skewed
toward big spheres (a weak reading cannot rule out a bigger, deeper sphere), which pulls the mean
upward; the median is the estimate that minimises the expected absolute error, chosen over the mean
on validation seeds (docs/extensions.md). The mean is reported beside it (``radius_mean_mm``) and is
the observation's entry 76. Material: conductor if more than half of the particles have χ > 0.
Success stays the position criterion (√trace Σ of x–y ≤ 10 mm).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.observation import HIST_BINS
from electroloc_gym.contract.params import EnvParams, GainOptions, LocalizeOptions
from electroloc_gym.contract.task_spec import (
    Choice,
    Column,
    Numbers,
    RecordField,
    Table,
    TaskState,
    option,
    state_array,
)
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.state import State as SimState
from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
from electroloc_gym.engines.numba_core.worlds import group_by_world
from electroloc_gym.kernels import egocentric_counts, jitter_resampled, mean_cov_rows, resample_indices, row_sums
from electroloc_gym.sensor_models.shape import DEFAULT_EEV_RADII_MM, InterpolatedShapeModel, TheoreticalShapeModel
from electroloc_gym.world.conditions import Condition, Target
from electroloc_gym.world.sensor import sphere_reading

__all__ = [
    "UnknownTargetTask",
    "UnknownTargetOptions",
    "UnknownTargetState",
    "TARGET_DRAWS",
    "CONTRASTS",
    "DEFAULT_RADIUS_RANGE_MM",
    "RADIUS_LIMITS_MM",
    "CONDUCTOR_CHI",
    "INSULATOR_CHI",
    "RADIUS_JITTER_MM",
    "CHI_JITTER",
    "SHAPE_INFO_KEYS",
    "MATERIALS",
    "SHAPE_RECORD_KEYS",
    "SHAPE_METRICS",
    "identification_statistics",
]

#: The contrasts of a perfect conductor and a perfect insulator (Eq. 4).
CONDUCTOR_CHI = 1.0
INSULATOR_CHI = -0.5
#: Jitter of the radius after resampling, mm; of a continuous χ. (0.5 mm with 5000 particles: chosen on
#: validation seeds 101 and 102 over 0.25 mm with 2500 and 10 000 particles, docs/extensions.md.)
RADIUS_JITTER_MM = 0.5
CHI_JITTER = 0.02
#: The material estimate's names, indexed by the info's ``material_index`` (0: a conductor, χ > 0; 1: an
#: insulator) — the task's ``info_names``, the env's ``metadata["info_names"]["material_index"]``.
MATERIALS = ("conductor", "insulator")
#: The info keys the unknown-target env adds.
SHAPE_INFO_KEYS = (
    "radius_estimate_mm",
    "radius_mean_mm",
    "radius_spread_mm",
    "chi_estimate",
    "chi_spread",
    "p_conductor",
    "material_index",
    "target_radius_mm",
    "target_chi",
    "radius_error_frac",
    "material_correct",
)
#: The identification results a benchmark record keeps (``"shape"``): the info keys but the χ spread, the
#: material by its name (``material_estimate``, from the info's ``material_index``).
SHAPE_RECORD_KEYS = tuple(
    "material_estimate" if k == "material_index" else k for k in SHAPE_INFO_KEYS if k != "chi_spread"
)


#: How the episode's sphere is drawn (``"prior"``: radius uniform in ``radius_range_mm``, material or
#: contrast from ``contrast``; ``"condition"``: the condition's own sphere).
TARGET_DRAWS = ("prior", "condition")
#: ``"binary"``: a conductor (χ = +1) or an insulator (χ = −½); ``"continuous"``: χ uniform in [−½, 1].
CONTRASTS = ("binary", "continuous")
#: The default radius range (prior of the belief and of the draws), mm.
DEFAULT_RADIUS_RANGE_MM = (5.0, 20.0)
#: The sphere radii the env may hypothesise or calibrate (``radius_range_mm``, ``eev_radii_mm``), mm: from a
#: 1 mm bead to a 100 mm ball, as large as the paper's smallest allowed box (±50 mm) allows.
RADIUS_LIMITS_MM = (1.0, 50.0)


def _radius_range(name: str, value: Any) -> tuple[float, ...]:
    """(low, high) radii in :data:`RADIUS_LIMITS_MM`, low < high."""
    r = Numbers(2, *RADIUS_LIMITS_MM, " mm")(name, value)
    if r[0] >= r[1]:
        raise ValueError(f"{name} must be (low, high) with low < high, got {r!r}")
    return r


def _eev_radii(name: str, value: Any) -> tuple[float, ...]:
    """Distinct radii in :data:`RADIUS_LIMITS_MM`, sorted."""
    r = tuple(sorted(Numbers(None, *RADIUS_LIMITS_MM, " mm")(name, value)))
    if len(set(r)) != len(r):
        raise ValueError(f"{name} must be distinct, got {r!r}")
    return r


@dataclass(frozen=True)
class UnknownTargetOptions(GainOptions, LocalizeOptions):
    """ElectroLocUnknownTarget-v0's own options, beside the tank's and the dynamic gain.

    Attributes:
        target_draw: ``"prior"`` (the sphere drawn from the prior) or ``"condition"`` (the condition's own
            sphere, hidden from the agent: the benchmark over the paper's pairs).
        radius_range_mm: (low, high) radius range of the prior, mm (in :data:`RADIUS_LIMITS_MM`, low < high).
        contrast: ``"binary"`` (conductor or insulator) or ``"continuous"`` (χ ∈ [−½, 1]).
        eev_radii_mm: ``sensor_model="interpolated"``: the radii of the calibrated EEVs (mm, in
            :data:`RADIUS_LIMITS_MM`, distinct; stored sorted) the model interpolates between.
    """

    target_draw: str = option("prior", doc="how the episode's sphere is drawn", check=Choice(TARGET_DRAWS))
    radius_range_mm: Any = option(
        DEFAULT_RADIUS_RANGE_MM, doc="(low, high) radius range of the prior", check=_radius_range, unit="mm"
    )
    contrast: str = option("binary", doc="the sphere's contrast: binary or continuous", check=Choice(CONTRASTS))
    eev_radii_mm: Any = option(
        DEFAULT_EEV_RADII_MM, doc="the interpolated model's calibrated radii", check=_eev_radii, unit="mm"
    )


@dataclass
class UnknownTargetState(TaskState):
    """The unknown target's per-env arrays (the hidden sphere and the belief's shape statistics).

    Attributes:
        target_shape: (N, 2) the true sphere's radius (mm) and χ.
        shape_mean: (N, 2) the belief's mean radius (mm) and mean χ.
        shape_std: (N, 2) their standard deviations (mm, —).
        radius_median_mm: (N,) the belief's median radius, mm (the reported estimate).
        p_conductor: (N,) the belief's fraction of particles with χ > 0.
    """

    target_shape: NDArray[np.float64] = state_array(np.float64, (2,))
    shape_mean: NDArray[np.float64] = state_array(np.float64, (2,))
    shape_std: NDArray[np.float64] = state_array(np.float64, (2,))
    radius_median_mm: NDArray[np.float64] = state_array(np.float64)
    p_conductor: NDArray[np.float64] = state_array(np.float64)


def _material(chi: NDArray) -> NDArray[np.int64]:
    """The material index (:data:`MATERIALS`) of contrasts ``chi``: 0 (conductor) where χ > 0, else 1."""
    return np.where(np.asarray(chi) > 0, 0, 1).astype(np.int64)


class UnknownTargetTask(LocalizeTask):
    """The env ElectroLocUnknownTarget-v0: what it simulates, its spaces, reward, episode end, info and arguments.

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

    #: A hypothesis is (x, y, a, χ): two shape coordinates (radius, χ) per particle.
    particle_dims = 4
    info_keys = SHAPE_INFO_KEYS
    info_names: ClassVar[Mapping[str, tuple[str, ...]]] = {"material_index": MATERIALS}
    hidden_keys = ("target_x_mm", "target_y_mm", "target_radius_mm", "target_chi")
    hides_sphere = True
    Options = UnknownTargetOptions
    State = UnknownTargetState
    options: UnknownTargetOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.options = params.options_as(UnknownTargetOptions)
        self.radius_range_mm = self.options.radius_range_mm
        self.continuous = self.options.contrast == "continuous"
        #: The jitter's std per coordinate (x, y mm; radius mm; χ, none for a binary contrast).
        self._jitter_scale = np.array(
            [1.0, 1.0, RADIUS_JITTER_MM, CHI_JITTER if self.continuous else 0.0], dtype=np.float32
        )
        self._theoretical = [
            [TheoreticalShapeModel(self.at_gain(c, j)) for j in range(len(self.gains))] for c in self.pool
        ]

    # ---- the episode ------------------------------------------------------------------------------
    def _draw_chi(self, g: np.random.Generator, size: int | None = None) -> Any:
        if self.continuous:
            return g.uniform(INSULATOR_CHI, CONDUCTOR_CHI, size=size)
        return np.where(g.random(size) < 0.5, CONDUCTOR_CHI, INSULATOR_CHI)

    def _draw_radius(self, g: np.random.Generator, size: int | None = None) -> Any:
        lo, hi = self.radius_range_mm
        return g.uniform(lo, hi, size=size)

    def begin_episode(self, state: SimState, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in order: condition (pool of several), calibration seed (unless fixed),
        the sphere (``target_draw="prior"``: radius, then material or χ), target position
        (``randomize_target``), start position, particle positions, particle radii, particle χ.
        """
        c = self._draw_condition(state, i, g)
        state.cal_seed[i] = self._cal_seed(g)
        state.model[i] = [None] * len(self.gains)
        own = UnknownTargetState.of(state)
        if self.options.target_draw == "prior":
            radius = float(self._draw_radius(g))
            own.target_shape[i] = (radius, float(self._draw_chi(g)))
        else:
            own.target_shape[i] = (c.target.radius_mm, c.chi)
        s = c.start_half_width_mm
        state.target_mm[i] = g.uniform(-s, s, size=2) if self.options.randomize_target else c.target_xy_mm
        self._place(state, i, g, s)
        m = state.n_particles
        state.shape_particles[i, 0] = self._draw_radius(g, m)
        state.shape_particles[i, 1] = self._draw_chi(g, m)

    def true_mean_V(self, state: SimState, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) noise-free, unsaturated true readings of the hidden spheres, V (float64)."""
        offsets = state.target_mm[ids] - state.position_mm[ids]
        shape = UnknownTargetState.of(state).target_shape[ids]
        out = np.empty(len(ids))
        for c, rows in group_by_world(state, ids):
            out[rows] = sphere_reading(c, offsets[rows], shape[rows, 0], shape[rows, 1], saturate=False)
        return out if len(self.gains) == 1 else out * self._gain_array[state.gain_index[ids]]

    def sensor_model(self, state: SimState, i: int, level: int | None = None) -> Any:
        """Env ``i``'s shape sensor model (``mean_std(offsets, radius_mm, chi)``) at gain level ``level``
        (default: the current one; interpolated: built on first use).
        """
        j = int(state.gain_index[i]) if level is None else level
        models = state.model[i]
        if models[j] is None:
            if self.params.sensor_model == "analytic":
                models[j] = self._theoretical[int(state.world_key[i])][j]
            else:
                models[j] = InterpolatedShapeModel(
                    self.at_gain(state.world[i], j),
                    self.options.eev_radii_mm,
                    self.gain_seed(int(state.cal_seed[i]), j),
                    self.protocol,
                )
        return models[j]

    def episode_condition(self, state: SimState, i: int) -> Condition:
        """The episode's tank with its hidden sphere (ground truth; before the first reset: the first tank)."""
        if state.world[i] is None:
            return self.default_world()
        return self.true_condition(state, i)

    def true_condition(self, state: SimState, i: int) -> Condition:
        """Env ``i``'s tank with its hidden sphere (ground truth, for evaluation only)."""
        c: Condition = state.world[i]
        radius, chi = UnknownTargetState.of(state).target_shape[i]
        if c.target.radius_mm == radius and c.chi == chi:
            return c
        # χ = (σ_t − σ_w)/(σ_t + 2σ_w)  ⇔  σ_t = σ_w (1 + 2χ)/(1 − χ) (χ = 1: a perfect conductor)
        sw = c.water.conductivity_uScm
        sigma = 1.4e10 if chi >= 1.0 else sw * (1.0 + 2.0 * chi) / (1.0 - chi)
        material = "steel" if chi >= 1.0 else ("delrin" if chi <= -0.5 else "custom")
        return c.replace(
            target=Target(radius_mm=float(radius), conductivity_uScm=max(float(sigma), 0.0), material=material)
        )

    # ---- predictions for agents ------------------------------------------------------------------
    def predicted_mean_std(
        self, state: SimState, i: int, particles: NDArray, moves_mm: NDArray, level: int | None = None
    ) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of each (x, y, a, χ) hypothesis' reading after the moves (the
        offsets from columns 0–1, :meth:`LocalizeTask.offsets_after_move`).
        """
        off = self.offsets_after_move(state, i, particles, moves_mm)
        return self.sensor_model(state, i, level).mean_std(off, particles[..., 2], particles[..., 3])

    # ---- the measurement update ------------------------------------------------------------------
    def assimilate(
        self,
        state: SimState,
        ids: NDArray[np.intp],
        reading: NDArray[np.float64],
        u0: NDArray[np.float64],
        jitter: NDArray[np.uint16],
        normal_table: NDArray[np.float32],
    ) -> int:
        """Fuse each env's reading into its 4-D cloud (module docstring); returns −1 or the first env whose
        log-likelihood is NaN.
        """
        s = state
        k, m = len(ids), s.n_particles
        xy = s.particles_mm[ids]
        shape = s.shape_particles[ids]
        origin = s.position_mm[ids].astype(np.float32)
        off = (xy - origin[:, :, None]).transpose(0, 2, 1)
        ll = np.empty((k, m), dtype=np.float32)
        for e, i in enumerate(ids.tolist()):
            ll[e] = self.sensor_model(s, i).log_likelihood(np.float32(reading[e]), off[e], shape[e, 0], shape[e, 1])
        idx = np.empty((k, m), dtype=np.int64)
        bad = resample_indices(ll, u0, idx)
        if bad >= 0:
            return bad
        cloud = np.concatenate([xy, shape], axis=1)  # (k, 4, M): x, y, radius, χ
        half = s.half_mm[ids].astype(np.float32)
        lo = np.empty((k, 4), dtype=np.float32)
        hi = np.empty((k, 4), dtype=np.float32)
        lo[:, 0], lo[:, 1], hi[:, 0], hi[:, 1] = -half, -half, half, half
        lo[:, 2], hi[:, 2] = self.radius_range_mm
        lo[:, 3], hi[:, 3] = INSULATOR_CHI, CONDUCTOR_CHI
        out = np.empty_like(cloud)
        jitter_resampled(idx, cloud, jitter[:k], normal_table, self._jitter_scale, lo, hi, out)
        s.particles_mm[ids] = out[:, :2]
        s.shape_particles[ids] = out[:, 2:]
        mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
        x, y = s.particles_mm[ids, 0], s.particles_mm[ids, 1]
        mean_cov_rows(x, y, mean, cov)
        egocentric_counts(x, y, origin, 2 * half, HIST_BINS, counts)
        s.mean_mm[ids], s.cov_mm2[ids], s.counts[ids] = mean, cov, counts
        self._shape_statistics(s, ids)
        return -1

    def update_statistics(self, state: SimState, ids: NDArray[np.intp] | slice) -> None:
        """The x–y statistics and the shape's (:meth:`_shape_statistics`)."""
        super().update_statistics(state, ids)
        self._shape_statistics(state, np.arange(state.num_envs)[ids])

    def _shape_statistics(self, s: SimState, ids: NDArray[np.intp]) -> None:
        """The shape's means and stds (fixed-order sums) and the conductor fraction of envs ``ids``."""
        m = s.n_particles
        own = UnknownTargetState.of(s)
        for d in range(2):
            v = s.shape_particles[ids, d].astype(np.float64)
            total = np.empty(len(ids))
            row_sums(v, total)
            mu = total / m
            dev = v - mu[:, None]
            row_sums(dev * dev, total)
            own.shape_mean[ids, d] = mu
            own.shape_std[ids, d] = np.sqrt(total / m)
        # the median radius: the two middle values of the exact order (float64), no rounding but one mean
        v = np.partition(s.shape_particles[ids, 0].astype(np.float64), (m - 1) // 2 + np.arange(2 - m % 2), axis=1)
        own.radius_median_mm[ids] = 0.5 * (v[:, (m - 1) // 2] + v[:, m // 2])
        own.p_conductor[ids] = np.count_nonzero(s.shape_particles[ids, 1] > 0, axis=1) / m
        # the observation's condition entries 76–77: the belief's radius / 25 mm (clipped to 1, as the condition
        # descriptor's: radii above 25 mm read 1) and χ instead of the truth
        s.descriptor[ids, 0] = np.minimum(own.shape_mean[ids, 0] / 25.0, 1.0).astype(np.float32)
        s.descriptor[ids, 1] = own.shape_mean[ids, 1].astype(np.float32)

    def hidden_state(self, state: SimState, i: int) -> NDArray[np.float64]:
        """Env ``i``'s target centre (mm), radius (mm) and contrast χ, float64 (ground truth)."""
        return np.array([*state.target_mm[i], *UnknownTargetState.of(state).target_shape[i, :2]], dtype=np.float64)

    def task_info(self, state: SimState, sel: Any) -> dict[str, NDArray[Any]]:
        """The info arrays :data:`SHAPE_INFO_KEYS` of envs ``sel``."""
        s = UnknownTargetState.of(state)
        est_r, true_r = s.radius_median_mm[sel], s.target_shape[sel, 0]
        material = _material(s.p_conductor[sel] - 0.5)
        return {
            "radius_estimate_mm": est_r.copy(),
            "radius_mean_mm": s.shape_mean[sel, 0].copy(),
            "radius_spread_mm": s.shape_std[sel, 0].copy(),
            "chi_estimate": s.shape_mean[sel, 1].copy(),
            "chi_spread": s.shape_std[sel, 1].copy(),
            "p_conductor": s.p_conductor[sel].copy(),
            "material_index": material,
            "target_radius_mm": true_r.copy(),
            "target_chi": s.target_shape[sel, 1].copy(),
            "radius_error_frac": np.abs(est_r - true_r) / true_r,
            "material_correct": material == _material(s.target_shape[sel, 1]),
        }


# ---- what the layers above the engine report of the unknown target ----------------------------------------
_LENGTH_BOUND_MM = 1000.0  # the largest length a record holds (the tank is well under a metre across)


def identification_statistics(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The identification over a group of trial records' successes (empty when none holds identification
    results): the fraction whose material estimate is right and the median relative error of the radius.
    """
    results = [r["shape"] for r in records if r["success"] and r.get("shape") and "material_correct" in r["shape"]]
    if not results:
        return {}
    radius = np.asarray([float(s["radius_error_frac"]) for s in results if s["radius_error_frac"] is not None])
    return {
        "identified_trials": len(results),
        "material_correct_frac": float(np.mean([float(s["material_correct"]) for s in results])),
        "radius_error_median_frac": float(np.median(radius)) if radius.size else None,
    }


def _length(name: str, doc: str, nullable: bool = True) -> RecordField:
    return RecordField(name, doc, "mm", low=0.0, high=_LENGTH_BOUND_MM, nullable=nullable)


def _contrast(name: str, doc: str, nullable: bool = True) -> RecordField:
    return RecordField(name, doc, low=-1.0, high=1.0, nullable=nullable)


_RECORD_FIELDS = {
    f.name: f
    for f in (
        _length("radius_estimate_mm", "the particles' median radius"),
        _length("radius_mean_mm", "the particles' mean radius"),
        _length("radius_spread_mm", "the particles' radius std"),
        _contrast("chi_estimate", "the particles' mean contrast χ"),
        RecordField("p_conductor", "the fraction of particles with χ > 0", low=0.0, high=1.0, nullable=True),
        RecordField(
            "material_estimate",
            "conductor or insulator",
            kind="choice",
            choices=MATERIALS,
            info_key="material_index",
        ),
        _length("target_radius_mm", "the true radius", nullable=False),
        _contrast("target_chi", "the true contrast χ", nullable=False),
        RecordField("radius_error_frac", "|estimate − true radius| / true radius", low=0.0, high=1e6, nullable=True),
        RecordField("material_correct", "the material estimate is the true material", kind="bool"),
    )
}

#: What ElectroLocUnknownTarget-v0 reports (:class:`~electroloc_gym.contract.task_spec.TaskMetrics`): the
#: paper's localisation metrics, and the size and material identification over the successes.
SHAPE_METRICS = replace(
    LOCALIZATION_METRICS,
    record=tuple(_RECORD_FIELDS[k] for k in SHAPE_RECORD_KEYS),
    statistics=identification_statistics,
    statistic_keys=("identified_trials", "material_correct_frac", "radius_error_median_frac"),
    columns=(
        Column("successes", "Successes", format="{successes}"),
        Column("material_correct_frac", "Material correct", better="higher", format="{material_correct_frac!p:.1f} %"),
        Column(
            "radius_error_median_frac",
            "Radius error median",
            better="lower",
            format="{radius_error_median_frac!p:.1f} %",
        ),
    ),
    table=Table(
        title="Identification (unknown target, §7)",
        text=(
            "Over each agent's successful trials: the material estimate (conductor when more than half the "
            "particles have χ > 0) against the true one, and the median relative error of the radius estimate "
            "(the particles' median radius). The paper has no such numbers."
        ),
        count="identified_trials",
        pooled=" (pooled)",
    ),
    dataset_info=("radius_estimate_mm", "p_conductor"),
)
UnknownTargetTask.metrics = SHAPE_METRICS
