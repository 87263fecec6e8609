"""What an agent believes about the sensor: mean and standard deviation of Φ for a target offset.

Two models (DESIGN §5):

* :class:`AnalyticSensorModel` — the noise-free reading of §3.3 (saturation included) and the
  amplifier noise ``G·σ_s``.
* :class:`CalibratedSensorModel` — what the paper did (§5.3): with the target placed, the carriage
  visits a 4 mm grid of positions (26×26 over 100 mm for the 12.7 mm spheres, 31×31 over 120 mm for
  the 38.1 mm ones; in general ``±allowed_half_width_mm``), takes 10 noisy readings per point and
  stores their average and variance. Off-grid values are bilinearly interpolated (identical to
  ``scipy.interpolate.RegularGridInterpolator(method="linear")``, tested, but ≈3× faster on a uniform
  grid); outside the grid the no-target mean (0 V) and standard deviation (G·σ_s) are used.

Offsets are always ``target − carriage centre`` in mm, shape (..., 2).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym._kernels import bilinear_coefficients, calibration_tables, log_f32
from electroloc_gym.conditions import Condition
from electroloc_gym.sensor import calibration_readings, expected_reading

__all__ = [
    "SensorModel",
    "AnalyticSensorModel",
    "CalibratedSensorModel",
    "make_sensor_model",
    "SENSOR_MODEL_NAMES",
    "gaussian_log_likelihood",
    "calibration_grid_mm",
]

SENSOR_MODEL_NAMES = ("analytic", "calibrated")


def gaussian_log_likelihood(reading_V: ArrayLike, mean_V: NDArray, std_V: ArrayLike) -> NDArray:
    """Log N(reading; mean, std²) up to the constant −½ log 2π (broadcasting).

    With a scalar std the −log σ term is the same for every particle and is dropped. A float32 std
    array's log is the compiled :func:`electroloc_gym._kernels.log32` (within 1 ulp), the one the
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


def calibration_grid_mm(half_span_mm: float, grid_step_mm: float) -> NDArray[np.float64]:
    """The calibration grid's coordinates per axis, mm: ``−H, −H + step, …`` up to ``+H`` (inclusive when
    ``2H`` is a multiple of the step).
    """
    n = int(np.floor(2 * half_span_mm / grid_step_mm + 1e-9)) + 1
    return -half_span_mm + grid_step_mm * np.arange(n)


@runtime_checkable
class SensorModel(Protocol):
    """The sensor-model accessor an agent may read: ``env.unwrapped.sensor_model``."""

    condition: Condition

    @property
    def name(self) -> str:
        """"analytic" or "calibrated"."""
        ...

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        """Expected reading and its standard deviation (V) for targets at ``offsets_mm`` (..., 2)."""
        ...

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        """Log p(reading | offsets) up to a constant; ``reading_V`` broadcasts against offsets[..., 0]."""
        ...


