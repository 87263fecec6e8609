"""The belief's summary numbers both engines report, declared once: observation scalars, info error and spread.

The belief observation's first :data:`N_SCALARS` entries (layout: :mod:`electroloc_gym.contract.observation`)
are each one quantity of the env's belief or sensing, normalised by one formula, declared as data in
:data:`BELIEF_SCALARS`: entry i is

    ``clip(transform(max(q, floor) / (factor · scale)), −1, 1)``

with ``q`` its quantity (:func:`belief_quantities`: the carriage, the reading, the belief mean's offset
from the carriage, the belief's standard deviations, correlation and spread √trace Σ, the readings fused),
``scale`` one of the env's scales (the allowed half-width H, the saturation V_sat, the noise G·σ_s, the
success spread, the reading cap), ``factor`` a number, ``floor`` a lower bound (none for most) and
``transform`` the identity, ``tanh`` or ``log10``; an entry with no scale is its quantity as is.

:func:`belief_scalars` evaluates the declaration in any array namespace: the torch engine computes its
observation with it. The numba engine assembles the observation in a compiled kernel
(:func:`electroloc_gym.kernels.belief_observation_rows`, one env per row, scalar ``tanh`` and ``log10``),
which takes the declaration's numbers — the factors (:data:`BELIEF_SCALAR_FACTORS`), the spread's floor
and the correlation's floor — as arguments; ``tests/test_contract_rules.py`` checks that the kernel and
the declaration agree entry by entry.

The info's belief entries (``error_mm``, ``spread_mm``, ``success``) are :func:`belief_info_values`, the
termination rule's spread :func:`belief_spread_mm`. Everything here uses only arithmetic, ``sqrt``,
``tanh``, ``log10``, ``clip``, ``where`` and ``stack``, which numpy and torch both have with the same
meaning, in the inputs' precision (float64 in both engines).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "BeliefScalar",
    "BELIEF_SCALARS",
    "N_SCALARS",
    "BELIEF_SCALAR_FACTORS",
    "LOG_SPREAD_FLOOR_MM",
    "CORRELATION_FLOOR_MM2",
    "SCALE_NAMES",
    "TRANSFORMS",
    "belief_spread_mm",
    "belief_quantities",
    "belief_scalar_values",
    "belief_scalars",
    "belief_info_values",
]

#: The scales an entry may divide by (the keys of :func:`belief_scalar_values`' ``scales``).
SCALE_NAMES = ("half_width_mm", "saturation_V", "noise_std_V", "success_spread_mm", "max_observations")
#: The transforms an entry may apply after its division.
TRANSFORMS = ("identity", "tanh", "log10")
#: The quantities an entry may normalise (the keys of :func:`belief_quantities`).
QUANTITY_NAMES = (
    "carriage_x_mm",
    "carriage_y_mm",
    "reading_V",
    "mean_offset_x_mm",
    "mean_offset_y_mm",
    "std_x_mm",
    "std_y_mm",
    "correlation",
    "spread_mm",
    "n_observations",
)
#: The spread's floor in entry 10 (log₁₀ of a spread below it is log₁₀ of the floor), mm.
LOG_SPREAD_FLOOR_MM = 1e-6
#: Below this product of the standard deviations σ_x·σ_y (mm²) the correlation is 0 (a collapsed cloud).
CORRELATION_FLOOR_MM2 = 1e-12


@dataclass(frozen=True)
class BeliefScalar:
    """One scalar entry of the belief observation: ``clip(transform(max(q, floor) / (factor · scale)), −1, 1)``.

    Attributes:
        name: the entry's name.
        quantity: its quantity q, one of :data:`QUANTITY_NAMES` (unit in the name).
        scale: one of :data:`SCALE_NAMES` (q's unit), or None: q as is (dimensionless, factor 1).
        factor: the scale's multiplier (dimensionless, > 0).
        transform: one of :data:`TRANSFORMS`.
        floor: q's lower bound before the division (q's unit), or None.
    """

    name: str
    quantity: str
    scale: str | None
    factor: float = 1.0
    transform: str = "identity"
    floor: float | None = None

    def __post_init__(self) -> None:
        if self.quantity not in QUANTITY_NAMES:
            raise ValueError(f"quantity must be one of {list(QUANTITY_NAMES)}, got {self.quantity!r}")
        if self.scale is not None and self.scale not in SCALE_NAMES:
            raise ValueError(f"scale must be None or one of {list(SCALE_NAMES)}, got {self.scale!r}")
        if self.transform not in TRANSFORMS:
            raise ValueError(f"transform must be one of {list(TRANSFORMS)}, got {self.transform!r}")
        if not self.factor > 0.0 or (self.scale is None and self.factor != 1.0):
            raise ValueError(f"factor must be > 0 (1 without a scale), got {self.factor!r}")


#: The belief observation's scalar entries 0–11, in order (the layout's table:
#: :mod:`electroloc_gym.contract.observation`).
BELIEF_SCALARS = (
    BeliefScalar("carriage_x", "carriage_x_mm", "half_width_mm"),
    BeliefScalar("carriage_y", "carriage_y_mm", "half_width_mm"),
    BeliefScalar("reading", "reading_V", "saturation_V"),
    BeliefScalar("reading_noise_units", "reading_V", "noise_std_V", factor=3.0, transform="tanh"),
    BeliefScalar("mean_offset_x", "mean_offset_x_mm", "half_width_mm", factor=2.0),
    BeliefScalar("mean_offset_y", "mean_offset_y_mm", "half_width_mm", factor=2.0),
    BeliefScalar("std_x", "std_x_mm", "half_width_mm"),
    BeliefScalar("std_y", "std_y_mm", "half_width_mm"),
    BeliefScalar("correlation", "correlation", None),
    BeliefScalar("spread", "spread_mm", "half_width_mm"),
    BeliefScalar("log_spread", "spread_mm", "success_spread_mm", transform="log10", floor=LOG_SPREAD_FLOOR_MM),
    BeliefScalar("observations", "n_observations", "max_observations"),
)
N_SCALARS = len(BELIEF_SCALARS)
#: (N_SCALARS,) float64 each entry's factor, in order: the compiled kernel's argument.
BELIEF_SCALAR_FACTORS = np.array([e.factor for e in BELIEF_SCALARS], dtype=np.float64)
BELIEF_SCALAR_FACTORS.flags.writeable = False


def belief_spread_mm(xp: Any, cov_mm2: Any) -> Any:
    """(…,) the belief's spread √trace Σ (mm; the paper's success measure, §5.4) of (…, 2, 2) covariances,
    mm² (a negative trace from rounding counts as 0).
    """
    return xp.sqrt(xp.clip(cov_mm2[..., 0, 0] + cov_mm2[..., 1, 1], 0.0, None))


def belief_quantities(
    xp: Any, carriage_mm: Any, reading_V: Any, mean_mm: Any, cov_mm2: Any, n_observations: Any
) -> dict[str, Any]:
    """The quantities of :data:`QUANTITY_NAMES`, each (k,), from k envs' carriages (k, 2) mm, readings (k,) V,
    belief means (k, 2) mm and covariances (k, 2, 2) mm², and readings fused (k,) (float).
    """
    c00, c11, c01 = cov_mm2[:, 0, 0], cov_mm2[:, 1, 1], cov_mm2[:, 0, 1]
    sx = xp.sqrt(xp.clip(c00, 0.0, None))
    sy = xp.sqrt(xp.clip(c11, 0.0, None))
    sxy = sx * sy
    floor = CORRELATION_FLOOR_MM2
    return {
        "carriage_x_mm": carriage_mm[:, 0],
        "carriage_y_mm": carriage_mm[:, 1],
        "reading_V": reading_V,
        "mean_offset_x_mm": mean_mm[:, 0] - carriage_mm[:, 0],
        "mean_offset_y_mm": mean_mm[:, 1] - carriage_mm[:, 1],
        "std_x_mm": sx,
        "std_y_mm": sy,
        "correlation": xp.where(sxy > floor, c01 / xp.clip(sxy, floor, None), 0.0),
        "spread_mm": belief_spread_mm(xp, cov_mm2),
        "n_observations": n_observations,
    }


def belief_scalar_values(
    xp: Any,
    quantities: Mapping[str, Any],
    scales: Mapping[str, Any],
    entries: tuple[BeliefScalar, ...] = BELIEF_SCALARS,
) -> Any:
    """(k, len(entries)) the declared ``entries`` (default :data:`BELIEF_SCALARS`) of the ``quantities`` (each
    (k,)) under the ``scales`` (:data:`SCALE_NAMES`; each (k,) or a number), clipped to [−1, 1], in the
    inputs' precision.
    """
    transforms = {"tanh": xp.tanh, "log10": xp.log10}
    cols = []
    for e in entries:
        v = quantities[e.quantity]
        if e.floor is not None:
            v = xp.clip(v, e.floor, None)
        if e.scale is not None:
            v = v / (e.factor * scales[e.scale])
        if e.transform != "identity":
            v = transforms[e.transform](v)
        cols.append(v)
    return xp.clip(xp.stack(cols, -1), -1.0, 1.0)


def belief_scalars(
    xp: Any,
    carriage_mm: Any,
    reading_V: Any,
    mean_mm: Any,
    cov_mm2: Any,
    n_observations: Any,
    max_observations: int,
    half_width_mm: Any,
    noise_std_V: Any,
    saturation_V: Any,
    success_spread_mm: float,
) -> Any:
    """(k, N_SCALARS) the belief observation's scalar entries of k envs (:func:`belief_quantities`' inputs;
    ``n_observations`` float), in the inputs' precision (the caller casts to float32).

    Args:
        xp: the arrays' namespace (numpy or torch).
        carriage_mm: (k, 2) the reference point (the carriage), mm.
        reading_V: (k,) last readings, V.
        mean_mm: (k, 2) belief means, mm.
        cov_mm2: (k, 2, 2) belief covariances, mm².
        n_observations: (k,) readings fused so far (float).
        max_observations: the cap.
        half_width_mm: (k,) the allowed half-width H, mm.
        noise_std_V: (k,) G·σ_s, V.
        saturation_V: (k,) the clip level, V.
        success_spread_mm: the success threshold on √trace Σ, mm.
    """
    quantities = belief_quantities(xp, carriage_mm, reading_V, mean_mm, cov_mm2, n_observations)
    scales = {
        "half_width_mm": half_width_mm,
        "saturation_V": saturation_V,
        "noise_std_V": noise_std_V,
        "success_spread_mm": success_spread_mm,
        "max_observations": max_observations,
    }
    return belief_scalar_values(xp, quantities, scales)


def belief_info_values(
    xp: Any, mean_mm: Any, cov_mm2: Any, truth_mm: Any, success_spread_mm: float
) -> tuple[Any, Any, Any]:
    """The info's belief entries of k envs: (``error_mm`` |mean − truth| (k,) mm, ``spread_mm`` √trace Σ (k,)
    mm, ``success`` spread ≤ ``success_spread_mm`` (k,) bool), from the belief means (k, 2) mm, covariances
    (k, 2, 2) mm² and what they estimate (k, 2) mm (the target; the global env's carriage).
    """
    d = mean_mm - truth_mm
    spread = belief_spread_mm(xp, cov_mm2)
    return xp.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]), spread, spread <= success_spread_mm
