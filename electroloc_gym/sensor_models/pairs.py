"""Sensor models of a K-pair array (:mod:`electroloc_gym.world.sensor_array`) and the likelihood of its readings.

Per pair a mean and a std of its reading, and the log-likelihood of the K readings of one step.

The pairs' noises are independent (each pair has its own amplifier input noise, §3.2), so
``log p(Φ_1..Φ_K | x) = Σ_k log p(Φ_k | x)``, summed in pair order (a fixed order: the same bits on every CPU).
With K = 1 the sum is the one term itself, so the ``"single"`` layout's likelihood is the one-pair model's, bit
for bit.

* :class:`ArrayAnalyticSensorModel` — each pair's noise-free reading from the physics
  (:func:`~electroloc_gym.world.sensor_array.array_reading`) and the amplifier noise G·σ_s.
* :class:`ArrayCalibratedSensorModel` — one calibration per pair, each a
  :class:`~electroloc_gym.sensor_models.CalibratedSensorModel` (same protocol, grid, statistics and bilinear
  lookup). The grid of pair k is laid over ``u = target − carriage − c_k`` (c_k the pair's centre): the
  calibration puts the carriage at ``target − c_k − u`` for every grid point u and records pair k. For a pair
  that is the paper's unit translated by c_k (``"single"``, ``"grid-2x2"``) that table *is* the paper's
  calibration (the same noise-free grid, cached), looked up at ``offsets − c_k``; for a pair in the carriage's
  shared field (``"line-4"``, ``"ring-8"``) its reading is not a translate of the paper's, so its own noisy
  readings fill the table (``reading_fn``; its noise-free grid, :func:`pair_noise_free_grid`, is cached per
  condition, pair and protocol). Centring the grid on the pair keeps its response, which falls off with the
  distance from the pair, inside the grid's ±2H. Pair 0 is calibrated with ``seed`` (so
  ``"single"`` is today's model bit for bit), pair k ≥ 1 with :func:`pair_seeds`' independent seeds.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels.fusion import sum_over_pairs
from electroloc_gym.sensor_models.calibrated import (
    DEFAULT_CALIBRATION,
    SENSOR_MODEL_NAMES,
    CalibratedSensorModel,
    CalibrationProtocol,
    calibration_grid_for,
    make_sensor_model,
)
from electroloc_gym.sensor_models.likelihood import gaussian_log_likelihood
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import add_calibration_noise
from electroloc_gym.world.sensor_array import SensorLayout, array_reading

__all__ = [
    "ArrayAnalyticSensorModel",
    "ArrayCalibratedSensorModel",
    "make_array_sensor_model",
    "pair_seeds",
    "pair_noise_free_grid",
]


def pair_seeds(seed: int, n_pairs: int) -> tuple[int, ...]:
    """Calibration seeds of K pairs: ``seed`` for pair 0, independent 63-bit seeds (``SeedSequence([seed, k])``)
    for pair k ≥ 1.
    """
    extra = [
        int(np.random.SeedSequence([int(seed), k]).generate_state(1, np.uint64)[0] >> np.uint64(1))
        for k in range(1, n_pairs)
    ]
    return (int(seed), *extra)


def _pair_readings(readings_V: ArrayLike, n_pairs: int) -> NDArray:
    r = np.asarray(readings_V)
    if r.ndim == 0 or r.shape[0] != n_pairs:
        raise ValueError(f"readings_V must hold one reading per pair (leading axis K = {n_pairs}), got shape {r.shape}")
    return r


class ArrayAnalyticSensorModel:
    """Every pair's mean from the physics (saturated at ±V_sat) and std G·σ_s.

    Args:
        condition: the condition (sphere, tank, amplifier).
        layout: the pairs.
    """

    name = "analytic"

    def __init__(self, condition: Condition, layout: SensorLayout) -> None:
        self.condition = condition
        self.sensor_layout = layout
        self.n_pairs = layout.n_pairs
        self.noise_std_V = float(condition.noise_std_V)
        array_reading(condition, layout, np.zeros(2))  # the layout must fit the condition's geometry
        self._pairs = tuple(layout.pair(k) for k in range(self.n_pairs))

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        """(K, ...) mean and std (V) of every pair's reading for targets at ``offsets_mm`` (..., 2)."""
        mean = array_reading(self.condition, self.sensor_layout, offsets_mm)
        return mean, np.full_like(mean, self.noise_std_V)

    def log_likelihood(self, readings_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Σ_k log N(Φ_k; mean_k, (G·σ_s)²) (...) up to a constant; ``readings_V`` (K,) or (K, ...) broadcasting."""
        r = _pair_readings(readings_V, self.n_pairs)
        mean = array_reading(self.condition, self.sensor_layout, offsets_mm)
        return sum_over_pairs([gaussian_log_likelihood(r[k], mean[k], self.noise_std_V) for k in range(self.n_pairs)])

    def pair_log_likelihood(self, k: int, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Log N(Φ_k; mean_k, (G·σ_s)²) (...) of pair k's reading alone (one-by-one fusion)."""
        mean = array_reading(self.condition, self._pairs[k], offsets_mm)[0]
        return gaussian_log_likelihood(reading_V, mean, self.noise_std_V)


class ArrayCalibratedSensorModel:
    """One :class:`~electroloc_gym.sensor_models.CalibratedSensorModel` per pair, its grid centred on the pair
    (module docstring).

    Args:
        condition: the condition to calibrate (the true target type).
        layout: the pairs.
        seed: calibration seed of pair 0 (:func:`pair_seeds` for the others).
        protocol: the calibration protocol, the same for every pair.
    """

    name = "calibrated"

    def __init__(
        self,
        condition: Condition,
        layout: SensorLayout,
        seed: int = 0,
        protocol: CalibrationProtocol = DEFAULT_CALIBRATION,
    ) -> None:
        self.condition = condition
        self.sensor_layout = layout
        self.n_pairs = layout.n_pairs
        self.seed = int(seed)
        self.protocol = protocol
        array_reading(condition, layout, np.zeros(2))  # the layout must fit the condition's geometry
        self.centres_mm = layout.centres_mm
        pairs = []
        for k, (unit, pair_seed) in enumerate(
            zip(layout.paper_unit_centres, pair_seeds(seed, self.n_pairs), strict=True)
        ):
            if unit is not None:  # the paper's unit, translated: the paper's calibration (cached per seed)
                pairs.append(make_sensor_model("calibrated", condition, pair_seed, protocol))
            else:
                pairs.append(CalibratedSensorModel(condition, pair_seed, protocol, reading_fn=self._reading_fn(k)))
        self.pairs: tuple[CalibratedSensorModel, ...] = tuple(pairs)

    def _reading_fn(self, k: int):
        """Pair k's calibration readings: its cached noise-free grid (:func:`pair_noise_free_grid`) plus noise from
        the quantile table, as :func:`~electroloc_gym.world.sensor.calibration_readings`.
        """
        mean = pair_noise_free_grid(self.condition, self.sensor_layout.pair(k), self.protocol)

        def reading(u: NDArray, rng: np.random.Generator) -> NDArray:
            if np.shape(u)[:-1] != mean.shape:
                raise ValueError(f"calibration offsets of shape {np.shape(u)} do not match the grid {mean.shape}")
            return add_calibration_noise(self.condition, mean, rng)

        return reading

    def _pair_offsets(self, offsets_mm: ArrayLike, k: int) -> NDArray:
        off = np.asarray(offsets_mm)
        if not np.any(self.centres_mm[k]):
            return off
        dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
        return off.astype(dtype, copy=False) - self.centres_mm[k].astype(dtype)

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        """(K, ...) mean and std (V) of every pair's reading from its table (bilinear)."""
        stats = [p.mean_std(self._pair_offsets(offsets_mm, k)) for k, p in enumerate(self.pairs)]
        return np.stack([m for m, _ in stats]), np.stack([s for _, s in stats])

    def log_likelihood(self, readings_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Σ_k log N(Φ_k; mean_k, std_k²) (...) (the −log std_k terms kept); ``readings_V`` (K,) or (K, ...)."""
        r = _pair_readings(readings_V, self.n_pairs)
        return sum_over_pairs([self.pair_log_likelihood(k, r[k], offsets_mm) for k in range(self.n_pairs)])

    def pair_log_likelihood(self, k: int, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Log N(Φ_k; mean_k, std_k²) (...) of pair k's reading alone, from its table (one-by-one fusion)."""
        return self.pairs[k].log_likelihood(reading_V, self._pair_offsets(offsets_mm, k))


@functools.lru_cache(maxsize=64)
def pair_noise_free_grid(
    condition: Condition, pair: SensorLayout, protocol: CalibrationProtocol = DEFAULT_CALIBRATION
) -> NDArray[np.float64]:
    """A one-pair layout's calibration readings without noise or clip, (samples, n, n), V, on the grid of
    ``protocol`` laid over ``u = target − carriage − centre`` (the same for every seed; cached, read-only).
    """
    grid = calibration_grid_for(condition, protocol)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    u = np.stack([gx, gy], axis=-1) + pair.centres_mm[0]
    mean = np.broadcast_to(
        array_reading(condition, pair, u, saturate=False)[0], (protocol.samples_per_point, grid.size, grid.size)
    ).copy()
    mean.flags.writeable = False
    return mean


def make_array_sensor_model(
    kind: str,
    condition: Condition,
    layout: SensorLayout,
    seed: int = 0,
    protocol: CalibrationProtocol = DEFAULT_CALIBRATION,
) -> ArrayAnalyticSensorModel | ArrayCalibratedSensorModel:
    """A K-pair sensor model by name, ``"analytic"`` or ``"calibrated"``."""
    if kind == "analytic":
        return ArrayAnalyticSensorModel(condition, layout)
    if kind == "calibrated":
        return ArrayCalibratedSensorModel(condition, layout, seed, protocol)
    raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {kind!r}")
