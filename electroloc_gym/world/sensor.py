"""The robot's sensor: carriage geometry and the amplified, noisy, saturating reading (paper §3.1–3.2, Fig. 6).

``Φ = clip(s·G·(δV(S1) − δV(S2)) + ε, −V_sat, +V_sat)``, ``ε ~ N(0, (G·σ_s)²)``, in volts, where
``s`` is the condition's ``signal_scale``.
"""

from __future__ import annotations

from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels import noisy_saturated
from electroloc_gym.kernels.streams import normal_table, table_normal_indices
from electroloc_gym.world import physics
from electroloc_gym.world.conditions import Condition

__all__ = [
    "expected_reading",
    "sphere_reading",
    "saturated_reading",
    "noisy_reading",
    "calibration_readings",
    "add_calibration_noise",
    "electrode_positions_mm",
    "zero_crossing_mm",
]


@overload
def expected_reading(
    condition: Condition, offsets_mm: NDArray[np.float32], *, saturate: bool = True
) -> NDArray[np.float32]: ...
@overload
def expected_reading(
    condition: Condition, offsets_mm: NDArray[np.float64], *, saturate: bool = True
) -> NDArray[np.float64]: ...
@overload
def expected_reading(condition: Condition, offsets_mm: ArrayLike, *, saturate: bool = True) -> NDArray[np.floating]: ...
def expected_reading(condition: Condition, offsets_mm: ArrayLike, *, saturate: bool = True) -> NDArray[np.floating]:
    """Noise-free reading Φ (V) for targets at ``offsets_mm`` = target − carriage centre, shape (..., 2).

    float32 input stays float32 (the belief's fast path); anything else is computed in float64.
    """
    return sphere_reading(condition, offsets_mm, condition.target.radius_mm, condition.chi, saturate=saturate)


def sphere_reading(
    condition: Condition, offsets_mm: ArrayLike, radius_mm: ArrayLike, chi: ArrayLike, *, saturate: bool = True
) -> NDArray[np.floating]:
    """Noise-free reading Φ (V) of spheres of radius ``radius_mm`` (mm) and contrast ``chi`` at
    ``offsets_mm`` (..., 2), in the tank of ``condition`` (its own sphere is :func:`expected_reading`'s).

    ``radius_mm`` and ``chi`` may be arrays broadcasting against ``offsets[..., 0]`` (one sphere per
    offset: the unknown-target env's hypotheses). The sphere's centre lies A + E + O below the
    electrodes (§6.7). Strength and depth are computed in float64 and rounded once to the offsets'
    precision; float32 offsets are computed in float32, anything else in float64.
    """
    off = np.asarray(offsets_mm)
    dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    t = dtype.type
    a = np.asarray(radius_mm, dtype=np.float64)
    g = condition.geometry
    depth = (a + g.electrode_radius_mm) + g.clearance_mm
    delta = physics.differential_perturbation(
        off.astype(dtype, copy=False),
        a,
        np.asarray(chi, dtype=np.float64),
        depth,
        spacing_mm=g.spacing_mm,
        emitter_voltage_V=g.emitter_voltage_V,
        electrode_radius_mm=g.electrode_radius_mm,
    )
    phi = np.asarray(delta * t(condition.signal_scale * condition.amplifier.gain))
    if saturate:
        sat = t(condition.saturation_V)
        phi = np.clip(phi, -sat, sat, out=phi if phi.ndim else None)
    return phi


def saturated_reading(mean_V: ArrayLike, noise_V: ArrayLike, saturation_V: ArrayLike) -> NDArray[np.float64]:
    """The reading Φ = clip(mean + noise, −V_sat, V_sat) (V) from its noise-free, unsaturated value and
    its noise (every env and the map's calibration build their readings here).
    """
    sat = np.asarray(saturation_V)
    return np.minimum(np.maximum(np.asarray(mean_V) + noise_V, -sat), sat)


def noisy_reading(condition: Condition, offsets_mm: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
    """A noisy, saturated reading Φ (V) at ``offsets_mm`` (..., 2), noise drawn from ``rng``."""
    mean = expected_reading(condition, np.asarray(offsets_mm, dtype=np.float64), saturate=False)
    return saturated_reading(mean, rng.normal(0.0, condition.noise_std_V, size=mean.shape), condition.saturation_V)


def add_calibration_noise(
    condition: Condition, mean_V: NDArray[np.float64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """Calibration readings from their noise-free, unsaturated values ``mean_V`` (V): add
    N(0, (G·σ_s)²) noise and saturate, the noise from the normal quantile table
    (:mod:`electroloc_gym.kernels.streams`, far cheaper than ``rng.normal`` for the thousands of readings of a
    calibration; a new calibration per episode is the default).
    """
    mean = np.ascontiguousarray(mean_V, dtype=np.float64).reshape(-1)
    out = np.empty_like(mean)
    noisy_saturated(
        mean,
        table_normal_indices(rng, mean.size),
        normal_table(),
        float(condition.noise_std_V),
        float(condition.saturation_V),
        out,
    )  # clip(mean + z·σ, ±V_sat), z from the table
    return out.reshape(np.shape(mean_V))


def calibration_readings(condition: Condition, offsets_mm: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
    """The calibration's noisy, saturated readings Φ (V) at ``offsets_mm`` (..., 2): :func:`noisy_reading`
    with the noise from the quantile table (:func:`add_calibration_noise`).
    """
    mean = expected_reading(condition, np.asarray(offsets_mm, dtype=np.float64), saturate=False)
    return add_calibration_noise(condition, mean, rng)


def electrode_positions_mm(condition: Condition, carriage_xy_mm: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """World (x, y) of the emitters (``"emitter+"``, ``"emitter-"``) and sensors (``"S1"``, ``"S2"``), mm."""
    p = np.asarray(carriage_xy_mm, dtype=float)
    h = condition.geometry.spacing_mm / 2.0
    return {
        "emitter+": p + (h, 0.0),
        "emitter-": p + (-h, 0.0),
        "S1": p + (0.0, h),
        "S2": p + (0.0, -h),
    }


def zero_crossing_mm(condition: Condition, r_max_mm: float = 400.0) -> float:
    """3-D distance (mm) along the 45° line where the noise-free differential reading changes sign.

    Inside it lies the near field (the 0 V contour of Fig. 4a / Fig. 9), beyond it the far field; near
    it the signal vanishes, so the detection distance jumps across a gap as the noise falls (§2.3).
    NaN if the reading keeps its sign out to ``r_max_mm``.
    """
    geo = condition.geometry
    depth = condition.depth_mm

    def signed(R: ArrayLike) -> NDArray[np.float64]:
        h = np.sqrt(np.maximum(np.asarray(R, float) ** 2 - depth * depth, 0.0)) / np.sqrt(2.0)
        return physics.differential_perturbation(
            np.stack([h, h], axis=-1),
            condition.target.radius_mm,
            condition.chi,
            depth,
            spacing_mm=geo.spacing_mm,
            emitter_voltage_V=geo.emitter_voltage_V,
            electrode_radius_mm=geo.electrode_radius_mm,
        )

    R = np.linspace(depth, r_max_mm, 4001)[1:]
    v = signed(R)
    flips = np.nonzero(np.sign(v[:-1]) * np.sign(v[1:]) < 0)[0]
    if flips.size == 0:
        return float("nan")
    i = int(flips[0])
    return physics.brent_root(lambda r: float(signed(r)), R[i], R[i + 1], xtol=1e-9)
