"""Belief statistics of unweighted particle clouds: mean, population covariance, the observation's histogram.

Sequential float64 sums in particle order, so a cloud gives the same bits alone or in a batch, in
any memory layout.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from electroloc_gym.kernels.mathf32 import JIT

__all__ = ["mean_cov_rows", "egocentric_counts"]

_F32_HALF = np.float32(0.5)


@njit(**JIT)
def _cov_about(x, y, mx, my, cov, e):  # pragma: no cover - compiled
    """Population covariance of one cloud (x, y: (M,)) about the mean (mx, my) into ``cov[e]`` (sequential float64)."""
    m = x.shape[0]
    fm = np.float64(m)
    cxx = 0.0
    cxy = 0.0
    cyy = 0.0
    for i in range(m):
        dx = np.float64(x[i]) - mx
        dy = np.float64(y[i]) - my
        cxx += dx * dx
        cxy += dx * dy
        cyy += dy * dy
    cov[e, 0, 0] = cxx / fm
    cov[e, 0, 1] = cxy / fm
    cov[e, 1, 0] = cxy / fm
    cov[e, 1, 1] = cyy / fm


@njit(**JIT)
def _mean_cov_one(x, y, mean, cov, e):  # pragma: no cover - compiled
    """Mean and population covariance of one cloud (x, y: (M,)) into ``mean[e]``, ``cov[e]``."""
    m = x.shape[0]
    fm = np.float64(m)
    sx = 0.0
    sy = 0.0
    for i in range(m):
        sx += np.float64(x[i])
        sy += np.float64(y[i])
    mean[e, 0] = sx / fm
    mean[e, 1] = sy / fm
    _cov_about(x, y, sx / fm, sy / fm, cov, e)


@njit(**JIT)
def _counts_one(x, y, cx, cy, scale, bins, out, e, cells, hist):  # pragma: no cover - compiled
    """Histogram counts of one cloud (x, y: (M,)) around (cx, cy) into ``out[e]`` (see egocentric_counts).

    ``cells`` (M,) int32 and ``hist`` (4, bins²) int32 are scratch: the cells are computed in a
    vectorised pass (the float cell coordinate is clamped before its integer conversion, so the
    conversion is always in range; in range it truncates as numpy's ``astype``), then counted into four
    interleaved histograms, so that repeated cells do not chain one increment on the previous one.
    """
    m = x.shape[0]
    fb = np.float32(bins)  # numpy's ``rel * 8`` keeps the particles' dtype (a Python int is weak)
    lo = np.float32(-1.0)
    top = np.int32(bins - 1)
    nb = np.int32(bins)
    zero = np.int32(0)
    for i in range(m):
        a = np.int32(min(max(((x[i] - cx) / scale + _F32_HALF) * fb, lo), fb))
        b = np.int32(min(max(((y[i] - cy) / scale + _F32_HALF) * fb, lo), fb))
        cells[i] = min(max(a, zero), top) * nb + min(max(b, zero), top)
    hist[:] = 0
    m4 = m - m % 4
    for i in range(0, m4, 4):
        hist[0, cells[i]] += 1
        hist[1, cells[i + 1]] += 1
        hist[2, cells[i + 2]] += 1
        hist[3, cells[i + 3]] += 1
    for i in range(m4, m):
        hist[0, cells[i]] += 1
    for c in range(bins * bins):
        out[e, c] = np.float64(hist[0, c] + hist[1, c] + hist[2, c] + hist[3, c])


@njit(**JIT)
def mean_cov_rows(px, py, mean, cov):  # pragma: no cover - compiled
    """Mean (k, 2) and population covariance (k, 2, 2), float64, of k unweighted clouds.

    Two sequential float64 passes per cloud: ``μ = Σ x / M``, then ``Σ = Σ (x − μ)(x − μ)ᵀ / M``.

    Args:
        px: (k, M) particle x (float32 or float64, any strides), mm.
        py: (k, M) particle y, mm.
        mean: (k, 2) float64 output, mm.
        cov: (k, 2, 2) float64 output, mm².
    """
    for e in range(px.shape[0]):
        _mean_cov_one(px[e], py[e], mean, cov, e)


@njit(**JIT)
def egocentric_counts(px, py, carriage, scale, bins, out):  # pragma: no cover - compiled
    """Particle counts (k, bins²) on a bins×bins grid of offsets around each carriage.

    Stands for ``observation._egocentric_histogram`` without weights, in the particles' dtype::

        rel = (p − carriage.astype(dtype)) / scale + 0.5        # scale = (2·H).astype(dtype)
        ij = np.clip((rel · bins).astype(intp), 0, bins − 1);  cell = i·bins + j

    Args:
        px: (k, M) particle x, mm.
        py: (k, M) particle y, mm.
        carriage: (k, 2) carriage centres cast to the particles' dtype, mm.
        scale: (k,) 2·H in the particles' dtype, mm.
        bins: cells per axis.
        out: (k, bins²) float64 counts.
    """
    cells = np.empty(px.shape[1], dtype=np.int32)
    hist = np.empty((4, bins * bins), dtype=np.int32)
    for e in range(px.shape[0]):
        _counts_one(px[e], py[e], carriage[e, 0], carriage[e, 1], scale[e], bins, out, e, cells, hist)
