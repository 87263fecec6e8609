"""The belief observation's assembly from a cloud's statistics (layout: :mod:`electroloc_gym.contract.observation`).

One env per row, float64 arithmetic then a float32 cast; ``tanh`` and ``log10`` are scalar libm calls
(one per env: no SIMD path). The scalar entries' formulas are compiled here; their numbers (each entry's
factor, the spread's and the correlation's floors) are arguments, the declaration's
(:data:`electroloc_gym.contract.belief_summary.BELIEF_SCALARS`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from electroloc_gym.kernels.mathf32 import JIT

__all__ = ["belief_observation_rows"]


@njit(inline="always")
def _clip1(v):  # pragma: no cover - compiled
    """``np.clip(v, −1, 1)`` (NaN stays NaN)."""
    v = -1.0 if v < -1.0 else v
    return 1.0 if v > 1.0 else v


@njit(**JIT)
def belief_observation_rows(
    carriage,
    reading,
    mean,
    cov,
    n_obs,
    max_obs,
    hw,
    noise,
    sat,
    success,  # pragma: no cover
    hist,
    desc,
    factor,
    spread_floor,
    rho_floor,
    out,
):
    """The belief observations (k, 81) float32 of k clouds from their statistics (see
    :mod:`electroloc_gym.contract.observation` for the layout), float64 arithmetic, then cast: scalar entry
    i is ``clip(transform(q / (factor[i] · scale)), −1, 1)`` with its quantity, scale and transform of
    :data:`~electroloc_gym.contract.belief_summary.BELIEF_SCALARS`.

    Args:
        carriage: (k, 2) carriage centres, mm.
        reading: (k,) last readings, V.
        mean: (k, 2) belief means, mm.
        cov: (k, 2, 2) belief covariances, mm².
        n_obs: (k,) float64 readings fused so far.
        max_obs: the observation cap.
        hw: (k,) allowed half-widths H, mm.
        noise: (k,) G·σ_s, V.
        sat: (k,) saturation, V.
        success: the success threshold on √trace Σ, mm.
        hist: (k, 64) float64 histogram mass fractions.
        desc: (k, 5) float32 condition descriptors.
        factor: (n_scalars,) float64 each scalar entry's factor (n_scalars = 12: the histogram starts there).
        spread_floor: the spread's floor in the log₁₀ entry, mm.
        rho_floor: the σ_x·σ_y below which the correlation is 0, mm².
        out: (k, 81) float32 output.
    """
    n_sc = factor.shape[0]
    for e in range(carriage.shape[0]):
        cx = carriage[e, 0]
        cy = carriage[e, 1]
        h = hw[e]
        c00 = cov[e, 0, 0]
        c11 = cov[e, 1, 1]
        sx = np.sqrt(c00 if c00 > 0.0 else 0.0)
        sy = np.sqrt(c11 if c11 > 0.0 else 0.0)
        sxy = sx * sy
        rho = cov[e, 0, 1] / (sxy if sxy > rho_floor else rho_floor) if sxy > rho_floor else 0.0
        tr = c00 + c11
        spread = np.sqrt(tr if tr > 0.0 else 0.0)
        r = reading[e]
        out[e, 0] = np.float32(_clip1(cx / (factor[0] * h)))
        out[e, 1] = np.float32(_clip1(cy / (factor[1] * h)))
        out[e, 2] = np.float32(_clip1(r / (factor[2] * sat[e])))
        out[e, 3] = np.float32(_clip1(np.tanh(r / (factor[3] * noise[e]))))
        out[e, 4] = np.float32(_clip1((mean[e, 0] - cx) / (factor[4] * h)))
        out[e, 5] = np.float32(_clip1((mean[e, 1] - cy) / (factor[5] * h)))
        out[e, 6] = np.float32(_clip1(sx / (factor[6] * h)))
        out[e, 7] = np.float32(_clip1(sy / (factor[7] * h)))
        out[e, 8] = np.float32(_clip1(rho))
        out[e, 9] = np.float32(_clip1(spread / (factor[9] * h)))
        out[e, 10] = np.float32(
            _clip1(np.log10((spread if spread > spread_floor else spread_floor) / (factor[10] * success)))
        )
        out[e, 11] = np.float32(_clip1(n_obs[e] / (factor[11] * max_obs)))
        nh = hist.shape[1]
        for c in range(nh):
            out[e, n_sc + c] = np.float32(hist[e, c])
        for c in range(desc.shape[1]):
            out[e, n_sc + nh + c] = desc[e, c]
