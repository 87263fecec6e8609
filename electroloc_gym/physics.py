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

Table 3's theoretical detection distances: the four 12.7 mm rows are reproduced within ≈1 mm, the
four 38.1 mm rows are not (docs/design.md, "Physics", says why); ``electroloc detect`` shows both.
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
    "eq5_single_detector",
    "eq6_detection_distance",
    "layout_signal_on_45deg",
    "layout_detection_distance",
    "fit_signal_scale",
    "EQ5_ZERO_R",
]

FloatArray = NDArray[np.float64]

#: Dimensionless distance of the zero of Eq. 5 along the 45° line (Fig. 4–5 singularity).
EQ5_ZERO_R = 0.4123


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


# --------------------------------------------------------------------------------------------
# Detection distance: Eq. 5 (single detector) and Eq. 6, and the experimental layout (§6.7).
# --------------------------------------------------------------------------------------------


def eq5_single_detector(r: ArrayLike, a: float, e: float, chi: float) -> FloatArray:
    """Dimensionless perturbation ν = δV/V_e of Eq. 5 (paper §2.3, Eq. 5, in a cleaned-up form).

    Single detector at the origin, emitters at (±½, 0, 0), target at (r/√2, r/√2, 0); all lengths
    divided by the emitter spacing L.
    """
    r = np.asarray(r, dtype=float)
    s2 = np.sqrt(2.0)
    P = 1.0 + 2.0 * s2 * r + 4.0 * r * r
    M = 1.0 - 2.0 * s2 * r + 4.0 * r * r
    r3 = r * r * r
    N1 = (s2 - 4.0 * s2 * r * r + 16.0 * r3) * np.sqrt(M)
    N2 = (-s2 + 4.0 * s2 * r * r + 16.0 * r3) * np.sqrt(P)
    D = r * r * (P * np.sqrt(P)) * (M * np.sqrt(M))
    return -2.0 * (a * a * a) * chi * e * (N1 - N2) / D


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


def _last_crossing(r: FloatArray, g: FloatArray, func: Callable[[float], float | FloatArray]) -> float:
    """Largest root of ``func`` given samples ``g = func(r)`` on an increasing grid ``r``."""
    above = np.nonzero(g >= 0.0)[0]
    if above.size == 0:
        return float("nan")
    i = int(above[-1])
    if i == r.size - 1:
        return float("inf")
    return brent_root(func, r[i], r[i + 1], xtol=1e-12, rtol=1e-12)


def eq6_detection_distance(n: float, a: float, e: float, chi: float, r_max: float = 50.0) -> float:
    """Eq. 6: r_d = max{r : |ν(r)| = 2n} (dimensionless), for the single-detector layout of Eq. 5."""
    if not n > 0:
        raise ValueError(f"n (dimensionless noise) must be > 0, got {n!r}")
    r = np.geomspace(1e-3, r_max, 20001)

    def g(rr):
        return np.abs(eq5_single_detector(rr, a, e, chi)) - 2.0 * n

    return _last_crossing(r, g(r), g)


def layout_signal_on_45deg(
    distance_mm: ArrayLike,
    radius_mm: float,
    chi: float,
    depth_mm: float,
    spacing_mm: float = 50.0,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
) -> FloatArray:
    """|δV(S1) − δV(S2)| (V) of the experimental layout for a target along the 45° direction.

    ``distance_mm`` is the 3-D distance from the carriage centre to the target centre (§6.7), so the
    horizontal offset is ``h = sqrt(R² − depth²)`` along the line x = y; R < depth is invalid.
    """
    R = np.asarray(distance_mm, float)
    h = np.sqrt(np.maximum(R * R - depth_mm * depth_mm, 0.0))
    off = np.stack([h / np.sqrt(2.0), h / np.sqrt(2.0)], axis=-1)
    return np.abs(
        differential_perturbation(off, radius_mm, chi, depth_mm, spacing_mm, emitter_voltage_V, electrode_radius_mm)
    )


