"""The physics of the electrolocation robot (no Gymnasium, no randomness).

Units: lengths in millimetres (mm), potentials in volts (V), fields in V/mm, conductivities in
µS/cm. Every function is vectorised over arbitrary leading shapes.

Numerical form: array expressions use only IEEE-exact operations (+ − × ÷, √), never ``pow``
(``r**-1.5`` is ``1/(r·√r)``), so every element gets the same bits on every CPU however it is batched;
the hot two-sensor dipole difference is one compiled elementwise pass (docs/design.md).

Geometry (paper §2.2, §6.7, Appendix A): the carriage carries two emitters at
``p + (±L/2, 0, 0)`` and two sensing electrodes ``S1 = p + (0, +L/2, 0)``,
``S2 = p + (0, -L/2, 0)``, all in the plane z = 0. A target sphere of radius A sits below with its
centre at ``z = -(A + E + O)`` (electrode radius E = 1 mm, clearance O = 2 mm).

Model (paper Eq. 4 and Eq. 7):

* The emitters are spheres of radius E held at ±V_e; far from them each behaves as a point charge
  with ``q·k = V_e·E`` (App. A, Eq. 7), so ``φ(x) = V_e E (1/|x - x₊| - 1/|x - x₋|)``.
* A small sphere in a uniform field ``E_f`` becomes a dipole (Rasnow 1996, paper Eq. 4):
  ``δV(s) = χ a³ E_f(c)·(s - c)/|s - c|³`` with contrast ``χ = (σ_t - σ_w)/(σ_t + 2σ_w)``.
* The robot reads the amplified difference ``G·(δV(S1) - δV(S2))``; the unperturbed potentials at
  S1 and S2 are equal (both lie on the emitters' mid-plane), so only the perturbation is seen.

The detection distances built on this signal (Eq. 5, Eq. 6, Table 3) are :mod:`electroloc_gym.world.detection`'s.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

import numpy as np
from numba import vectorize
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "contrast_factor_sphere",
    "contrast_factor_cylinder",
    "emitter_potential",
    "emitter_field",
    "sphere_perturbation",
    "cylinder_perturbation",
    "differential_perturbation",
    "differential_line_perturbation",
    "brent_root",
]

FloatArray = NDArray[np.float64]


def contrast_factor_sphere(target_conductivity_uScm: ArrayLike, water_conductivity_uScm: ArrayLike) -> FloatArray:
    """χ = (σ_t − σ_w)/(σ_t + 2σ_w) of a sphere (paper Eq. 4); +1 conductor, −½ insulator.

    Args:
        target_conductivity_uScm: conductivity of the target, µS/cm (≥ 0).
        water_conductivity_uScm: conductivity of the water, µS/cm (> 0).
    """
    st = np.asarray(target_conductivity_uScm, dtype=float)
    sw = np.asarray(water_conductivity_uScm, dtype=float)
    return (st - sw) / (st + 2.0 * sw)


def contrast_factor_cylinder(target_conductivity_uScm: ArrayLike, water_conductivity_uScm: ArrayLike) -> FloatArray:
    """χ₂ = (σ_t − σ_w)/(σ_t + σ_w) of an infinite cylinder in a transverse field (2-D analogue)."""
    st = np.asarray(target_conductivity_uScm, dtype=float)
    sw = np.asarray(water_conductivity_uScm, dtype=float)
    return (st - sw) / (st + sw)


def _point_charges(
    x: FloatArray, x_pos: FloatArray, x_neg: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    dp = x - x_pos
    dn = x - x_neg
    rp = np.sqrt(np.sum(dp * dp, axis=-1, keepdims=True))
    rn = np.sqrt(np.sum(dn * dn, axis=-1, keepdims=True))
    return dp, dn, rp, rn


def emitter_potential(
    x_mm: ArrayLike,
    emitter_pos_mm: ArrayLike,
    emitter_neg_mm: ArrayLike,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
) -> FloatArray:
    """Potential φ (V) of the two emitters at points ``x_mm`` (..., 3), App. A Eq. 7.

    The emitters are modelled as point charges with ``q·k = V_e·E`` so that the potential on the
    surface of an isolated emitter sphere of radius E equals ±V_e.
    """
    x = np.asarray(x_mm, dtype=float)
    _, _, rp, rn = _point_charges(x, np.asarray(emitter_pos_mm, float), np.asarray(emitter_neg_mm, float))
    return emitter_voltage_V * electrode_radius_mm * (1.0 / rp - 1.0 / rn)[..., 0]


def emitter_field(
    x_mm: ArrayLike,
    emitter_pos_mm: ArrayLike,
    emitter_neg_mm: ArrayLike,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
) -> FloatArray:
    """Electric field E_f = −∇φ (V/mm) at points ``x_mm`` (..., 3), App. A Eq. 7."""
    x = np.asarray(x_mm, dtype=float)
    dp, dn, rp, rn = _point_charges(x, np.asarray(emitter_pos_mm, float), np.asarray(emitter_neg_mm, float))
    return emitter_voltage_V * electrode_radius_mm * (dp / (rp * rp * rp) - dn / (rn * rn * rn))


def sphere_perturbation(
    s_mm: ArrayLike,
    center_mm: ArrayLike,
    radius_mm: ArrayLike,
    chi: ArrayLike,
    field_at_center_V_per_mm: ArrayLike,
) -> FloatArray:
    """Perturbation δV (V) at points ``s_mm`` (..., 3) of a sphere in a uniform field, paper Eq. 4.

    ``δV(s) = χ a³ E_f(c)·(s − c)/|s − c|³`` (Rasnow 1996): the field of the induced dipole.
    """
    d = np.asarray(s_mm, float) - np.asarray(center_mm, float)
    r2 = np.sum(d * d, axis=-1)
    dot = np.sum(np.asarray(field_at_center_V_per_mm, float) * d, axis=-1)
    a = np.asarray(radius_mm, float)
    return np.asarray(chi, float) * (a * a * a) * dot / (r2 * np.sqrt(r2))


def cylinder_perturbation(
    s_mm: ArrayLike,
    axis_point_mm: ArrayLike,
    radius_mm: ArrayLike,
    chi2: ArrayLike,
    field_at_axis_V_per_mm: ArrayLike,
) -> FloatArray:
    """Perturbation δV (V) of a vertical infinite cylinder: the 2-D analogue of Eq. 4 (docs/design.md, "Physics").

    ``δV(s) = χ₂ a² E_f(c)·(s − c)/|s − c|²`` where c is the closest point of the (vertical) axis
    to s, i.e. only the horizontal (x, y) components enter.
    """
    s = np.asarray(s_mm, float)[..., :2]
    c = np.asarray(axis_point_mm, float)[..., :2]
    e = np.asarray(field_at_axis_V_per_mm, float)[..., :2]
    d = s - c
    r2 = np.sum(d * d, axis=-1)
    a = np.asarray(radius_mm, float)
    return np.asarray(chi2, float) * (a * a) * np.sum(e * d, axis=-1) / r2


def differential_perturbation(
    offsets_mm: ArrayLike,
    radius_mm: float | FloatArray,
    chi: float | FloatArray,
    depth_mm: float | FloatArray,
    spacing_mm: float = 50.0,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
) -> FloatArray:
    """δV(S1) − δV(S2) (V, at the electrodes, before amplification) for a sphere at ``offsets_mm``.

    Eq. 4 + Eq. 7 written per coordinate column (the analytic sensor model evaluates it on every
    particle), with exact operations only (module docstring).

    Args:
        offsets_mm: (..., 2) horizontal target position relative to the carriage centre, mm.
        radius_mm: sphere radius A, mm (or an array, one sphere per offset, broadcasting).
        chi: contrast factor χ (dimensionless; or an array, as ``radius_mm``).
        depth_mm: depth of the sphere centre below the electrode plane, mm (> 0; or an array).
        spacing_mm: emitter spacing L (= sensor spacing), mm.
        emitter_voltage_V: emitter voltage V_e, V.
        electrode_radius_mm: emitter radius E, mm.

    Returns:
        Array of shape (...) in volts.
    """
    return _differential_dipole(
        offsets_mm,
        chi * (radius_mm * radius_mm * radius_mm),
        depth_mm,
        1.5,
        spacing_mm,
        emitter_voltage_V,
        electrode_radius_mm,
    )


_DIPOLE_SIGNATURES = [
    "float32(float32, float32, float32, float32, float32, float32, float32, boolean)",
    "float64(float64, float64, float64, float64, float64, float64, float64, boolean)",
]


@vectorize(_DIPOLE_SIGNATURES, cache=True)
def _dipole_difference(x, y, h, z2, k, strength, one, point):  # pragma: no cover - compiled
    """One offset's ``strength · E_f(c)·[(S1 − c)/|S1 − c|^p − (S2 − c)/|S2 − c|^p]``, p = 3 (``point``)
    or 2, in the input's precision (``one`` = 1 in it), exact operations only (module docstring).
    """
    # Emitter field at the object centre c = (x, y, -depth) (Eq. 7).
    xp = x - h
    xn = x + h
    y2z2 = y * y + z2
    tp = xp * xp + y2z2
    tn = xn * xn + y2z2
    ip = one / (tp * np.sqrt(tp))
    inn = one / (tn * np.sqrt(tn))
    ex = k * (xp * ip - xn * inn)
    eyz = k * (ip - inn)  # E_y = eyz * y, E_z = eyz * (-depth)
    # Dipole potential at the sensors, (s - c) = (-x, ±h - y, +depth) (Eq. 4).
    x2z2 = x * x + z2
    d1 = h - y
    d2 = -h - y
    t1 = x2z2 + d1 * d1
    t2 = x2z2 + d2 * d2
    r1 = one / (t1 * np.sqrt(t1)) if point else one / t1
    r2 = one / (t2 * np.sqrt(t2)) if point else one / t2
    common = -ex * x - eyz * z2  # E·(s-c) without the y term: E_x(-x) + E_z(+depth) = -ex x - eyz depth²
    dot1 = common + eyz * y * d1
    dot2 = common + eyz * y * d2
    return strength * (dot1 * r1 - dot2 * r2)


#: The compiled numpy ufunc itself (float32 and float64 loops), without numba's Python-level dispatcher.
_DIPOLE_UFUNC = _dipole_difference.ufunc


def _differential_dipole(
    offsets_mm: ArrayLike,
    strength: float | FloatArray,
    depth_mm: float | FloatArray,
    power: float,
    spacing_mm: float,
    emitter_voltage_V: float,
    electrode_radius_mm: float,
) -> NDArray:
    """``strength · E_f(c)·[(S1 − c)/|S1 − c|^(2·power) − (S2 − c)/|S2 − c|^(2·power)]`` per offset.

    ``power = 1.5``: a sphere's point dipole (Eq. 4, strength χa³); ``power = 1``: a vertical
    cylinder's line dipole (2-D analogue, strength χ₂a²), c at ``depth_mm`` below the electrodes.
    float32 offsets are computed in float32, anything else in float64; one compiled pass per offset.
    ``strength`` and ``depth_mm`` may be arrays broadcasting against the offsets (one object each).
    """
    off = np.asarray(offsets_mm)
    dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    t = dtype.type
    x = off[..., 0].astype(dtype, copy=False)
    y = off[..., 1].astype(dtype, copy=False)
    z2 = np.asarray(depth_mm * depth_mm, dtype=dtype)  # arrays (per-object depth and strength) broadcast
    return _DIPOLE_UFUNC(
        x,
        y,
        t(spacing_mm / 2.0),
        z2,
        t(emitter_voltage_V * electrode_radius_mm),
        np.asarray(strength, dtype=dtype),
        t(1.0),
        power == 1.5,
    )


def differential_line_perturbation(
    offsets_mm: ArrayLike,
    radius_mm: float,
    chi2: float,
    depth_mm: float,
    spacing_mm: float = 50.0,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
) -> FloatArray:
    """δV(S1) − δV(S2) (V) of a vertical cylinder whose axis top sits ``depth_mm`` below the electrodes.

    The 2-D analogue of Eq. 4 (docs/design.md, "Physics"), ``χ₂ a² E_f(c)·(s − c)/|s − c|²``, evaluated with the
    same column-wise fast path as :func:`differential_perturbation`; float32 in, float32 out.
    """
    return _differential_dipole(
        offsets_mm, chi2 * (radius_mm * radius_mm), depth_mm, 1.0, spacing_mm, emitter_voltage_V, electrode_radius_mm
    )


def brent_root(
    f: Callable[[float], float | NDArray[np.floating[Any]]],
    a: float,
    b: float,
    *,
    xtol: float,
    rtol: float | None = None,
) -> float:
    """The root of ``f`` in the bracket [a, b]: scipy's ``brentq`` (``rtol`` None: scipy's default)."""
    from scipy.optimize import brentq

    if rtol is None:
        root = brentq(f, a, b, xtol=xtol)
    else:
        root = brentq(f, a, b, xtol=xtol, rtol=rtol)  # pyright: ignore[reportArgumentType]  # scipy is unannotated: pyright takes rtol's type from its float64 default
    return float(cast(float, root))  # full_output False: brentq returns the root alone, not (root, results)
