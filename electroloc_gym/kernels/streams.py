"""Fast random draws shared by the sensor calibration and the particle filter.

Normal draws from a quantile table: each N(0, 1) value is one of 65536 equiprobable standard-normal
quantiles (:func:`normal_table`) picked by 16 random bits taken straight from the generator's bit
stream (:func:`table_normal_indices`; the filter's kernels and the calibration look the values up):
an order of magnitude cheaper per value than numpy's ziggurat, for the 5000 jitter values of every
filter step and the thousands of readings of every calibration. The table is rescaled to unit
variance; its tails stop at ±4.3σ (probability 1.5·10⁻⁵), which neither a roughening kernel nor the
noise of a 10-sample calibration average needs.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from electroloc_gym.kernels import box_affine

__all__ = ["NORMAL_TABLE_BITS", "normal_table", "table_normal_indices", "uniform_in_box"]

#: Bits per jitter draw: the table holds 2**16 quantiles.
NORMAL_TABLE_BITS = 16


@functools.cache
def normal_table() -> NDArray[np.float32]:
    """The 65536 standard-normal quantiles Φ⁻¹((k + ½)/65536), rescaled to unit variance (float32, read-only)."""
    n = 1 << NORMAL_TABLE_BITS
    q = ndtri((np.arange(n) + 0.5) / n)
    q /= np.sqrt(np.mean(q * q))
    table = q.astype(np.float32)
    table.flags.writeable = False
    return table


def table_normal_indices(rng: np.random.Generator, n: int) -> NDArray[np.uint16]:
    """``n`` indices into :func:`normal_table`: the 16-bit words of ⌈n/4⌉ raw 64-bit draws of ``rng``."""
    return rng.bit_generator.random_raw((n + 3) // 4).view(np.uint16)[:n]


def uniform_in_box(
    rng: np.random.Generator, low: NDArray, high: NDArray, n: int, out_xy: tuple[NDArray, NDArray] | None = None
) -> NDArray[np.float64] | None:
    """``rng.uniform(low, high, size=(n, 2))`` bit for bit, without numpy's slow broadcasting.

    With array bounds numpy's ``uniform`` takes its broadcasting path; it
    computes ``low + (high − low) · U`` with ``U = rng.random()``, which is what this does in bulk
    (:func:`electroloc_gym.kernels.box_affine`). Returns the (n, 2) float64 points, or, with
    ``out_xy`` (two (n,) arrays of any float dtype), writes x and y there (cast on store, as
    ``astype``) and returns None.
    """
    u = rng.random((n, 2))
    low = np.asarray(low, dtype=np.float64).reshape(2)
    span = np.asarray(high, dtype=np.float64).reshape(2) - low
    if out_xy is not None:
        box_affine(u, low, span, *out_xy)
        return None
    out = np.empty((n, 2))
    box_affine(u, low, span, out[:, 0], out[:, 1])
    return out