def _distance_grid(depth_mm: float, r_max_mm: float) -> FloatArray:
    return np.linspace(depth_mm, r_max_mm, 40001)[1:]


def layout_detection_distance(
    radius_mm: float,
    chi: float,
    noise_rms_V: float,
    depth_mm: float,
    signal_scale: float = 1.0,
    threshold_sigmas: float = 2.0,
    spacing_mm: float = 50.0,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
    r_max_mm: float = 400.0,
) -> float:
    """Detection distance (mm) of the experimental layout, §6.7 / Table 3 (theory column).

    The largest 3-D distance R along the 45° direction at which ``signal_scale·|δV(S1) − δV(S2)|``
    equals ``threshold_sigmas·σ`` (Eq. 6's max over the crossings). Gain cancels: both the signal
    and the noise are amplified by G.
    """
    if not noise_rms_V > 0:
        raise ValueError(f"noise_rms_V must be > 0, got {noise_rms_V!r}")
    kw = dict(
        radius_mm=radius_mm,
        chi=chi,
        depth_mm=depth_mm,
        spacing_mm=spacing_mm,
        emitter_voltage_V=emitter_voltage_V,
        electrode_radius_mm=electrode_radius_mm,
    )

    def g(R):
        return signal_scale * layout_signal_on_45deg(R, **kw) - threshold_sigmas * noise_rms_V

    R = _distance_grid(depth_mm, r_max_mm)
    return _last_crossing(R, g(R), g)


def fit_signal_scale(
    measured_distance_mm: float,
    radius_mm: float,
    chi: float,
    noise_rms_V: float,
    depth_mm: float,
    threshold_sigmas: float = 2.0,
    spacing_mm: float = 50.0,
    emitter_voltage_V: float = 2.0,
    electrode_radius_mm: float = 1.0,
    r_max_mm: float = 400.0,
) -> float:
    """Smallest ``signal_scale`` whose model detection distance reaches ``measured_distance_mm``.

    Paper §6.7, Table 3. Because R_d(s) = max{R : s·|Δ(R)| ≥ kσ} is non-decreasing in s, the smallest such
    s is ``kσ / max_{R ≥ R_meas} |Δ(R)|``. When R_meas lies on a monotone part of the near branch the
    maximum is at R_meas itself; when R_meas lies in the gap around the EEV's zero crossing on the
    45° line, the maximum is the peak of the far branch, i.e. the scale at which the detection
    distance jumps past the gap (where "the near branch ends").
    """
    from scipy.optimize import OptimizeResult, minimize_scalar

    kw = dict(
        radius_mm=radius_mm,
        chi=chi,
        depth_mm=depth_mm,
        spacing_mm=spacing_mm,
        emitter_voltage_V=emitter_voltage_V,
        electrode_radius_mm=electrode_radius_mm,
    )
    if measured_distance_mm <= depth_mm:
        raise ValueError(f"measured_distance_mm must exceed the target depth {depth_mm} mm, got {measured_distance_mm}")
    R = np.linspace(measured_distance_mm, r_max_mm, 40001)
    sig = layout_signal_on_45deg(R, **kw)
    i = int(np.argmax(sig))
    lo, hi = R[max(i - 1, 0)], R[min(i + 1, R.size - 1)]
    best = float(sig[i])
    if hi > lo:
        res = minimize_scalar(
            lambda r: -layout_signal_on_45deg(r, **kw), bounds=(lo, hi), method="bounded", options={"xatol": 1e-10}
        )
        res = cast(OptimizeResult, res)  # scipy is unannotated: minimize_scalar returns an OptimizeResult
        best = max(best, float(-res.fun))
    # Nudge up by 1e-6 (relative) so that the returned scale attains R_meas also when s* is the jump
    # scale, where the far-branch peak only touches the threshold (a grid search could miss it).
    return threshold_sigmas * noise_rms_V / best * (1.0 + 1e-6)
