"""The apparatus of one experimental condition, as frozen, validated dataclasses.

The target sphere, the water, the amplifier and the carriage geometry (units in every field name: mm, V,
mV, µS/cm).

:class:`electroloc_gym.world.conditions.Condition` combines them with the workspace and the signal scale.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from electroloc_gym.utils.checks import check_float

__all__ = ["MATERIAL_CONDUCTIVITY_uScm", "Target", "Water", "Amplifier", "Geometry", "as_floats", "from_dict"]

#: Conductivities (µS/cm) of the paper's target materials. Steel ≈ 1.4·10⁶ S/m; Delrin (acetal) is
#: an insulator (≈10⁻¹³ S/m). Only the contrast χ matters, which is +1 and −½ to many digits.
MATERIAL_CONDUCTIVITY_uScm: dict[str, float] = {"steel": 1.4e10, "delrin": 1e-9}


def as_floats(obj: Any, *names: str) -> None:
    """Store the (checked) numeric fields ``names`` of a frozen dataclass as Python floats (numpy scalars in)."""
    for n in names:
        object.__setattr__(obj, n, float(getattr(obj, n)))


def from_dict(cls: type, data: Mapping[str, Any]) -> Any:
    """``cls(**data)`` for a dataclass, refusing unknown and missing fields by name."""
    fields = dataclasses.fields(cls)
    names = {f.name for f in fields}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"unknown {cls.__name__} field(s) {unknown}; allowed: {sorted(names)}")
    missing = sorted(
        f.name
        for f in fields
        if f.name not in data and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    )
    if missing:
        raise ValueError(f"missing {cls.__name__} field(s) {missing}; required: {sorted(f.name for f in fields)}")
    return cls(**data)


@dataclass(frozen=True)
class Target:
    """A spherical target.

    Attributes:
        radius_mm: sphere radius A, mm (> 0).
        conductivity_uScm: target conductivity σ_t, µS/cm (≥ 0).
        material: a label ("steel", "delrin" or "custom").
    """

    radius_mm: float
    conductivity_uScm: float
    material: str = "custom"

    def __post_init__(self) -> None:
        check_float("radius_mm", self.radius_mm, low=0.0)
        check_float("conductivity_uScm", self.conductivity_uScm, low=0.0, inclusive=True)
        as_floats(self, "radius_mm", "conductivity_uScm")

    @classmethod
    def sphere(cls, diameter_mm: float, material: str) -> Target:
        """A sphere of a named material ("steel" or "delrin")."""
        key = material.lower()
        if key not in MATERIAL_CONDUCTIVITY_uScm:
            raise ValueError(f"material must be one of {sorted(MATERIAL_CONDUCTIVITY_uScm)}, got {material!r}")
        check_float("diameter_mm", diameter_mm, low=0.0)
        return cls(radius_mm=diameter_mm / 2.0, conductivity_uScm=MATERIAL_CONDUCTIVITY_uScm[key], material=key)

    @property
    def diameter_mm(self) -> float:
        """Sphere diameter, mm."""
        return 2.0 * self.radius_mm


@dataclass(frozen=True)
class Water:
    """The tank's water. Attributes: conductivity_uScm, µS/cm (> 0)."""

    conductivity_uScm: float

    def __post_init__(self) -> None:
        check_float("water conductivity_uScm", self.conductivity_uScm, low=0.0)
        as_floats(self, "conductivity_uScm")


@dataclass(frozen=True)
class Amplifier:
    """Differential amplifier and noise.

    Attributes:
        gain: differential gain G (dimensionless, > 0).
        noise_rms_mV: RMS noise σ_s referred to the electrodes, mV (> 0), as measured in the paper's
            unshielded tank (Table 3).
        saturation_V: the data-acquisition card clips the amplified reading at ±saturation_V, V.
        noise_factor: dimensionless multiplier (> 0) on σ_s, default 1 (the paper's tank). §7 reports
            that shielding the tank cuts the ambient noise by more than 32×: ``noise_factor=1/32``.
            It applies wherever the noise enters: the readings, the calibration, the sensor models'
            likelihoods and the detection distance (:attr:`effective_noise_rms_mV`).
        output_noise_mV: RMS noise added after the amplifier (the data-acquisition card's own), mV (≥ 0),
            which does not scale with the gain; default 0: the paper refers all its noise to the
            electrodes (§6.1: "divide σ_nt by G"). It is what makes the gain matter beyond saturation
            (dynamic gain, §7; docs/extensions.md).
    """

    gain: float
    noise_rms_mV: float
    saturation_V: float = 10.0
    noise_factor: float = 1.0
    output_noise_mV: float = 0.0

    def __post_init__(self) -> None:
        check_float("gain", self.gain, low=0.0)
        check_float("noise_rms_mV", self.noise_rms_mV, low=0.0)
        check_float("saturation_V", self.saturation_V, low=0.0)
        check_float("noise_factor", self.noise_factor, low=0.0)
        check_float("output_noise_mV", self.output_noise_mV, low=0.0, inclusive=True)
        as_floats(self, "gain", "noise_rms_mV", "saturation_V", "noise_factor", "output_noise_mV")

    @property
    def effective_noise_rms_mV(self) -> float:
        """RMS noise referred to the electrodes, mV: σ_s·noise_factor, with the output noise referred back
        through the gain (√((σ_s·f)² + (σ_out/G)²)) when there is one.
        """
        if self.output_noise_mV == 0.0:
            return self.noise_rms_mV * self.noise_factor
        return float(np.hypot(self.noise_rms_mV * self.noise_factor, self.output_noise_mV / self.gain))

    @property
    def noise_std_V(self) -> float:
        """Standard deviation of the amplified reading, V: G·σ_s·noise_factor (⊕ the output noise)."""
        if self.output_noise_mV == 0.0:
            return self.gain * self.effective_noise_rms_mV * 1e-3
        return float(np.hypot(self.gain * self.noise_rms_mV * self.noise_factor, self.output_noise_mV)) * 1e-3

    def with_gain(self, gain: float) -> Amplifier:
        """The same amplifier at another gain G (> 0): signal and input noise scale, saturation and the
        output noise do not.
        """
        return dataclasses.replace(self, gain=gain)


@dataclass(frozen=True)
class Geometry:
    """Carriage geometry and emitter drive (paper §6.7, Appendix A; docs/design.md).

    Attributes:
        spacing_mm: emitter spacing L = sensor spacing, mm.
        electrode_radius_mm: electrode radius E, mm.
        emitter_voltage_V: emitter drive V_e, V.
        clearance_mm: gap O between the electrodes and the top of the target, mm.
    """

    spacing_mm: float = 50.0
    electrode_radius_mm: float = 1.0
    emitter_voltage_V: float = 2.0
    clearance_mm: float = 2.0

    def __post_init__(self) -> None:
        check_float("spacing_mm", self.spacing_mm, low=0.0)
        check_float("electrode_radius_mm", self.electrode_radius_mm, low=0.0)
        check_float("emitter_voltage_V", self.emitter_voltage_V, low=0.0)
        check_float("clearance_mm", self.clearance_mm, low=0.0, inclusive=True)
        as_floats(self, "spacing_mm", "electrode_radius_mm", "emitter_voltage_V", "clearance_mm")
