"""Sensor-model lookups: the calibrated model's bilinear table and Gaussian log-likelihood (paper §5.3, §4.1).

The calibration's statistics (:func:`calibration_tables`) and per-cell coefficients
(:func:`bilinear_coefficients`) are built by :mod:`electroloc_gym.sensor_models.calibrated`; the
simulation core evaluates the log-likelihood of every particle inside the filter update
(:func:`electroloc_gym.kernels.filter.calibrated_assimilate`, one env at a time: ``_calibrated_ll_one``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from electroloc_gym.kernels.mathf32 import JIT, log32

__all__ = ["calibration_tables", "pooled_calibration_tables", "bilinear_coefficients"]

_F32_HALF_NEG = np.float32(-0.5)
_ZERO = np.float32(0.0)


@njit(**JIT)
def _calibrated_ll_one(
    px,
    py,
    ox0,
    oy0,
    sign,
    lo,
    inv,
    n1,
    base,
    table,
    reading,
    ll,
    sd,
    rows,  # pragma: no cover
    txs,
    tys,
):
    """One env's calibrated log-likelihoods into ``ll`` (M,) float32 at the offsets ``off = sign·(p − o)``
    of the particles ``px``, ``py`` (M,) from the origin (ox0, oy0), all float32 (sign ±1: exact).

    Stands for ``CalibratedSensorModel.log_likelihood`` (``mean_std``, then ``gaussian_log_likelihood``)
    in float32, per particle::

        fx = (off_x − lo) · inv;  fy = (off_y − lo) · inv
        inside = (fx ≥ 0) & (fx ≤ n1) & (fy ≥ 0) & (fy ≤ n1)
        ix = min(int(fx), n1 − 1);  iy = min(int(fy), n1 − 1);  tx = fx − ix;  ty = fy − iy
        c = table[base + (ix·n1 + iy if inside else n1²)]              # 8 float32 coefficients
        mean = c0 + c1·tx + c2·ty + c3·tx·ty;  std = c4 + c5·tx + c6·ty + c7·tx·ty
        z = (reading − mean) / std;  ll = −0.5·z·z − log32(std)       # up to the constant −½ log 2π

    Three passes, so that the two without the table gather vectorise: the cell index and (tx, ty) of
    every particle; the gather and the two bilinear sums; the Gaussian term. ``fx`` is clamped to
    [−1, n1 + 1] before the integer conversion (the conversion is then in range; ``ix`` is the same
    wherever the particle is inside, and outside the coefficients of ``tx``, ``ty`` are 0, so any
    finite value gives the same result).

    Arguments: ``lo`` float32 grid origin, mm; ``inv`` float32 inverse grid step, 1/mm; ``n1`` cells
    per axis; ``base`` the first row of this env's coefficients in ``table`` ((rows, 8) float32, the
    env's last row: outside the grid); ``reading`` float32, V; ``sd``, ``rows``, ``txs``, ``tys``
    (M,) scratch (float32, int32, float32, float32).
    """
    m = px.shape[0]
    n1i = np.int32(n1)
    n1f = np.float32(n1)
    above = np.float32(n1 + 1)
    below = np.float32(-1.0)
    top = np.int32(n1 - 1)
    b = np.int32(base)
    outside = np.int32(base + n1 * n1)
    for i in range(m):
        fx = ((px[i] - ox0) * sign - lo) * inv
        fy = ((py[i] - oy0) * sign - lo) * inv
        ix = min(np.int32(min(max(fx, below), above)), top)
        iy = min(np.int32(min(max(fy, below), above)), top)
        txs[i] = fx - np.float32(ix)
        tys[i] = fy - np.float32(iy)
        inside = (fx >= _ZERO) & (fx <= n1f) & (fy >= _ZERO) & (fy <= n1f)
        rows[i] = b + ix * n1i + iy if inside else outside
    for i in range(m):
        row = rows[i]
        tx = txs[i]
        ty = tys[i]
        txy = tx * ty
        mean = table[row, 0] + table[row, 1] * tx
        mean = mean + table[row, 2] * ty
        mean = mean + table[row, 3] * txy
        std = table[row, 4] + table[row, 5] * tx
        std = std + table[row, 6] * ty
        std = std + table[row, 7] * txy
        ll[i] = mean
        sd[i] = std
    for i in range(m):
        z = (reading - ll[i]) / sd[i]
        ll[i] = (_F32_HALF_NEG * z) * z - log32(sd[i])


@njit(**JIT)
def _point_mean_var(samples, a, b):  # pragma: no cover - compiled
    """Mean and sample variance (ddof = 1) of the readings at grid point (a, b): sequential float64 sums."""
    s = samples.shape[0]
    fs = np.float64(s)
    acc = samples[0, a, b]
    for t in range(1, s):
        acc += samples[t, a, b]
    mu = acc / fs
    ss = 0.0
    for t in range(s):
        d = samples[t, a, b] - mu
        ss += d * d
    return mu, ss / (fs - 1.0)


@njit(**JIT)
def calibration_tables(samples, min_std, mean_out, std_out):  # pragma: no cover - compiled
    """Per grid point mean and sample std (ddof = 1, floored at ``min_std``) of calibration readings.

    Sequential float64 sums over the samples (the calibrated sensor model and the vector env's
    per-episode calibration both call this, so both get the same bits).

    Args:
        samples: (S, n, n) float64 readings, V (S ≥ 2).
        min_std: floor of the std, V.
        mean_out: (n, n) float64 output, mean per point, V.
        std_out: (n, n) float64 output, floored std per point, V.
    """
    _, nx, ny = samples.shape
    for a in range(nx):
        for b in range(ny):
            mu, var = _point_mean_var(samples, a, b)
            sd = np.sqrt(var)
            mean_out[a, b] = mu
            std_out[a, b] = sd if sd > min_std else min_std


@njit(**JIT)
def pooled_calibration_tables(samples, min_std, saturation, mean_out, std_out):  # pragma: no cover - compiled
    """Per grid point mean, and the pooled std wherever no reading saturated (one pass, fixed order).

    The mean and, at points with a reading at ±``saturation``, the floored sample std are those of
    :func:`calibration_tables` (same operations). At every other ("clean") point the std is
    ``max(√(Σ var / n_clean), min_std)``: the root of the mean sample variance (ddof = 1) over the clean
    points, summed sequentially in grid order.

    Args:
        samples: (S, n, n) float64 readings, V (S ≥ 2).
        min_std: floor of the std, V.
        saturation: clip level of the readings, V (> 0).
        mean_out: (n, n) float64 output, mean per point, V.
        std_out: (n, n) float64 output, std per point, V.

    Returns:
        The number of clean points (0: every point saturated; then every std is per point).
    """
    s, nx, ny = samples.shape
    total = 0.0
    clean = 0
    for a in range(nx):
        for b in range(ny):
            mu, var = _point_mean_var(samples, a, b)
            sat = False
            for t in range(s):
                sat = sat or abs(samples[t, a, b]) >= saturation
            sd = np.sqrt(var)
            mean_out[a, b] = mu
            if sat:
                std_out[a, b] = sd if sd > min_std else min_std
            else:
                std_out[a, b] = -1.0  # marks a clean point until the pooled value is known
                total += var
                clean += 1
    if clean > 0:
        pooled = np.sqrt(total / np.float64(clean))
        pooled = pooled if pooled > min_std else min_std
        for a in range(nx):
            for b in range(ny):
                if std_out[a, b] < 0.0:
                    std_out[a, b] = pooled
    return clean


@njit(**JIT)
def _cell_coefficients(t, a, b, out, r, col):  # pragma: no cover - compiled
    """``t00, t10 − t00, t01 − t00, t11 − t10 − t01 + t00`` of cell (a, b) of ``t`` into ``out[r, col:col + 4]``."""
    v00 = t[a, b]
    v10 = t[a + 1, b]
    v01 = t[a, b + 1]
    v11 = t[a + 1, b + 1]
    out[r, col] = v00
    out[r, col + 1] = v10 - v00
    out[r, col + 2] = v01 - v00
    out[r, col + 3] = v11 - v10 - v01 + v00


@njit(**JIT)
def bilinear_coefficients(mean, std, outside_std, out):  # pragma: no cover - compiled
    """Per-cell bilinear coefficients of the mean and std tables, and the "outside the grid" row.

    Row ``a·n1 + b`` holds, for each table ``t`` (mean, then std), ``t00, t10 − t00, t01 − t00,
    t11 − t10 − t01 + t00`` (value = c0 + c1·tx + c2·ty + c3·tx·ty in the cell); the last row is
    ``(0, 0, 0, 0, outside_std, 0, 0, 0)`` (no target: mean 0 V). ``out`` may be float32 (cast on store).

    Args:
        mean: (n, n) float64 mean table, V.
        std: (n, n) float64 std table, V.
        outside_std: std outside the grid, V.
        out: (n1² + 1, 8) output, n1 = n − 1.
    """
    n1 = mean.shape[0] - 1
    for a in range(n1):
        for b in range(n1):
            _cell_coefficients(mean, a, b, out, a * n1 + b, 0)
            _cell_coefficients(std, a, b, out, a * n1 + b, 4)
    last = n1 * n1
    for c in range(8):
        out[last, c] = 0.0
    out[last, 4] = outside_std
