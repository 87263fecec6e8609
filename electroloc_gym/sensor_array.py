"""A sensor array's readings: the true and the noisy reading of every one of K differential sensing pairs (paper §7).

The true reading of pair k is the paper's amplifier applied to that pair:
``Φ_k = clip(s·G·(δV(e_k1) − δV(e_k2)) + G·Δφ_nt,k + ε_k, ±V_sat)``, ``ε_k ~ N(0, (G·σ_s)²)`` independent per
pair, ``δV`` the target's induced dipole (Eq. 4) in the field of the pair's emitters, all from
:mod:`electroloc_gym.physics` (``Δφ_nt,k`` is 0, or below :data:`BASELINE_TOLERANCE_V`, or subtracted). A pair
that is the paper's unit translated by c (electrodes c ± (0, L/2), emitters c ± (L/2, 0)) is computed by
:func:`electroloc_gym.sensor.sphere_reading` at ``offsets − c``, the compiled fast path: the ``"single"``
layout's numbers are the one-pair sensor's bit for bit. Other pairs are one compiled pass of the same
equations for electrodes and emitters anywhere (:func:`electroloc_gym.kernels.fusion.general_pair_difference`),
tested equal to the physics module's :func:`~electroloc_gym.physics.emitter_field` +
:func:`~electroloc_gym.physics.sphere_perturbation` (:func:`_general_pair`), which is also tested equal to the
fast path on the paper's pair.
:func:`array_noisy_reading` adds each pair's own noise; :func:`detection_coverage` is the share of the
start box from which at least one pair detects the target.

Where the pairs sit, and the designs that keep their no-target reading ≈ 0 V, are the layouts of
:mod:`electroloc_gym.sensor_layouts` (:class:`SensorLayout`, :func:`named_layout`, :func:`make_sensor_layout`
and the constants), re-exported here.

Offsets are ``target − carriage centre`` (..., 2), mm; readings come out with the pairs first, (K, ...), V.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym import physics
from electroloc_gym.conditions import Condition
from electroloc_gym.kernels.fusion import general_pair_difference
from electroloc_gym.sensor import saturated_reading, sphere_reading
from electroloc_gym.sensor_layouts import (
    BASELINE_TOLERANCE_V,
    CARRIAGE_REACH_MM,
    LAYOUT_DESIGNS,
    LAYOUT_NAMES,
    MAX_PAIRS,
    SensorLayout,
    _error,
    _points3,
    make_sensor_layout,
    named_layout,
)

__all__ = [
    "LAYOUT_NAMES",
    "LAYOUT_DESIGNS",
    "CARRIAGE_REACH_MM",
    "BASELINE_TOLERANCE_V",
    "MAX_PAIRS",
    "SensorLayout",
    "named_layout",
    "make_sensor_layout",
    "array_reading",
    "array_noisy_reading",
    "pair_baseline_V",
    "detection_coverage",
]


def pair_baseline_V(layout: SensorLayout) -> NDArray[np.float64]:
    """(K,) the no-target difference each pair's amplifier input sees, V: 0 with the front end, else Δφ_nt."""
    return np.zeros(layout.n_pairs) if layout.subtract_baseline else layout.baselines_V


def _general_pair(
    condition: Condition,
    electrodes: NDArray[np.float64],
    emitters: NDArray[np.float64],
    off: NDArray[np.float64],
    a: NDArray[np.float64],
    chi: NDArray[np.float64],
) -> NDArray[np.float64]:
    """s·(δV(e1) − δV(e2)) (V, before the gain) of one pair for spheres at ``off`` (..., 2) through the physics
    module's general functions (Eq. 4, 7), float64: the reference the compiled pass is tested against.
    """
    g = condition.geometry
    depth = (a + g.electrode_radius_mm) + g.clearance_mm
    x, y = np.broadcast_arrays(off[..., 0], off[..., 1], depth)[:2]
    centre = np.stack([x, y, -np.broadcast_to(depth, x.shape)], axis=-1)
    emit = _points3(emitters)
    field_V_per_mm = physics.emitter_field(centre, emit[0], emit[1], g.emitter_voltage_V, g.electrode_radius_mm)
    elec = _points3(electrodes)
    dv = physics.sphere_perturbation(elec[0], centre, a, chi, field_V_per_mm) - physics.sphere_perturbation(
        elec[1], centre, a, chi, field_V_per_mm
    )
    return dv * condition.signal_scale


