"""The belief update of N envs as tensor operations (paper §4.1, Algorithm 1).

Likelihoods, systematic resampling, jitter, clip, statistics, histogram and the observation (its scalar
entries: the shared declaration, :mod:`electroloc_gym.contract.belief_summary`).

Each function is the numba kernel's arithmetic (:mod:`electroloc_gym.kernels`) batched over envs:
float32 for the particles, the likelihoods and the weights (as the numba core), float64 for the
weights' total, the cumulative weights and the resampling pointers (a float32 cumulative sum of 2500
weights would lose the small weights' mass), float64 for the statistics. Sums are torch's reductions
(their order is the device's: the results agree with the numba core's fixed-order sums to float
rounding, not bit for bit). The exp and log are torch's (the numba core's are its branch-free
polynomials; both within an ulp of the exact value).
"""

from __future__ import annotations

import torch

from electroloc_gym.contract.belief_summary import belief_scalars
from electroloc_gym.engines.torch_core.rng import lookup
from electroloc_gym.protocol import HIST_BINS

__all__ = [
    "dipole_difference",
    "calibrated_mean_std",
    "grid_mean_std",
    "calibrated_log_likelihood",
    "gaussian_log_likelihood",
    "analytic_mean",
    "analytic_log_likelihood",
    "resample",
    "statistics",
    "belief_observation",
    "HIST_BINS",
]


def dipole_difference(
    x: torch.Tensor, y: torch.Tensor, h: torch.Tensor, z2: torch.Tensor, k: torch.Tensor, strength: torch.Tensor
) -> torch.Tensor:
    """``physics._dipole_difference`` (Eq. 4 + Eq. 7, a sphere's point dipole) elementwise in the inputs'
    precision: δV(S1) − δV(S2) (V) of a sphere at offsets (x, y) mm, half-spacing ``h`` mm, depth² ``z2``
    mm², ``k`` = V_e·E (V·mm), ``strength`` = χ·A³ (mm³) (broadcasting).
    """
    xp = x - h
    xn = x + h
    y2z2 = y * y + z2
    tp = xp * xp + y2z2
    tn = xn * xn + y2z2
    ip = 1.0 / (tp * torch.sqrt(tp))
    inn = 1.0 / (tn * torch.sqrt(tn))
    ex = k * (xp * ip - xn * inn)
    eyz = k * (ip - inn)
    x2z2 = x * x + z2
    d1 = h - y
    d2 = -h - y
    t1 = x2z2 + d1 * d1
    t2 = x2z2 + d2 * d2
    r1 = 1.0 / (t1 * torch.sqrt(t1))
    r2 = 1.0 / (t2 * torch.sqrt(t2))
    common = -ex * x - eyz * z2
    dot1 = common + eyz * y * d1
    dot2 = common + eyz * y * d2
    return strength * (dot1 * r1 - dot2 * r2)


