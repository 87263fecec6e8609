"""Detection distances of the electrolocation robot (no Gymnasium, no randomness).

Paper Eq. 5 (one detector), Eq. 6 (the largest distance at which the signal exceeds twice the noise)
and the experimental two-sensor layout along the 45° line (§6.7, Table 3's theory column), and the
signal scale fitted to Table 3's measured distances (docs/physics.md).

Units: lengths in mm (Eq. 5 and Eq. 6 dimensionless, divided by the emitter spacing L), potentials in
V. The signal itself is :mod:`electroloc_gym.world.physics`' (``differential_perturbation``); a detection
distance is the last crossing of signal − threshold on a fine grid, refined by Brent's method.

Table 3's theoretical detection distances: the four 12.7 mm rows are reproduced within ≈1 mm, the
four 38.1 mm rows are not (docs/design.md, "Physics", says why); ``electroloc detect`` shows both.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

import numpy as np
from numpy.typing import ArrayLike

from electroloc_gym.world.physics import FloatArray, brent_root, differential_perturbation

__all__ = [
    "eq5_single_detector",
    "eq6_detection_distance",
    "layout_signal_on_45deg",
    "layout_detection_distance",
    "fit_signal_scale",
    "EQ5_ZERO_R",
]

#: Dimensionless distance of the zero of Eq. 5 along the 45° line (Fig. 4–5 singularity).
EQ5_ZERO_R = 0.4123


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