class AnalyticSensorModel:
    """Mean from the physics (§3.3, saturated), std = G·σ_s everywhere.

    Args:
        condition: the condition (amplifier noise; and the target, unless ``expected_fn`` is given).
        expected_fn: optional noise-free reading (V) of ``offsets_mm`` (..., 2); default the
            condition's single sphere, :func:`electroloc_gym.sensor.expected_reading`. A multi-object
            map passes its own (:func:`electroloc_gym.scene.make_map_sensor_model`).
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


class CalibratedSensorModel:
    """The paper's empirical sensor model: a grid of sample means and variances (§5.3).

    Args:
        condition: the condition to calibrate (the true target type; the target sits at the origin of
            the offset grid).
        seed: seed of the calibration readings; the same (condition, seed) gives the same model.
        grid_step_mm: grid pitch, mm (paper: 4 mm).
        samples_per_point: readings per grid point (paper: 10).
        half_span_mm: the grid covers offsets ±this, mm; default the condition's allowed box.
        min_std_fraction: floor on the calibrated std as a fraction of G·σ_s. Ten samples of a saturated
            reading have zero variance; a zero std would make the likelihood infinitely sharp, so the
            std is floored (default 0.25·G·σ_s, the 0.1 % quantile of a 10-sample std is ≈0.3·σ).
        reading_fn: optional noisy reading (V) at ``offsets_mm`` (..., 2) drawn from a Generator;
            default the condition's single sphere, :func:`electroloc_gym.sensor.calibration_readings`. A
            multi-object map passes its own (offsets = map origin − carriage).
        position_blur_mm: optional position uncertainty b, mm (default 0: off). The stored std
            becomes ``sqrt(std² + (|∇mean|·b)²)`` (gradient of the mean table, central differences):
            a particle then stands for a neighbourhood of radius ≈ b instead of a point, which keeps a
            sparse particle cloud from collapsing on a very steep map (used by the multi-object map,
            :mod:`electroloc_gym.scene`).
    """

    name = "calibrated"

    def __init__(self, condition: Condition, seed: int = 0, *, grid_step_mm: float = 4.0, samples_per_point: int = 10,
                 half_span_mm: float | None = None, min_std_fraction: float = 0.25,
                 reading_fn: Callable[[NDArray, np.random.Generator], NDArray] | None = None,
                 position_blur_mm: float = 0.0) -> None:
        if not grid_step_mm > 0:
            raise ValueError(f"grid_step_mm must be > 0, got {grid_step_mm!r}")
        if int(samples_per_point) < 2:
            raise ValueError(f"samples_per_point must be ≥ 2, got {samples_per_point!r}")
        self.condition = condition
        self.seed = int(seed)
        half = condition.allowed_half_width_mm if half_span_mm is None else float(half_span_mm)
        self.grid_mm = calibration_grid_mm(half, grid_step_mm)
        n = self.grid_mm.size
        self.grid_step_mm = float(grid_step_mm)
        self.noise_std_V = float(condition.noise_std_V)
        rng = np.random.default_rng(self.seed)
        gx, gy = np.meshgrid(self.grid_mm, self.grid_mm, indexing="ij")
        offs = np.stack([gx, gy], axis=-1)
        draw = functools.partial(calibration_readings, condition) if reading_fn is None else reading_fn
        samples = draw(np.broadcast_to(offs[None], (int(samples_per_point), n, n, 2)), rng)
        self.mean_table_V = np.empty((n, n))
        self.std_table_V = np.empty((n, n))
        calibration_tables(np.ascontiguousarray(samples, dtype=np.float64), min_std_fraction * self.noise_std_V,
                           self.mean_table_V, self.std_table_V)  # mean, floored std (ddof = 1) per point
        if not (np.isfinite(position_blur_mm) and position_blur_mm >= 0):
            raise ValueError(f"position_blur_mm must be a finite number ≥ 0, got {position_blur_mm!r}")
        self.position_blur_mm = float(position_blur_mm)
        if self.position_blur_mm > 0:
            gx, gy = np.gradient(self.mean_table_V, self.grid_step_mm)
            self.std_table_V = np.hypot(self.std_table_V, np.hypot(gx, gy) * self.position_blur_mm)
        self._coef = self._bilinear_coefficients()

    def _bilinear_coefficients(self) -> NDArray[np.float64]:
        """Per-cell coefficients (cells + 1, 8): mean and std as c0 + c1·tx + c2·ty + c3·tx·ty.

        The extra last row is the "outside the grid" cell: constant no-target mean 0 V and std G·σ_s.
        One row gather per particle then replaces four corner gathers and a mask (hot path).
        """
        n1 = self.grid_mm.size - 1
        coef = np.empty((n1 * n1 + 1, 8))
        bilinear_coefficients(self.mean_table_V, self.std_table_V, self.noise_std_V, coef)
        return coef

    @property
    def grid_shape(self) -> tuple[int, int]:
        """(n_x, n_y) grid points."""
        return (self.grid_mm.size, self.grid_mm.size)

    def mean_std(self, offsets_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        off = np.asarray(offsets_mm)
        dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.float64
        n1 = self.grid_mm.size - 1
        inv = dtype.type(1.0 / self.grid_step_mm)
        lo = dtype.type(self.grid_mm[0])
        fx = (off[..., 0] - lo) * inv
        fy = (off[..., 1] - lo) * inv
        inside = (fx >= 0) & (fx <= n1) & (fy >= 0) & (fy <= n1)
        ix = np.minimum(fx.astype(np.intp), n1 - 1)  # fx ≥ 0 where it matters; the top edge uses the last cell
        iy = np.minimum(fy.astype(np.intp), n1 - 1)
        tx = fx - ix.astype(dtype)
        ty = fy - iy.astype(dtype)
        cell = np.where(inside, ix * n1 + iy, n1 * n1)
        c = self._coef[cell].astype(dtype, copy=False)
        txy = tx * ty
        mean = c[..., 0] + c[..., 1] * tx + c[..., 2] * ty + c[..., 3] * txy
        std = c[..., 4] + c[..., 5] * tx + c[..., 6] * ty + c[..., 7] * txy
        return mean, std

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        mean, std = self.mean_std(offsets_mm)
        return gaussian_log_likelihood(reading_V, mean, std)


@functools.lru_cache(maxsize=64)
def _cached_calibration(condition: Condition, seed: int) -> CalibratedSensorModel:
    return CalibratedSensorModel(condition, seed)


def make_sensor_model(kind: str, condition: Condition, seed: int = 0) -> AnalyticSensorModel | CalibratedSensorModel:
    """Build (calibrated: cached per (condition, seed)) a sensor model by name."""
    if kind == "analytic":
        return AnalyticSensorModel(condition)
    if kind == "calibrated":
        return _cached_calibration(condition, int(seed))
    raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {kind!r}")
