"""The analytic sensor model: the noise-free reading of the physics and the amplifier noise (paper §2.2, §3.2)."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.sensor_models.likelihood import gaussian_log_likelihood
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import expected_reading

__all__ = ["AnalyticSensorModel"]


class AnalyticSensorModel:
    """Mean from the physics (Eq. 4, saturated at ±10 V, §6.1), std = G·σ_s everywhere.

    Args:
        condition: the condition (amplifier noise; and the target, unless ``expected_fn`` is given).
        expected_fn: optional noise-free reading (V) of ``offsets_mm`` (..., 2); default the
            condition's single sphere, :func:`electroloc_gym.world.sensor.expected_reading`. A multi-object
            map passes its own (:func:`electroloc_gym.world.scene.make_map_sensor_model`).
    """

    name = "analytic"

    def __init__(self, condition: Condition, expected_fn: Callable[[ArrayLike], NDArray] | None = None) -> None:
        self.condition = condition
        self.noise_std_V = float(condition.noise_std_V)
        self._expected = functools.partial(expected_reading, condition) if expected_fn is None else expected_fn

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        mean = self._expected(offsets_mm)
        return mean, np.full_like(mean, self.noise_std_V)

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        # Constant std: the −log σ term is the same for every particle and is dropped.
        return gaussian_log_likelihood(reading_V, self._expected(offsets_mm), self.noise_std_V)
