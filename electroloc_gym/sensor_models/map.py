"""The agent's sensor models of a pre-mapped tank (ElectroLocGlobal-v0, paper §6.5, Fig. 14).

The map models keep the sensor models' convention ``offsets = target − carriage`` with the **map
origin** as the target, i.e. ``offsets = −carriage`` (carriage position in the map frame).
:func:`make_map_sensor_model` builds the same :class:`~electroloc_gym.sensor_models.AnalyticSensorModel` /
:class:`~electroloc_gym.sensor_models.CalibratedSensorModel` (4 mm grid of carriage positions over the
allowed box, 10 noisy readings per point, bilinear interpolation, paper §5.3) as the single-target
env, fed by the scene's reading instead of one sphere's, plus a **position blur** (default
:data:`DEFAULT_POSITION_BLUR_MM` = 2 mm): the model's std becomes ``sqrt(std² + (|∇mean|·b)²)``.

Why the blur: the map is far steeper than a single sphere's EEV (median |∇Φ| ≈ 1.7 σ per mm, 90th
percentile ≈ 4 σ per mm) while 2500 particles over the ±80 mm box sit ≈ 3.2 mm apart, so with the
bare amplifier noise the likelihood band of a reading is much narrower than the particle spacing:
resampling keeps a handful of particles, none near the truth, and the filter "succeeds" at a wrong
place (random actions, calibrated model, 60 trials: b = 0: 11 of 58 successes more than 10 mm off;
b = 1 mm: 1 of 57; b = 2 mm: 0 of 57). b = 2 mm was chosen from that run, before any Table-2
comparison; it is of the order of the particle spacing and of the paper's per-step jitter (1 mm per
axis, √2 mm radial). Sensitivity (Table 2 protocol, 50 trials, calibrated; successes, mean/median
error mm, mean/median steps): b = 1: rnd-wlk 49, 1.9/0.9, 10.7/9; min-var 50, 3.4/1.0, 5.6/5.
b = 1.5: 49, 1.3/1.1, 12.3/10; 50, 2.4/1.4, 6.2/5. b = 2: 48, 1.4/1.1, 13.3/11; 50, 3.9/2.0,
6.4/5. b = 3: 47, 1.9/1.6, 14.6/14; 50, 3.7/2.4, 6.9/6. ``position_blur_mm=0`` gives the bare model.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.sensor_models.analytic import AnalyticSensorModel
from electroloc_gym.sensor_models.calibrated import (
    DEFAULT_CALIBRATION,
    SENSOR_MODEL_NAMES,
    CalibratedSensorModel,
    CalibrationProtocol,
)
from electroloc_gym.sensor_models.likelihood import gaussian_log_likelihood

if TYPE_CHECKING:
    from electroloc_gym.world.scene import Scene

__all__ = ["DEFAULT_POSITION_BLUR_MM", "MapAnalyticSensorModel", "make_map_sensor_model"]

#: Default position blur of the map's sensor models, mm (module docstring).
DEFAULT_POSITION_BLUR_MM = 2.0


def _blur(value: object) -> float:
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not np.isfinite(value)
        or value < 0
    ):
        raise ValueError(f"position_blur_mm must be a finite number ≥ 0, got {value!r}")
    return float(value)


class MapAnalyticSensorModel(AnalyticSensorModel):
    """The map's analytic model: the scene's noise-free reading, std ``sqrt((G·σ_s)² + (|∇Φ|·b)²)``.

    ``|∇Φ|`` (V/mm) by central differences of ±0.25 mm over carriage positions (4 extra map
    evaluations; ``position_blur_mm=0`` skips them and gives the bare std G·σ_s).

    Args:
        scene: the map.
        position_blur_mm: position blur b, mm (≥ 0).
    """

    _H_MM = 0.25

    def __init__(self, scene: Scene, position_blur_mm: float = DEFAULT_POSITION_BLUR_MM) -> None:
        super().__init__(scene.as_condition(), expected_fn=scene.expected_reading_at_offsets)
        self.scene = scene
        self.position_blur_mm = _blur(position_blur_mm)

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        off = np.asarray(offsets_mm)
        if off.dtype not in (np.float32, np.float64):
            off = off.astype(np.float64)
        mean = self._expected(off)
        if self.position_blur_mm == 0:
            return mean, np.full_like(mean, self.noise_std_V)
        h = off.dtype.type(self._H_MM)
        ex = np.array([h, 0], dtype=off.dtype)
        ey = np.array([0, h], dtype=off.dtype)
        gx = (self._expected(off + ex) - self._expected(off - ex)) / (2 * h)
        gy = (self._expected(off + ey) - self._expected(off - ey)) / (2 * h)
        b = off.dtype.type(self.position_blur_mm)
        s = off.dtype.type(self.noise_std_V)
        std = np.sqrt(s * s + (gx * gx + gy * gy) * (b * b))
        return mean, std

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        mean, std = self.mean_std(offsets_mm)
        return gaussian_log_likelihood(reading_V, mean, std)


@functools.lru_cache(maxsize=32)
def _cached_map_calibration(scene: Scene, seed: int, protocol: CalibrationProtocol) -> CalibratedSensorModel:
    return CalibratedSensorModel(scene.as_condition(), seed, protocol, reading_fn=scene.noisy_reading_at_offsets)


def make_map_sensor_model(
    kind: str,
    scene: Scene,
    seed: int = 0,
    position_blur_mm: float = DEFAULT_POSITION_BLUR_MM,
    protocol: CalibrationProtocol = DEFAULT_CALIBRATION,
) -> MapAnalyticSensorModel | CalibratedSensorModel:
    """The agent's model of the map's reading, ``offsets_mm = −carriage`` (map origin − carriage).

    ``"analytic"``: the scene's noise-free reading (:class:`MapAnalyticSensorModel`). ``"calibrated"``:
    the paper's procedure (§5.3) over carriage positions — ``protocol``'s grid over the allowed box
    (41×41 for ±80 mm at 4 mm), its readings per point, bilinear interpolation; seeded and cached per
    (scene, seed, protocol). Both widen the std by the position blur (module docstring), which
    replaces ``protocol.position_blur_mm``. The map's offsets are the carriage positions themselves, all
    inside the allowed box, so the grid always covers the allowed box (``grid_extent`` does not apply).
    """
    blur = _blur(position_blur_mm)
    if kind == "analytic":
        return MapAnalyticSensorModel(scene, blur)
    if kind == "calibrated":
        return _cached_map_calibration(
            scene, int(seed), protocol.replace(position_blur_mm=blur, grid_extent="allowed-box")
        )
    raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {kind!r}")
