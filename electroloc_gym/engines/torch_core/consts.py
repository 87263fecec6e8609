"""What the torch core needs of the env's parameters, as tensors on its device (built once, on the host).

Per condition of the episode pool (one, or the eight presets with ``condition="random"``): the boxes
(mm), the noise G·σ_s and the clip V_sat (V), the observation's descriptor, the analytic model's
dipole constants (:func:`electroloc_gym.world.physics.differential_perturbation`'s, in float32 as the numba
core's belief) and the calibration's noise-free grid (:func:`~electroloc_gym.sensor_models.calibrated.
noise_free_calibration_grid`, padded to the pool's largest grid). What the torch core does not
implement is refused here with one error naming the argument, as the capability table says
(:mod:`electroloc_gym.contract.capabilities`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from electroloc_gym.contract.capabilities import check_engine, params_options
from electroloc_gym.contract.observation import condition_descriptor, condition_index
from electroloc_gym.contract.params import DISCRETE_MOVES_MM, EnvParams, LocalizeOptions, memory_limit_bytes
from electroloc_gym.kernels.streams import normal_table
from electroloc_gym.registry import ENVS, EnvEntry
from electroloc_gym.sensor_models.calibrated import (
    CalibrationProtocol,
    calibration_grid_for,
    fixed_coefficients,
    grid_points_bound,
    noise_free_calibration_grid,
)

__all__ = ["TorchConsts", "check_supported", "torch_entry"]


def torch_entry() -> EnvEntry:
    """The env table's entry of the task the torch core implements (ElectroLoc-v0's): the first entry whose
    ``backends`` name ``"torch"`` (read from the table, so the engine imports no task of the numba engine).
    """
    return next(e for e in ENVS if "torch" in e.backends)


def check_supported(params: EnvParams) -> None:
    """One ValueError naming the first option value the torch engine does not implement (the capability
    table's limits, :mod:`electroloc_gym.contract.capabilities`).
    """
    check_engine("torch", params_options(params))


#: Host bytes per calibration reading while the constants are built: its offset (2 float64) and its
#: noise-free value (float64), one condition at a time (:func:`~electroloc_gym.sensor_models.calibrated.
#: noise_free_calibration_grid`).
HOST_BYTES_PER_READING = 24


def _check_host_calibration(proto: CalibrationProtocol, points: int) -> None:
    """Refuse a calibration grid whose noise-free readings cannot fit in the host's memory (the numba
    engine's message), before any is computed.
    """
    limit = memory_limit_bytes()
    need = HOST_BYTES_PER_READING * proto.samples_per_point * points * points
    if need > limit:
        raise ValueError(
            f"calibration grid of {points}×{points} points × {proto.samples_per_point} "
            f"readings needs ≈{need / 2**30:.3g} GiB, more than this machine's "
            f"{limit / 2**30:.3g} GiB: choose a coarser calibration grid_step_mm"
        )


@dataclass(frozen=True)
class TorchConsts:
    """The constants of one torch core (see the module docstring); tensors on ``device``.

    Attributes (per condition c of the pool, P conditions):
        half_mm, start_half_mm: (P,) float64 allowed and start half-widths, mm.
        target_mm: (P, 2) float64 the preset target centre, mm.
        noise_V, saturation_V: (P,) float64 G·σ_s and V_sat, V.
        descriptor: (P, 5) float32 observation entries 76–80.
        preset_index: (P,) int64 each condition's ``info["condition_index"]``: its index in
            :data:`~electroloc_gym.world.conditions.PRESET_NAMES`, −1 for a custom condition (as the numba envs').
        dip_h, dip_k, dip_strength, dip_z2, dip_scale: (P,) float64 the dipole's L/2 (mm), V_e·E (V·mm),
            χ·A³ (mm³), depth² (mm²) and s·G, read from :attr:`~electroloc_gym.world.conditions.Condition.
            dipole_constants` (the true reading uses them in float64, the analytic belief model rounded once
            to float32, as the numba core).
        grid_mean_V: (P, n, n) float64 the calibration's noise-free readings (padded with 0), V.
        grid_points: (P,) int64 points per axis of each condition's grid; grid_lo_mm, grid_inv_mm: (P,)
            float32 its first coordinate (mm) and inverse step (1/mm).
        floor_V: (P,) float64 the std floor, V.
        normal_table: (65536,) float32 the normal quantile table.
        moves_mm: (9, 2) float64 the discrete moves, mm.
        fixed_table: with a fixed ``calibration_seed``, (P, (n − 1)² + 1, 8) float32 the numba core's own
            coefficients of each condition (:func:`~electroloc_gym.sensor_models.calibrated.fixed_coefficients`) in the
            torch core's row layout (row a·(n − 1) + b; the last row: outside the grid); else None.
    """

    device: torch.device
    pool: int
    n_particles: int
    calibrated: bool
    pooled_std: bool
    samples_per_point: int
    fixed_calibration_seed: int | None
    belief_obs: bool
    discrete: bool
    randomize_target: bool
    max_observations: int
    max_episode_steps: int | None
    success_spread_mm: float
    grid_n: int
    half_mm: torch.Tensor
    start_half_mm: torch.Tensor
    target_mm: torch.Tensor
    noise_V: torch.Tensor
    saturation_V: torch.Tensor
    descriptor: torch.Tensor
    preset_index: torch.Tensor
    dip_h: torch.Tensor
    dip_k: torch.Tensor
    dip_strength: torch.Tensor
    dip_z2: torch.Tensor
    dip_scale: torch.Tensor
    grid_mean_V: torch.Tensor
    grid_points: torch.Tensor
    grid_lo_mm: torch.Tensor
    grid_inv_mm: torch.Tensor
    floor_V: torch.Tensor
    normal_table: torch.Tensor
    moves_mm: torch.Tensor
    fixed_table: torch.Tensor | None

    @classmethod
    def build(cls, params: EnvParams, device: torch.device) -> TorchConsts:
        """The constants of ``params`` on ``device`` (ValueError: what the torch core does not implement)."""
        check_supported(params)
        options = params.options_as(LocalizeOptions)
        pool = options.conditions()
        proto = params.calibration
        if params.sensor_model == "calibrated":
            _check_host_calibration(proto, max(grid_points_bound(proto, c.allowed_half_width_mm) for c in pool))

        def f64(values: list | np.ndarray) -> torch.Tensor:
            return torch.tensor(np.asarray(values, dtype=np.float64), device=device)

        calibrated = params.sensor_model == "calibrated"
        grids = [calibration_grid_for(c, proto) for c in pool] if calibrated else [np.zeros(2)]
        n = max(g.size for g in grids)
        grid_mean = np.zeros((len(pool), n, n))
        if calibrated:
            for i, c in enumerate(pool):
                g = noise_free_calibration_grid(c, proto)[0]
                grid_mean[i, : g.shape[0], : g.shape[1]] = g
        fixed = None
        if calibrated and params.calibration_seed is not None:
            n1 = n - 1
            fixed_np = np.zeros((len(pool), n1 * n1 + 1, 8), dtype=np.float32)
            for i, (c, g) in enumerate(zip(pool, grids, strict=True)):
                coef, k1 = fixed_coefficients(c, params.calibration_seed, proto), g.size - 1
                rows = (np.arange(k1)[:, None] * n1 + np.arange(k1)[None, :]).reshape(-1)
                fixed_np[i, rows] = coef[:-1]
                fixed_np[i, -1] = coef[-1]
            fixed = torch.tensor(fixed_np, device=device)
        dip = np.array([c.dipole_constants for c in pool], dtype=np.float64)  # (P, 5): h, k, strength, z², s·G
        return cls(
            device=device,
            pool=len(pool),
            n_particles=params.n_particles,
            calibrated=calibrated,
            pooled_std=proto.std_estimator == "pooled",
            samples_per_point=proto.samples_per_point,
            fixed_calibration_seed=params.calibration_seed,
            belief_obs=params.observation == "belief",
            discrete=params.action_type == "discrete",
            randomize_target=options.randomize_target,
            max_observations=params.max_observations,
            max_episode_steps=params.max_episode_steps,
            success_spread_mm=float(params.success_spread_mm),
            grid_n=n,
            half_mm=f64([c.allowed_half_width_mm for c in pool]),
            start_half_mm=f64([c.start_half_width_mm for c in pool]),
            target_mm=f64([c.target_xy_mm for c in pool]),
            noise_V=f64([c.noise_std_V for c in pool]),
            saturation_V=f64([c.saturation_V for c in pool]),
            descriptor=torch.tensor(np.stack([condition_descriptor(c) for c in pool]), device=device),
            preset_index=torch.tensor(condition_index([c.name for c in pool]), device=device),
            dip_h=f64(dip[:, 0]),
            dip_k=f64(dip[:, 1]),
            dip_strength=f64(dip[:, 2]),
            dip_z2=f64(dip[:, 3]),
            dip_scale=f64(dip[:, 4]),
            grid_mean_V=torch.tensor(grid_mean, device=device),
            grid_points=torch.tensor([g.size for g in grids], device=device, dtype=torch.int64),
            grid_lo_mm=torch.tensor(np.asarray([g[0] for g in grids], dtype=np.float32), device=device),
            grid_inv_mm=torch.tensor(np.full(len(grids), 1.0 / proto.grid_step_mm, dtype=np.float32), device=device),
            floor_V=f64([proto.min_std_fraction * c.noise_std_V for c in pool]),
            normal_table=torch.tensor(normal_table(), device=device),
            moves_mm=torch.tensor(DISCRETE_MOVES_MM, device=device),
            fixed_table=fixed,
        )
