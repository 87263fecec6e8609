"""Bulk random-draw transforms: uniform points in a box, noisy saturated readings.

Each is the numpy expression quoted in its docstring, with the same float64 operations (so the same
bits), without numpy's slow broadcasting over an inner axis of length 2.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from electroloc_gym.kernels.mathf32 import JIT

__all__ = ["box_affine", "noisy_saturated"]


@njit(**JIT)
def box_affine(u, low, span, out_x, out_y):  # pragma: no cover - compiled
    """``low + span · u`` for uniform draws ``u`` (n, 2) float64, column c into ``out_c`` (cast on store).

    numpy's ``low + (high − low) * u`` with ``span = high − low`` (2,) — the same float64 operations —
    without its slow broadcast over an inner axis of length 2.
    """
    lx = low[0]
    ly = low[1]
    sx = span[0]
    sy = span[1]
    for j in range(u.shape[0]):
        out_x[j] = lx + sx * u[j, 0]
        out_y[j] = ly + sy * u[j, 1]


@njit(**JIT)
def noisy_saturated(mean, idx, table, std, sat, out):  # pragma: no cover - compiled
    """``np.clip(mean + table[idx].astype(float64) · std, −sat, sat)`` over 1-D float64 arrays (same bits)."""
    for i in range(mean.shape[0]):
        v = mean[i] + np.float64(table[idx[i]]) * std
        v = v if v >= -sat else -sat
        out[i] = v if v <= sat else sat
