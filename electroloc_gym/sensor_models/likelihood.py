"""The sensor-model protocol and the Gaussian log-likelihood shared by every sensor model (paper §3.2, §4.1).

An agent's sensor model gives the mean and standard deviation (V) of the reading Φ for a target at
``offsets_mm = target − carriage centre`` (..., 2), mm.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels import log_f32
from electroloc_gym.world.conditions import Condition

__all__ = ["SensorModel", "gaussian_log_likelihood"]


def gaussian_log_likelihood(reading_V: ArrayLike, mean_V: NDArray, std_V: ArrayLike) -> NDArray:
    """Log N(reading; mean, std²) up to the constant −½ log 2π (broadcasting).

    With a scalar std the −log σ term is the same for every particle and is dropped. A float32 std
    array's log is the compiled :func:`electroloc_gym.kernels.log32` (within 1 ulp), the one the
    native vector env uses, so that both envs compute the same bits on every CPU.
    """
    z = (np.asarray(reading_V, dtype=mean_V.dtype) - mean_V) / std_V
    out = -0.5 * z * z
    if np.ndim(std_V) > 0:
        std = np.asarray(std_V)
        if std.dtype == np.float32 and out.dtype == np.float32 and std.shape == out.shape:
            log_std = np.empty(std.size, dtype=np.float32)
            log_f32(np.ascontiguousarray(std).reshape(-1), log_std)
            out -= log_std.reshape(std.shape)
        else:
            out -= np.log(std)
    return out


@runtime_checkable
class SensorModel(Protocol):
    """The sensor-model accessor an agent may read: ``env.unwrapped.sensor_model``."""

    condition: Condition

    @property
    def name(self) -> str:
        """The model's name: "analytic" or "calibrated"."""
        ...

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        """Expected reading and its standard deviation (V) for targets at ``offsets_mm`` (..., 2)."""
        ...

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Log p(reading | offsets) up to a constant; ``reading_V`` broadcasts against offsets[..., 0]."""
        ...
