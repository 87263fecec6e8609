"""Observation builders shared by the single and the batched environments.

All functions accept arbitrary leading batch dimensions so that ``ElectroLocEnv`` (no batch) and the
native vector env (batch = number of envs) build identical vectors from one code path.

The "belief" observation (float32, every entry in [−1, 1]) makes the task close to Markov:

=====  =============================================  ==========================================
index  feature                                        normalisation
=====  =============================================  ==========================================
0–1    carriage position (x, y)                       / allowed half-width H (mm)
2      last reading Φ                                  / saturation (10 V)
3      last reading in noise units                     tanh(Φ / (3·G·σ_s))
4–5    belief mean − carriage (x, y)                   / 2H
6–7    belief standard deviation (x, y)                / H, clipped to [0, 1]
8      belief correlation ρ_xy                         as is
9      spread √trace Σ                                 / H, clipped to [0, 1]
10     log₁₀(spread / success spread)                  clipped to [−1, 1]
11     observations used / observation cap             as is
12–75  8×8 egocentric particle histogram               mass fraction per cell; cells span
                                                       offsets ±H around the carriage (x-major)
76–80  condition descriptor                            radius/25 mm, χ, log₁₀(G)/4,
                                                       G·σ_s (V), signal_scale/8 (clipped)
=====  =============================================  ==========================================

The "raw" observation is ``[x/H, y/H, Φ/10 V]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.kernels import belief_observation_rows, egocentric_counts
from electroloc_gym.belief import weighted_mean_cov
from electroloc_gym.conditions import Condition

HIST_BINS = 8
N_SCALARS = 12
N_DESCRIPTOR = 5
BELIEF_OBS_DIM = N_SCALARS + HIST_BINS * HIST_BINS + N_DESCRIPTOR
RAW_OBS_DIM = 3
OBSERVATION_MODES = ("belief", "raw")

__all__ = [
    "BELIEF_OBS_DIM",
    "RAW_OBS_DIM",
    "OBSERVATION_MODES",
    "HIST_BINS",
    "condition_descriptor",
    "belief_observation",
    "raw_observation",
]


def condition_descriptor(condition: Condition) -> NDArray[np.float32]:
    """Five numbers in [−1, 1] that tell the policy which condition it is in."""
    d = np.array([
        condition.target.radius_mm / 25.0,
        condition.chi,
        np.log10(condition.amplifier.gain) / 4.0,
        condition.noise_std_V,
        condition.signal_scale / 8.0,
    ])
    return np.clip(d, -1.0, 1.0).astype(np.float32)


def raw_observation(carriage_mm: NDArray, reading_V: NDArray, half_width_mm: NDArray | float,
                    saturation_V: NDArray | float = 10.0) -> NDArray[np.float32]:
    """[x/H, y/H, Φ/V_sat] with batch dims (..., 3)."""
    hw = np.asarray(half_width_mm, dtype=np.float64)[..., None]
    pos = np.asarray(carriage_mm) / hw
    r = np.asarray(reading_V) / np.asarray(saturation_V)
    return np.clip(np.concatenate([pos, r[..., None]], axis=-1), -1.0, 1.0).astype(np.float32)


def belief_observation(
    carriage_mm: NDArray,
    reading_V: NDArray,
    particles_mm: NDArray,
    weights: NDArray | None,
    n_observations: NDArray | int,
    max_observations: int,
    half_width_mm: NDArray | float,
    noise_std_V: NDArray | float,
    saturation_V: NDArray | float,
    success_spread_mm: float,
    descriptor: NDArray,
    mean_cov: tuple[NDArray, NDArray] | None = None,
    hist: NDArray | None = None,
) -> NDArray[np.float32]:
    """The belief observation (..., BELIEF_OBS_DIM); see the module docstring for the layout.

    Args:
        carriage_mm: (..., 2) carriage centre, mm.
        reading_V: (...) last reading, V.
        particles_mm: (..., M, 2) particles (target positions in the world frame), mm.
        weights: (..., M) normalised weights or None (uniform).
        n_observations: (...) readings fused so far.
        max_observations: the cap.
        half_width_mm: (...) allowed half-width H, mm.
        noise_std_V: (...) G·σ_s, V.
        saturation_V: (...) clip level, V.
        success_spread_mm: the success threshold on √trace Σ, mm.
        descriptor: (..., 5) from :func:`condition_descriptor`.
        mean_cov: precomputed (mean, cov) of the particles, if the caller has them.
        hist: precomputed (..., 64) histogram (entries 12–75), if the caller has it.
    """
    carriage = np.asarray(carriage_mm, dtype=np.float64)
    batch = carriage.shape[:-1]
    k = int(np.prod(batch)) if batch else 1
    hw = np.asarray(half_width_mm, dtype=np.float64)
    if hw.shape != batch:
        hw = np.broadcast_to(hw, batch)
    mean, cov = weighted_mean_cov(particles_mm, weights) if mean_cov is None else mean_cov
    if hist is None:
        hist = _egocentric_histogram(particles_mm, weights, carriage, hw)

    def rows(x: Any, tail: tuple[int, ...] = (), dtype: Any = np.float64) -> NDArray:
        a = np.asarray(x, dtype=dtype)
        if a.shape != batch + tail or not a.flags.c_contiguous:
            a = np.ascontiguousarray(np.broadcast_to(a, batch + tail))
        return a.reshape((k,) + tail)

    out = np.empty((k, BELIEF_OBS_DIM), dtype=np.float32)
    belief_observation_rows(rows(carriage, (2,)), rows(reading_V), rows(mean, (2,)), rows(cov, (2, 2)),
                            rows(n_observations), float(max_observations), rows(hw), rows(noise_std_V),
                            rows(saturation_V), float(success_spread_mm), rows(hist, (HIST_BINS * HIST_BINS,)),
                            rows(descriptor, (N_DESCRIPTOR,), np.float32), out)
    return out.reshape(batch + (BELIEF_OBS_DIM,))


def _egocentric_histogram(particles_mm: NDArray, weights: NDArray | None, carriage: NDArray,
                          hw: NDArray) -> NDArray:
    """Mass fraction of particles in an 8×8 grid of offsets ±H around the carriage, (..., 64).

    Without weights the cells are counted by a compiled kernel (:func:`electroloc_gym.kernels.egocentric_counts`,
    the same float arithmetic as the weighted numpy path) — one pass instead of eight.
    """
    p = np.asarray(particles_mm)
    if p.dtype not in (np.float32, np.float64):
        p = p.astype(np.float64)
    m = p.shape[-2]
    batch = p.shape[:-2]
    nb = HIST_BINS * HIST_BINS
    if weights is None:
        flat = p.reshape((-1, m, 2))
        n_clouds = flat.shape[0]
        counts = np.empty((n_clouds, nb))
        egocentric_counts(flat[..., 0], flat[..., 1], np.asarray(carriage).reshape(n_clouds, 2).astype(p.dtype),
                          (2 * hw).reshape(n_clouds).astype(p.dtype), HIST_BINS, counts)
        return (counts / m).reshape(batch + (nb,))
    rel = (p - carriage[..., None, :].astype(p.dtype)) / (2 * hw[..., None, None]).astype(p.dtype) + 0.5
    ij = np.clip((rel * HIST_BINS).astype(np.intp), 0, HIST_BINS - 1)
    cell = ij[..., 0] * HIST_BINS + ij[..., 1]
    n_clouds = int(np.prod(batch)) if batch else 1
    flat_cells = (cell.reshape(n_clouds, m) + nb * np.arange(n_clouds)[:, None]).ravel()
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    return np.bincount(flat_cells, weights=w, minlength=n_clouds * nb).reshape(batch + (nb,))
