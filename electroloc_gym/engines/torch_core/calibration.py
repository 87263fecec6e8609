"""The per-episode calibration (paper §5.3) as tensor operations over N envs.

The numba core's protocol, operation for operation (:func:`~electroloc_gym.sensor_models.calibrated.
calibration_coefficients`): at every grid point, ``samples_per_point`` readings ``clip(μ + z·G·σ_s,
±V_sat)`` with ``z`` from the normal quantile table; per point the mean and the sample variance
(ddof = 1); the std per point (floored) or pooled over the points none of whose readings saturated;
and, from these, the bilinear coefficients of each cell and the "outside the grid" row (0 V, G·σ_s),
rounded to float32.
The draws are the env's counter-based stream ``"calibration"`` (:mod:`.rng`), so the tables are the
numba core's in distribution, not in value (a fixed ``calibration_seed`` takes the numba core's own
tables, :class:`~.consts.TorchConsts`).

What an env keeps of its episode's calibration is the two float64 grids, mean and std (n² points each,
:func:`calibration_grids`): the coefficients are differences of neighbouring points, computed where a
particle looks them up (:func:`~.belief_update.grid_mean_std`) with the same float64 operations and the same
float32 rounding as :func:`tables_from_draws`' table — the same bits in half the bytes of the
coefficient table (16·n² against 32·((n − 1)² + 1)), and the "outside" row is the condition's G·σ_s.

The sums over the samples run over the deviations from the noise-free value μ (one pass: Σd, Σd²), so
the variance keeps float64's precision without a second pass over the draws. The pool's grids are
padded to the largest; padded points are excluded from the pooled variance and never looked up.
"""

from __future__ import annotations

from collections.abc import Callable

import torch

from electroloc_gym.engines.torch_core.consts import TorchConsts
from electroloc_gym.engines.torch_core.rng import STREAMS, bits32, lookup, stream_key

__all__ = ["calibration_grids", "grids_from_draws", "tables_from_draws", "coefficients"]


def calibration_grids(
    c: TorchConsts, cond: torch.Tensor, k0: torch.Tensor, k1: torch.Tensor, episode: torch.Tensor
) -> torch.Tensor:
    """(N, 2, n²) float64 each env's calibration of its episode: the mean and the std grids (V), point
    (a, b) at a·n + b (padded points: never looked up).

    Args:
        c: the constants.
        cond: (N,) int64 each env's condition in the pool.
        k0: (N,) int64 each env's first key word.
        k1: (N,) int64 its second key word.
        episode: (N,) int64 its episode (with the key: the draws' coordinates).
    """
    n = c.grid_n
    per = n * n
    half = (per + 1) // 2  # words per sample: two 16-bit indices each
    key = stream_key(k0, k1, episode, torch.zeros_like(episode), STREAMS["calibration"])

    def draws(t: int) -> torch.Tensor:
        w = bits32(key, half, start=t * half)
        return torch.cat([w & 0xFFFF, w >> 16], dim=1)[:, :per].reshape(-1, n, n)

    mean, std = grids_from_draws(c, cond, draws)
    return torch.stack([mean, std], dim=1).reshape(-1, 2, per)


def tables_from_draws(c: TorchConsts, cond: torch.Tensor, draws: Callable[[int], torch.Tensor]) -> torch.Tensor:
    """(N, (n − 1)² + 1, 8) float32 the bilinear coefficients (:func:`coefficients`) of the grids of
    :func:`grids_from_draws` (the numba core's table, row a·(n − 1) + b; the equivalence tests' form).
    """
    mean, std = grids_from_draws(c, cond, draws)
    return coefficients(mean, std, c.noise_V[cond])


def grids_from_draws(
    c: TorchConsts, cond: torch.Tensor, draws: Callable[[int], torch.Tensor]
) -> tuple[torch.Tensor, torch.Tensor]:
    """(N, n, n) float64 mean and std grids (V) of the calibration from given draws: ``draws(t)`` (N, n, n)
    int64 the normal-table indices of sample t at every grid point (the equivalence tests inject numpy's).
    """
    s = c.samples_per_point
    mu = c.grid_mean_V[cond]  # (N, n, n)
    sigma = c.noise_V[cond][:, None, None]
    sat = c.saturation_V[cond][:, None, None]
    table = c.normal_table
    sum_d = torch.zeros_like(mu)
    sum_d2 = torch.zeros_like(mu)
    saturated = torch.zeros(mu.shape, dtype=torch.bool, device=mu.device)
    for t in range(s):  # a fixed number of samples: no data-dependent loop
        reading = torch.clamp(mu + lookup(table, draws(t)).to(torch.float64) * sigma, min=-sat, max=sat)
        d = reading - mu
        sum_d = sum_d + d
        sum_d2 = sum_d2 + d * d
        saturated = saturated | (reading.abs() >= sat)
    mean = mu + sum_d / s
    var = torch.clamp((sum_d2 - sum_d * sum_d / s) / (s - 1), min=0.0)
    floor = c.floor_V[cond][:, None, None]
    std = torch.maximum(torch.sqrt(var), floor)
    if c.pooled_std:
        n = mu.shape[1]
        points = c.grid_points[cond]
        axis = torch.arange(n, device=mu.device)
        valid = (axis[None, :] < points[:, None])[:, :, None] & (axis[None, :] < points[:, None])[:, None, :]
        clean = valid & ~saturated
        n_clean = clean.sum(dim=(1, 2)).to(torch.float64)
        pooled = torch.sqrt((var * clean).sum(dim=(1, 2)) / torch.clamp(n_clean, min=1.0))
        pooled = torch.maximum(pooled, c.floor_V[cond])[:, None, None]
        std = torch.where(clean, pooled, std)
    return mean, std


def coefficients(mean: torch.Tensor, std: torch.Tensor, outside_std: torch.Tensor) -> torch.Tensor:
    """Each cell's ``t00, t10 − t00, t01 − t00, t11 − t10 − t01 + t00`` of the mean and std tables (float64,
    stored float32), row a·(n − 1) + b, then the outside row (0, 0, 0, 0, ``outside_std``, 0, 0, 0).
    """
    parts = []
    for t in (mean, std):
        v00, v10, v01, v11 = t[:, :-1, :-1], t[:, 1:, :-1], t[:, :-1, 1:], t[:, 1:, 1:]
        parts += [v00, v10 - v00, v01 - v00, v11 - v10 - v01 + v00]
    k = mean.shape[0]
    cells = torch.stack(parts, dim=-1).reshape(k, -1, 8)
    outside = torch.zeros(k, 1, 8, dtype=mean.dtype, device=mean.device)
    outside[:, 0, 4] = outside_std
    return torch.cat([cells, outside], dim=1).to(torch.float32)
