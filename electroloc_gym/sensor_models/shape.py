"""Sensor models of a sphere of unknown size and material (paper §7).

"The conductivity and diameter of the target could be two more dimensions in the search space" (§7).

A hypothesis is a target position and a shape: radius ``a`` (mm) and contrast ``χ`` (Eq. 4; +1 a
perfect conductor, −½ a perfect insulator). Both models give the mean and standard deviation (V) of
the reading for offsets ``target − carriage`` (..., 2) and a shape per offset (arrays broadcasting
against ``offsets[..., 0]``); the tank — water, amplifier, carriage geometry, signal scale — is the
condition's, whose own sphere is ignored.

* :class:`TheoreticalShapeModel` (``sensor_model="analytic"``): the theoretical EEV of §7, Eq. 4 for
  the hypothesis' sphere (strength ``χa³``, centre at depth ``a + E + O``), saturated at ±V_sat, with
  the amplifier noise ``G·σ_s``. It is the physics the tank itself runs, so it is exact.
* :class:`InterpolatedShapeModel` (``sensor_model="interpolated"``): what §7 proposes for sizes that were
  never calibrated — an EEV interpolated from calibrated EEVs (the paper's protocol, §5.3) of a steel
  and a Delrin sphere at a few known radii. The readings are linear in χa³ at a fixed depth, so each
  calibrated mean is divided by its sphere's strength; between two calibrated radii the per-strength
  means and the stds are interpolated linearly in the radius (the depth, which also changes with the
  radius, is what the interpolation approximates; outside the calibrated range the nearest radius is
  used), the mean is multiplied by the hypothesis' own ``χa³`` (the conductor's tables for χ ≥ 0, the
  insulator's for χ < 0) and saturated at ±V_sat.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.sensor_models.calibrated import (
    DEFAULT_CALIBRATION,
    CalibratedSensorModel,
    CalibrationProtocol,
    bilinear_cells,
    bilinear_mean_std,
)
from electroloc_gym.sensor_models.likelihood import gaussian_log_likelihood
from electroloc_gym.world import physics
from electroloc_gym.world.conditions import Condition, MATERIAL_CONDUCTIVITY_uScm, Target
from electroloc_gym.world.sensor import sphere_reading

__all__ = ["TheoreticalShapeModel", "InterpolatedShapeModel", "SHAPE_SENSOR_MODELS", "DEFAULT_EEV_RADII_MM"]

#: The unknown-target env's sensor models (the theoretical EEV first: the env's default).
SHAPE_SENSOR_MODELS = ("analytic", "interpolated")
#: The radii of the calibrated EEVs the interpolated model starts from, mm: every 2.5 mm over the default
#: radius range (the paper's 6.35 and 19.05 mm spheres are then sizes it has not seen). With only the
#: paper's two sizes the interpolation errs by up to 11 noise σ; with these, by at most 0.34 σ (RMS over
#: the grid, all eight tanks; the calibration's own noise is ≈ 0.3 σ).
DEFAULT_EEV_RADII_MM = (5.0, 7.5, 10.0, 12.5, 15.0, 17.5, 20.0)


class TheoreticalShapeModel:
    """The theoretical EEV of any sphere (module docstring); std ``G·σ_s`` everywhere.

    Args:
        condition: the tank (water, amplifier, geometry, signal scale).
    """

    name = "analytic"

    def __init__(self, condition: Condition) -> None:
        self.condition = condition
        self.noise_std_V = float(condition.noise_std_V)

    def mean_std(self, offsets_mm: ArrayLike, radius_mm: ArrayLike, chi: ArrayLike) -> tuple[NDArray, NDArray]:
        """Mean and std (V) of the reading of each hypothesis (offsets (..., 2), radius mm and χ (...))."""
        mean = sphere_reading(self.condition, offsets_mm, radius_mm, chi)
        return mean, np.full_like(mean, self.noise_std_V)

    def log_likelihood(
        self, reading_V: ArrayLike, offsets_mm: ArrayLike, radius_mm: ArrayLike, chi: ArrayLike
    ) -> NDArray:
        """Log p(reading | hypothesis) up to a constant (the −log σ term is the same for all and dropped)."""
        return gaussian_log_likelihood(
            reading_V, sphere_reading(self.condition, offsets_mm, radius_mm, chi), self.noise_std_V
        )


@functools.lru_cache(maxsize=64)
def _calibrated_eev(
    condition: Condition, radius_mm: float, material: str, seed: int, protocol: CalibrationProtocol
) -> CalibratedSensorModel:
    target = Target(radius_mm=radius_mm, conductivity_uScm=MATERIAL_CONDUCTIVITY_uScm[material], material=material)
    return CalibratedSensorModel(condition.replace(target=target), seed, protocol)


class InterpolatedShapeModel:
    """EEVs of unseen sizes interpolated from calibrated ones (module docstring).

    Every table shares the tank's calibration grid, so one cell lookup per hypothesis serves all of
    them; the coefficients are stacked (material, radius, cell, 8) with the means divided by each
    table's strength χ_ref·a_k³, and each hypothesis gathers the two rows of its bracketing radii.

    Args:
        condition: the tank.
        radii_mm: the calibrated radii (≥ 1, distinct, positive), mm.
        seed: seed of the calibrations (table k of material m, m = 0 steel, 1 Delrin, uses seed
            ``seed + 2k + m``).
        protocol: the calibration protocol of every table.
    """

    name = "interpolated"

    def __init__(
        self,
        condition: Condition,
        radii_mm: tuple[float, ...] = DEFAULT_EEV_RADII_MM,
        seed: int = 0,
        protocol: CalibrationProtocol = DEFAULT_CALIBRATION,
    ) -> None:
        self.condition = condition
        self.noise_std_V = float(condition.noise_std_V)
        self.radii_mm = np.array(sorted(float(r) for r in radii_mm))
        self.seed = int(seed)
        water = condition.water.conductivity_uScm
        materials = ("steel", "delrin")
        #: The calibrated spheres' contrasts χ (steel ≈ +1, Delrin ≈ −½).
        self.chi_ref = {
            m: float(physics.contrast_factor_sphere(MATERIAL_CONDUCTIVITY_uScm[m], water)) for m in materials
        }
        tables = [
            [
                _calibrated_eev(condition, float(r), m, self.seed + 2 * k + j, protocol)
                for k, r in enumerate(self.radii_mm)
            ]
            for j, m in enumerate(materials)
        ]
        self.grid_mm, self.grid_step_mm = tables[0][0].grid_mm, tables[0][0].grid_step_mm
        coef = np.stack([np.stack([t._coef for t in row]) for row in tables])  # (2, K, cells + 1, 8)
        strength = np.array([[self.chi_ref[m] * r * r * r for r in self.radii_mm] for m in materials])
        coef[..., :4] /= strength[:, :, None, None]
        self._coef = coef

    def mean_std(self, offsets_mm: ArrayLike, radius_mm: ArrayLike, chi: ArrayLike) -> tuple[NDArray, NDArray]:
        """Mean and std (V) of the reading of each hypothesis (offsets (..., 2), radius mm and χ (...))."""
        cell, tx, ty = bilinear_cells(offsets_mm, self.grid_mm, self.grid_step_mm)
        dtype = tx.dtype
        shape = np.broadcast_shapes(cell.shape, np.shape(radius_mm), np.shape(chi))
        a = np.broadcast_to(np.asarray(radius_mm, dtype=dtype), shape)
        x = np.broadcast_to(np.asarray(chi, dtype=dtype), shape)
        cell, tx, ty = (np.broadcast_to(v, shape) for v in (cell, tx, ty))
        r = self.radii_mm
        if r.size == 1:
            j, t = np.zeros(shape, dtype=np.intp), np.zeros(shape, dtype=dtype)
            j1 = j
        else:
            j = np.clip(np.searchsorted(r, a, side="right") - 1, 0, r.size - 2)
            j1 = j + 1
            lo, hi = r[j].astype(dtype), r[j1].astype(dtype)
            t = np.clip((a - lo) / (hi - lo), dtype.type(0.0), dtype.type(1.0))
        mat = (x < 0).astype(np.intp)  # 0: the conductor's tables, 1: the insulator's
        m0, s0 = bilinear_mean_std(self._coef[mat, j, cell].astype(dtype, copy=False), tx, ty)
        m1, s1 = bilinear_mean_std(self._coef[mat, j1, cell].astype(dtype, copy=False), tx, ty)
        one = dtype.type(1.0)
        mean = ((one - t) * m0 + t * m1) * (x * (a * a * a))
        sat = dtype.type(self.condition.saturation_V)
        return np.clip(mean, -sat, sat), (one - t) * s0 + t * s1

    def log_likelihood(
        self, reading_V: ArrayLike, offsets_mm: ArrayLike, radius_mm: ArrayLike, chi: ArrayLike
    ) -> NDArray:
        """Log p(reading | hypothesis) up to a constant."""
        mean, std = self.mean_std(offsets_mm, radius_mm, chi)
        return gaussian_log_likelihood(reading_V, mean, std)