def array_reading(
    condition: Condition,
    layout: SensorLayout,
    offsets_mm: ArrayLike,
    *,
    radius_mm: ArrayLike | None = None,
    chi: ArrayLike | None = None,
    saturate: bool = True,
) -> NDArray[np.floating]:
    """Noise-free readings Φ (K, ...) (V) of every pair for spheres at ``offsets_mm`` (..., 2) = target − carriage.

    Args:
        condition: the tank, sphere and amplifier (every pair has the same amplifier: G, σ_s, ±V_sat).
        layout: the pairs (its geometry must be the condition's).
        offsets_mm: (..., 2) target − carriage centre, mm; float32 stays float32 (as
            :func:`~electroloc_gym.sensor.expected_reading`), anything else float64.
        radius_mm: sphere radius, mm (default the condition's; or an array broadcasting against offsets[..., 0]).
        chi: contrast χ (default the condition's; χ = 0 is no target).
        saturate: clip at ±V_sat.
    """
    if layout.geometry != condition.geometry:
        raise _error(f"was built for {layout.geometry}, the condition has {condition.geometry}")
    off = np.asarray(offsets_mm)
    dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    off = off.astype(dtype, copy=False)
    a = np.asarray(condition.target.radius_mm if radius_mm is None else radius_mm, dtype=np.float64)
    x = np.asarray(condition.chi if chi is None else chi, dtype=np.float64)
    gain = condition.amplifier.gain
    base = pair_baseline_V(layout)
    out = np.empty((layout.n_pairs,) + np.broadcast_shapes(off.shape[:-1], a.shape, x.shape), dtype=dtype)
    elec, emit = layout.electrodes, layout.emitters
    g = condition.geometry
    strength = x * (a * a * a)
    depth = (a + g.electrode_radius_mm) + g.clearance_mm
    drive = g.emitter_voltage_V * g.electrode_radius_mm
    for k, centre in enumerate(layout.paper_unit_centres):
        if centre is not None:
            shifted = off if centre == (0.0, 0.0) else off - np.asarray(centre, dtype=dtype)
            phi = sphere_reading(condition, shifted, a, x, saturate=False)
        else:  # Eq. 4 + 7 for this pair: the compiled pass, equal to _general_pair's (tested)
            (px, py), (nx, ny) = emit[k]
            (ax, ay), (bx, by) = elec[k]
            phi = general_pair_difference(
                off[..., 0].astype(np.float64),
                off[..., 1].astype(np.float64),
                depth,
                strength,
                drive,
                px,
                py,
                nx,
                ny,
                ax,
                ay,
                bx,
                by,
            )
            phi = phi * (condition.signal_scale * gain)
        if base[k] != 0.0:
            phi = phi + base[k] * gain
        out[k] = phi
    if saturate:
        sat = dtype.type(condition.saturation_V)
        np.clip(out, -sat, sat, out=out)
    return out


def array_noisy_reading(
    condition: Condition, layout: SensorLayout, offsets_mm: ArrayLike, rng: np.random.Generator, **sphere: Any
) -> NDArray[np.float64]:
    """Noisy, saturated readings Φ (K, ...) (V): each pair's own N(0, (G·σ_s)²) noise from ``rng`` (the pairs'
    draws in pair order), then the ±V_sat clip, as :func:`electroloc_gym.sensor.noisy_reading` (bit for bit
    for the ``"single"`` layout). ``sphere``: ``radius_mm``, ``chi`` as :func:`array_reading`.
    """
    mean = array_reading(condition, layout, np.asarray(offsets_mm, dtype=np.float64), saturate=False, **sphere)
    return saturated_reading(mean, rng.normal(0.0, condition.noise_std_V, size=mean.shape), condition.saturation_V)


def detection_coverage(
    condition: Condition, layout: SensorLayout, threshold_sigmas: float = 2.0, n_grid: int = 121
) -> float:
    """Fraction of carriage positions (uniform in the start box) from which at least one pair's noise-free reading
    exceeds ``threshold_sigmas``·G·σ_s: the array's analogue of
    :func:`electroloc_gym.conditions.start_box_coverage` (equal to it for ``"single"``).
    """
    s = condition.start_half_width_mm
    g = np.linspace(-s, s, n_grid)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    off = np.asarray(condition.target_xy_mm) - np.stack([gx, gy], axis=-1)
    signal = np.abs(array_reading(condition, layout, off))
    return float(np.mean(np.any(signal > threshold_sigmas * condition.noise_std_V, axis=0)))