def _cells(
    x: torch.Tensor, y: torch.Tensor, lo: torch.Tensor, inv: torch.Tensor, cells: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The cell (ix, iy) (N, M) int64 of each offset, its fractions (tx, ty) float32 and whether it is on
    the grid (``kernels.lookup._calibrated_ll_one``'s arithmetic); arguments as :func:`calibrated_mean_std`.
    """
    fx = (x - lo[:, None]) * inv[:, None]
    fy = (y - lo[:, None]) * inv[:, None]
    n1f = cells.to(torch.float32)[:, None]
    top = (cells - 1)[:, None]
    ix = torch.minimum(torch.clamp(fx, min=-1.0).clamp(max=n1f + 1).to(torch.int64), top)
    iy = torch.minimum(torch.clamp(fy, min=-1.0).clamp(max=n1f + 1).to(torch.int64), top)
    tx = fx - ix.to(torch.float32)
    ty = fy - iy.to(torch.float32)
    inside = (fx >= 0) & (fx <= n1f) & (fy >= 0) & (fy <= n1f)
    return ix, iy, tx, ty, inside


def _which(which: torch.Tensor | None, x: torch.Tensor) -> torch.Tensor:
    """(N, 1) int64 the table of each row of ``x`` (None: row i reads table i)."""
    if which is None:
        which = torch.arange(x.shape[0], device=x.device)
    return which.to(torch.int64)[:, None]


def calibrated_mean_std(
    x: torch.Tensor,
    y: torch.Tensor,
    lo: torch.Tensor,
    inv: torch.Tensor,
    cells: torch.Tensor,
    stride: int,
    table: torch.Tensor,
    which: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(N, M) float32 mean and std (V) of the calibrated model at offsets (target − carriage) ``x``, ``y``
    (N, M) float32 mm from a coefficient table: the bilinear lookup of ``kernels.lookup._calibrated_ll_one``.

    Args:
        x: (N, M) float32 offsets along x, mm.
        y: (N, M) float32 offsets along y, mm.
        lo: (N,) float32 each grid's first coordinate, mm.
        inv: (N,) float32 each grid's inverse step, 1/mm.
        cells: (N,) int64 each grid's cells per axis n1.
        stride: the row stride of ``table`` (the pool's largest n1); the last row is "outside".
        table: (T, stride² + 1, 8) float32 bilinear coefficients (:func:`.calibration.coefficients`).
        which: (N,) int64 the table each row reads (None: row i reads table i; a fixed calibration: the
            condition's own table, kept once).
    """
    ix, iy, tx, ty, inside = _cells(x, y, lo, inv, cells)
    per = stride * stride + 1
    rows = _which(which, x) * per + torch.where(inside, ix * stride + iy, stride * stride)
    coef = torch.index_select(table.reshape(-1, 8), 0, rows.reshape(-1)).reshape(rows.shape + (8,))
    c0, c1, c2, c3, c4, c5, c6, c7 = coef.unbind(-1)
    txy = tx * ty
    mean = c0 + c1 * tx + c2 * ty + c3 * txy
    std = c4 + c5 * tx + c6 * ty + c7 * txy
    return mean, std


def grid_mean_std(
    x: torch.Tensor,
    y: torch.Tensor,
    lo: torch.Tensor,
    inv: torch.Tensor,
    cells: torch.Tensor,
    n: int,
    grids: torch.Tensor,
    outside_std: torch.Tensor,
    which: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`calibrated_mean_std` from the float64 mean and std grids, bit for bit: each cell's
    coefficients ``t00, t10 − t00, t01 − t00, t11 − t10 − t01 + t00`` computed in float64 from its four
    corners and rounded to float32 as :func:`.calibration.coefficients` rounds them; off the grid 0 V and
    ``outside_std``.

    Args:
        x: (N, M) float32 offsets along x, mm.
        y: (N, M) float32 offsets along y, mm.
        lo: (N,) float32 each grid's first coordinate, mm.
        inv: (N,) float32 each grid's inverse step, 1/mm.
        cells: (N,) int64 each grid's cells per axis n1.
        n: the grids' points per axis (the pool's largest grid).
        grids: (T, 2, n²) float64 the mean and std grids, V (:func:`.calibration.calibration_grids`).
        outside_std: (N,) float64 G·σ_s, V (the std off the grid).
        which: (N,) int64 the grids each row reads (None: row i reads grids i).
    """
    ix, iy, tx, ty, inside = _cells(x, y, lo, inv, cells)
    per = n * n
    point = torch.where(inside, ix * n + iy, 0)
    if which is None:  # row i reads env i's grids: a gather along the rows, no flattened view
        rows = grids.reshape(grids.shape[0], 2 * per)

        def at(offset: int) -> torch.Tensor:
            return torch.gather(rows, 1, point + offset)
    else:
        flat, base = grids.reshape(-1), _which(which, x) * (2 * per) + point

        def at(offset: int) -> torch.Tensor:
            return lookup(flat, base + offset)

    txy = tx * ty
    out = []
    for plane in (0, per):  # the mean, then the std
        v00, v10, v01, v11 = at(plane), at(plane + n), at(plane + 1), at(plane + n + 1)
        c0 = v00.to(torch.float32)
        c1 = (v10 - v00).to(torch.float32)
        c2 = (v01 - v00).to(torch.float32)
        c3 = (v11 - v10 - v01 + v00).to(torch.float32)
        out.append(c0 + c1 * tx + c2 * ty + c3 * txy)
    mean = torch.where(inside, out[0], 0.0)
    std = torch.where(inside, out[1], outside_std.to(torch.float32)[:, None])
    return mean, std


def calibrated_log_likelihood(
    particles: torch.Tensor,
    origin: torch.Tensor,
    lo: torch.Tensor,
    inv: torch.Tensor,
    cells: torch.Tensor,
    stride: int,
    table: torch.Tensor,
    reading: torch.Tensor,
) -> torch.Tensor:
    """(N, M) float32 log-likelihoods of the calibrated model (``kernels.lookup._calibrated_ll_one``).

    Args:
        particles: (N, 2, M) float32 target hypotheses, mm.
        origin: (N, 2) float32 the carriage, mm (offsets = particle − carriage).
        lo: (N,) float32 each grid's first coordinate, mm.
        inv: (N,) float32 each grid's inverse step, 1/mm.
        cells: (N,) int64 each grid's cells per axis n1.
        stride: the row stride of ``table`` (the pool's largest n1); the last row is "outside".
        table: (N, stride² + 1, 8) float32 bilinear coefficients.
        reading: (N,) float32 readings, V.
    """
    x = particles[:, 0] - origin[:, 0:1]
    y = particles[:, 1] - origin[:, 1:2]
    mean, std = calibrated_mean_std(x, y, lo, inv, cells, stride, table)
    return gaussian_log_likelihood(mean, std, reading)


def gaussian_log_likelihood(mean: torch.Tensor, std: torch.Tensor, reading: torch.Tensor) -> torch.Tensor:
    """(N, M) float32 ``−z²/2 − log σ`` of the readings (N,) V under the (N, M) means and stds (V), the
    constant dropped (the calibrated model's likelihood).
    """
    z = (reading[:, None] - mean) / std
    return (-0.5 * z) * z - torch.log(std)


def analytic_mean(
    x: torch.Tensor,
    y: torch.Tensor,
    dip: tuple[torch.Tensor, ...],
    scale: torch.Tensor,
    saturation: torch.Tensor,
) -> torch.Tensor:
    """(N, M) float32 mean (V) of the analytic model at offsets ``x``, ``y`` (N, M) float32 mm: the physics,
    saturated (its std is the constant G·σ_s). ``dip`` = (h, z2, k, strength), each (N,) float32;
    ``scale`` (N,) float32 s·G; ``saturation`` (N,) float32 V_sat.
    """
    h, z2, k, strength = (d[:, None] for d in dip)
    sat = saturation[:, None]
    return torch.clamp(dipole_difference(x, y, h, z2, k, strength) * scale[:, None], min=-sat, max=sat)


def analytic_log_likelihood(
    particles: torch.Tensor,
    origin: torch.Tensor,
    dip: tuple[torch.Tensor, ...],
    scale: torch.Tensor,
    saturation: torch.Tensor,
    noise: torch.Tensor,
    reading: torch.Tensor,
) -> torch.Tensor:
    """(N, M) float32 log-likelihoods of the analytic model (mean :func:`analytic_mean`; std G·σ_s; the
    constant −log σ dropped), as ``AnalyticSensorModel.log_likelihood`` on float32 offsets; ``noise`` (N,)
    float32 G·σ_s, ``reading`` (N,) float32, V.
    """
    x = particles[:, 0] - origin[:, 0:1]
    y = particles[:, 1] - origin[:, 1:2]
    mean = analytic_mean(x, y, dip, scale, saturation)
    z = (reading[:, None] - mean) / noise[:, None]
    return (-0.5 * z) * z


def resample(
    ll: torch.Tensor,
    particles: torch.Tensor,
    u0: torch.Tensor,
    jx: torch.Tensor,
    jy: torch.Tensor,
    normal_table: torch.Tensor,
    half: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Systematic resampling, jitter and clip of N clouds (``kernels.filter._resample_one``); returns the
    new (N, 2, M) float32 particles and the (N, M) int64 resampling indices.

    ``w = exp(ll − max)`` (float32; all 1 where the max is not finite), ``cum = cumsum(w / Σw)``
    normalised by its last entry (float64), ``idx = min(searchsorted(cum, (U + j)/M, right), M − 1)``,
    then ``clip(particle[idx] + table[jitter], ±H)``.

    Args:
        ll: (N, M) float32 log-likelihoods.
        particles: (N, 2, M) float32.
        u0: (N,) float64 offsets U in [0, 1).
        jx: (N, M) int64 normal-table indices of the x jitter.
        jy: (N, M) int64 those of the y jitter.
        normal_table: (65536,) float32.
        half: (N,) float32 the box half-width H, mm.
    """
    m = ll.shape[1]
    top = ll.max(dim=1, keepdim=True).values
    finite = torch.isfinite(top)
    w = torch.where(finite, torch.exp(ll - torch.where(finite, top, torch.zeros_like(top))), torch.ones_like(ll))
    w64 = w.to(torch.float64)
    cum = torch.cumsum(w64 / w64.sum(dim=1, keepdim=True), dim=1)
    cum = cum / cum[:, -1:]
    idx = torch.clamp(systematic_indices(cum, u0), max=m - 1)
    h = half[:, None]
    x = torch.clamp(torch.gather(particles[:, 0], 1, idx) + lookup(normal_table, jx), min=-h, max=h)
    y = torch.clamp(torch.gather(particles[:, 1], 1, idx) + lookup(normal_table, jy), min=-h, max=h)
    return torch.stack([x, y], dim=1), idx


def pointers(u0: torch.Tensor, j: torch.Tensor, m: int) -> torch.Tensor:
    """Systematic resampling's pointers ``(U + j) / M``, float64, for (N, 1) offsets and int64 ``j``."""
    return (u0 + j.to(torch.float64)) / m


def systematic_indices(cum: torch.Tensor, u0: torch.Tensor) -> torch.Tensor:
    """``searchsorted(cum, (U + j)/M, right=True)`` for j = 0 … M−1 (N, M) int64, in O(M) per env.

    The pointers are evenly spaced, so the first pointer at or above each ``cum[i]`` has a closed form:
    ``q_i = ⌈cum_i·M − U⌉``, corrected by one step either way against the pointers themselves (computed
    as the search computes them, so the comparisons are the same). The answer for pointer j is then the
    number of ``q_i ≤ j``: a histogram of the ``q_i`` and its cumulative sum. Equal to the search, bit for
    bit (tested), without its M·log M memory-bound probes.
    """
    n, m = cum.shape
    u = u0.reshape(n, 1)
    q = torch.clamp(torch.ceil(cum * m - u), 0, m).to(torch.int64)
    below = (q > 0) & (pointers(u, q - 1, m) >= cum)  # the pointer before q already reaches cum_i
    q = torch.where(below, q - 1, q)
    above = (q < m) & (pointers(u, q, m) < cum)  # pointer q is still short of cum_i
    q = torch.where(above, q + 1, q)
    counts = torch.zeros(n, m + 1, dtype=torch.int64, device=cum.device)
    counts = counts.scatter_add(1, q, torch.ones_like(q))
    return torch.cumsum(counts[:, :m], dim=1)


def statistics(
    particles: torch.Tensor, centre: torch.Tensor, scale: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Mean (N, 2) and population covariance (N, 2, 2), float64, and the (N, 64) float64 histogram counts
    of N unweighted clouds (``kernels.moments``): cells of ``((p − centre)/scale + ½)·8`` in float32,
    truncated, clipped to [0, 7]; ``centre`` (N, 2) float32 the carriage, ``scale`` (N,) float32 2H.
    """
    p = particles.to(torch.float64)
    mean = p.mean(dim=2)
    d = p - mean[:, :, None]
    m = p.shape[2]
    cxx = (d[:, 0] * d[:, 0]).sum(dim=1) / m
    cxy = (d[:, 0] * d[:, 1]).sum(dim=1) / m
    cyy = (d[:, 1] * d[:, 1]).sum(dim=1) / m
    cov = torch.stack([torch.stack([cxx, cxy], dim=1), torch.stack([cxy, cyy], dim=1)], dim=1)
    fb = float(HIST_BINS)
    s = scale[:, None]
    a = torch.clamp(((particles[:, 0] - centre[:, 0:1]) / s + 0.5) * fb, min=-1.0, max=fb).to(torch.int64)
    b = torch.clamp(((particles[:, 1] - centre[:, 1:2]) / s + 0.5) * fb, min=-1.0, max=fb).to(torch.int64)
    cell = a.clamp(0, HIST_BINS - 1) * HIST_BINS + b.clamp(0, HIST_BINS - 1)
    counts = torch.zeros(p.shape[0], HIST_BINS * HIST_BINS, dtype=torch.float64, device=p.device)
    counts = counts.scatter_add(1, cell, torch.ones_like(cell, dtype=torch.float64))
    return mean, cov, counts


def belief_observation(
    carriage: torch.Tensor,
    reading: torch.Tensor,
    mean: torch.Tensor,
    cov: torch.Tensor,
    hist: torch.Tensor,
    n_obs: torch.Tensor,
    max_obs: int,
    half: torch.Tensor,
    noise: torch.Tensor,
    saturation: torch.Tensor,
    success_mm: float,
    descriptor: torch.Tensor,
) -> torch.Tensor:
    """(N, 81) float32 belief observations (layout: :mod:`electroloc_gym.contract.observation`): the scalar
    entries :func:`~electroloc_gym.contract.belief_summary.belief_scalars` in float64, then a float32 cast.
    """
    scalars = belief_scalars(
        torch, carriage, reading, mean, cov, n_obs.to(torch.float64), max_obs, half, noise, saturation, success_mm
    )
    return torch.cat([scalars.to(torch.float32), hist.to(torch.float32), descriptor], dim=1)
