"""The calibrated sensor model: what the paper's robot knew about its sensor (§5.3).

With the target placed, the carriage visits a square grid of positions (paper: 4 mm pitch, 26×26 over
100 mm for the 12.7 mm spheres, 31×31 over 120 mm for the 38.1 mm ones), takes ten noisy readings per
point and stores their average and spread. Off-grid values are bilinearly interpolated (identical to
``scipy.interpolate.RegularGridInterpolator(method="linear")``, tested, but ≈3× faster on a uniform
grid); outside the grid the no-target mean (0 V) and standard deviation (G·σ_s) are used.

Every choice of that protocol lives in one frozen :class:`CalibrationProtocol`; the single env, the
vector env and the multi-object map all build their tables through :func:`calibration_statistics`
(and, for one sphere, :func:`calibration_coefficients`), so the statistics exist once.

Offsets are always ``target − carriage centre`` in mm, shape (..., 2).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels import bilinear_coefficients, calibration_tables, pooled_calibration_tables
from electroloc_gym.sensor_models.analytic import AnalyticSensorModel
from electroloc_gym.sensor_models.likelihood import gaussian_log_likelihood
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import add_calibration_noise, expected_reading

__all__ = [
    "CalibrationProtocol",
    "DEFAULT_CALIBRATION",
    "PAPER_CALIBRATION",
    "CalibratedSensorModel",
    "make_sensor_model",
    "SENSOR_MODEL_NAMES",
    "STD_ESTIMATORS",
    "GRID_EXTENTS",
    "calibration_grid_mm",
    "calibration_grid_for",
    "calibration_statistics",
    "calibration_coefficients",
    "noise_free_calibration_grid",
    "coefficient_rows",
    "fixed_coefficients",
    "grid_points_bound",
]

#: The sensor models of a target's (or a map's) x–y position: the paper's calibrated model first (the envs'
#: default), then the analytic one.
SENSOR_MODEL_NAMES = ("calibrated", "analytic")

#: Which offsets the calibration grid covers.
GRID_EXTENTS = ("allowed-box", "all-offsets")

#: How the calibration turns a grid point's readings into the model's standard deviation.
STD_ESTIMATORS = ("per-point", "pooled")


@dataclass(frozen=True)
class CalibrationProtocol:
    """How the calibration is taken and summarised (paper §5.3).

    Attributes:
        grid_step_mm: grid pitch, mm (paper: 4 mm).
        samples_per_point: readings per grid point (paper: 10).
        grid_extent: the offsets the grid covers when ``half_span_mm`` is None: ``"allowed-box"``, ±the
            condition's allowed half width (the paper's 100 mm / 120 mm squares; offsets beyond it read
            as "no target"), or ``"all-offsets"``, ±twice it (every offset a particle in the allowed box
            can have from a carriage in it, so no hypothesis gets the false "no target" prediction).
        half_span_mm: the grid covers offsets ±this, mm (overrides ``grid_extent``).
        std_estimator: ``"per-point"``: each point's own sample std (ddof = 1, floored);
            ``"pooled"``: one std, the root of the mean sample variance over the points none of whose
            readings saturated (the amplifier noise is the same everywhere), and the per-point std
            (floored) at points with a saturated reading.
        min_std_fraction: floor of the std as a fraction of G·σ_s. Ten samples of a saturated reading
            have zero variance; a zero std would make the likelihood infinitely sharp (default 0.25:
            the 0.1 % quantile of a 10-sample std is ≈0.3·σ).
        position_blur_mm: position uncertainty b, mm (0: off). The std becomes
            ``sqrt(std² + (|∇mean|·b)²)`` (central differences of the mean table): a particle stands for
            a neighbourhood of radius ≈ b, which keeps a sparse cloud from collapsing on a very steep
            map (the multi-object map, :mod:`electroloc_gym.world.scene`).
    """

    grid_step_mm: float = 4.0
    samples_per_point: int = 10
    grid_extent: str = "all-offsets"
    half_span_mm: float | None = None
    std_estimator: str = "pooled"
    min_std_fraction: float = 0.25
    position_blur_mm: float = 0.0

    def __post_init__(self) -> None:
        def number(name: str, value: object, low: float, inclusive: bool) -> float:
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.integer, np.floating))
                or not math.isfinite(value)
                or value < low
                or (value == low and not inclusive)
            ):
                raise ValueError(f"{name} must be a finite number {'≥' if inclusive else '>'} {low}, got {value!r}")
            return float(value)

        object.__setattr__(self, "grid_step_mm", number("grid_step_mm", self.grid_step_mm, 0.0, False))
        s = self.samples_per_point
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 2 or s > 10_000:
            raise ValueError(f"samples_per_point must be an integer in [2, 10000], got {s!r}")
        object.__setattr__(self, "samples_per_point", int(s))
        if self.grid_extent not in GRID_EXTENTS:
            raise ValueError(f"grid_extent must be one of {list(GRID_EXTENTS)}, got {self.grid_extent!r}")
        if self.half_span_mm is not None:
            object.__setattr__(self, "half_span_mm", number("half_span_mm", self.half_span_mm, 0.0, False))
        if self.std_estimator not in STD_ESTIMATORS:
            raise ValueError(f"std_estimator must be one of {list(STD_ESTIMATORS)}, got {self.std_estimator!r}")
        object.__setattr__(self, "min_std_fraction", number("min_std_fraction", self.min_std_fraction, 0.0, False))
        object.__setattr__(self, "position_blur_mm", number("position_blur_mm", self.position_blur_mm, 0.0, True))

    def replace(self, **changes: object) -> CalibrationProtocol:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


#: The protocol every single-target env uses unless told otherwise: the paper's grid pitch and ten
#: readings per point, over every offset, with the pooled std (docs/fidelity.md says why).
DEFAULT_CALIBRATION = CalibrationProtocol()
#: The paper's protocol taken literally (§5.3): its 100 mm / 120 mm squares and each point's own sample std.
PAPER_CALIBRATION = CalibrationProtocol(grid_extent="allowed-box", std_estimator="per-point")


def calibration_grid_mm(half_span_mm: float, grid_step_mm: float) -> NDArray[np.float64]:
    """The calibration grid's coordinates per axis, mm: ``−H, −H + step, …`` up to ``+H`` (inclusive when
    ``2H`` is a multiple of the step).
    """
    n = int(np.floor(2 * half_span_mm / grid_step_mm + 1e-9)) + 1
    return cast("NDArray[np.float64]", -half_span_mm + grid_step_mm * np.arange(n))  # float × int64: float64


def calibration_grid_for(
    condition: Condition, protocol: CalibrationProtocol = DEFAULT_CALIBRATION
) -> NDArray[np.float64]:
    """The grid coordinates per axis (mm) that ``protocol`` visits for ``condition``."""
    if protocol.half_span_mm is not None:
        half = protocol.half_span_mm
    else:
        half = condition.allowed_half_width_mm * (2.0 if protocol.grid_extent == "all-offsets" else 1.0)
    return calibration_grid_mm(half, protocol.grid_step_mm)


def bilinear_cells(
    offsets_mm: ArrayLike, grid_mm: NDArray[np.float64], grid_step_mm: float
) -> tuple[NDArray[np.intp], NDArray, NDArray]:
    """(cell, tx, ty) of offsets (..., 2) on a calibration grid: the coefficient row (the extra last
    row ``n1²`` outside the grid) and the fractional position in the cell, in the offsets' precision.
    """
    off = np.asarray(offsets_mm)
    dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    n1 = grid_mm.size - 1
    inv = dtype.type(1.0 / grid_step_mm)
    lo = dtype.type(grid_mm[0])
    fx = (off[..., 0] - lo) * inv
    fy = (off[..., 1] - lo) * inv
    inside = (fx >= 0) & (fx <= n1) & (fy >= 0) & (fy <= n1)
    ix = np.minimum(fx.astype(np.intp), n1 - 1)  # fx ≥ 0 where it matters; the top edge uses the last cell
    iy = np.minimum(fy.astype(np.intp), n1 - 1)
    return np.where(inside, ix * n1 + iy, n1 * n1), fx - ix.astype(dtype), fy - iy.astype(dtype)


def bilinear_mean_std(c: NDArray, tx: NDArray, ty: NDArray) -> tuple[NDArray, NDArray]:
    """Mean and std from gathered coefficient rows ``c`` (..., 8): c0 + c1·tx + c2·ty + c3·tx·ty each."""
    txy = tx * ty
    mean = c[..., 0] + c[..., 1] * tx + c[..., 2] * ty + c[..., 3] * txy
    std = c[..., 4] + c[..., 5] * tx + c[..., 6] * ty + c[..., 7] * txy
    return mean, std


def _grid_offsets(grid_mm: NDArray[np.float64], samples: int) -> NDArray[np.float64]:
    """The (samples, n, n, 2) offsets of a calibration, every grid point repeated ``samples`` times."""
    gx, gy = np.meshgrid(grid_mm, grid_mm, indexing="ij")
    offs = np.stack([gx, gy], axis=-1)
    return np.broadcast_to(offs[None], (samples, grid_mm.size, grid_mm.size, 2))


@functools.lru_cache(maxsize=32)
def noise_free_calibration_grid(
    condition: Condition, protocol: CalibrationProtocol = DEFAULT_CALIBRATION
) -> NDArray[np.float64]:
    """The calibration's noise-free, unsaturated readings (samples, n, n), V — the same for every seed."""
    grid = calibration_grid_for(condition, protocol)
    offs = np.asarray(_grid_offsets(grid, protocol.samples_per_point), dtype=np.float64)
    mean = expected_reading(condition, offs, saturate=False)
    mean.flags.writeable = False
    return mean


def calibration_statistics(
    samples_V: NDArray, protocol: CalibrationProtocol, noise_std_V: float, saturation_V: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The model's mean and std tables (n, n), V, from the readings ``samples_V`` (samples, n, n).

    The one place where the calibration's statistics are computed (see :class:`CalibrationProtocol`).
    """
    samples = np.ascontiguousarray(samples_V, dtype=np.float64)
    n = samples.shape[-1]
    mean = np.empty((n, n))
    std = np.empty((n, n))
    floor = protocol.min_std_fraction * noise_std_V
    if protocol.std_estimator == "pooled":
        pooled_calibration_tables(samples, floor, float(saturation_V), mean, std)  # one pass, fixed order
    else:
        calibration_tables(samples, floor, mean, std)  # mean, floored std (ddof = 1) per point
    if protocol.position_blur_mm > 0:
        gx, gy = np.gradient(mean, protocol.grid_step_mm)
        std = np.hypot(std, np.hypot(gx, gy) * protocol.position_blur_mm)
    return mean, std


def calibration_coefficients(
    condition: Condition, seed: int, protocol: CalibrationProtocol = DEFAULT_CALIBRATION, out: NDArray | None = None
) -> NDArray:
    """``CalibratedSensorModel(condition, seed, protocol)._coef`` without building the model (tested equal).

    The per-cell bilinear coefficients (n1² + 1, 8) — the only part of the model a batched lookup needs
    (a new calibration per episode): the same draws (:func:`~electroloc_gym.world.sensor.add_calibration_noise`
    from ``default_rng(seed)``) on the cached noise-free grid, the same :func:`calibration_statistics`.
    ``out`` (float32 or float64) receives the values cast as ``astype`` would.
    """
    mean = noise_free_calibration_grid(condition, protocol)
    samples = add_calibration_noise(condition, mean, np.random.default_rng(int(seed)))
    tables = calibration_statistics(samples, protocol, float(condition.noise_std_V), float(condition.saturation_V))
    n = mean.shape[-1]
    if out is None:
        out = np.empty(((n - 1) ** 2 + 1, 8))
    bilinear_coefficients(tables[0], tables[1], float(condition.noise_std_V), out)
    return out


class CalibratedSensorModel:
    """The paper's empirical sensor model: a grid of sample means and spreads (§5.3).

    Args:
        condition: the condition to calibrate (the true target type; the target sits at the origin of
            the offset grid).
        seed: seed of the calibration readings; the same (condition, seed, protocol) gives the same model.
        protocol: how the calibration is taken and summarised (:class:`CalibrationProtocol`).
        reading_fn: optional noisy reading (V) at ``offsets_mm`` (..., 2) drawn from a Generator;
            default the condition's single sphere (the noise-free grid is then cached per condition).
            A multi-object map passes its own (offsets = map origin − carriage).
    """

    name = "calibrated"

    def __init__(
        self,
        condition: Condition,
        seed: int = 0,
        protocol: CalibrationProtocol = DEFAULT_CALIBRATION,
        *,
        reading_fn: Callable[[NDArray, np.random.Generator], NDArray] | None = None,
    ) -> None:
        if not isinstance(protocol, CalibrationProtocol):
            raise TypeError(f"protocol must be a CalibrationProtocol, got {type(protocol).__name__}")
        self.condition = condition
        self.seed = int(seed)
        self.protocol = protocol
        self.grid_mm = calibration_grid_for(condition, protocol)
        self.grid_step_mm = protocol.grid_step_mm
        self.noise_std_V = float(condition.noise_std_V)
        rng = np.random.default_rng(self.seed)
        if reading_fn is None:
            samples = add_calibration_noise(condition, noise_free_calibration_grid(condition, protocol), rng)
        else:
            samples = reading_fn(_grid_offsets(self.grid_mm, protocol.samples_per_point), rng)
        self.mean_table_V, self.std_table_V = calibration_statistics(
            samples, protocol, self.noise_std_V, float(condition.saturation_V)
        )
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
        cell, tx, ty = bilinear_cells(offsets_mm, self.grid_mm, self.grid_step_mm)
        return bilinear_mean_std(self._coef[cell].astype(tx.dtype, copy=False), tx, ty)

    def log_likelihood(self, reading_V: ArrayLike, offsets_mm: ArrayLike) -> NDArray:
        mean, std = self.mean_std(offsets_mm)
        return gaussian_log_likelihood(reading_V, mean, std)


def coefficient_rows(grid_mm: NDArray[np.float64]) -> int:
    """Coefficient rows of a calibration grid's bilinear table (its cells plus one, the outside row)."""
    return (grid_mm.size - 1) ** 2 + 1


@functools.lru_cache(maxsize=64)
def fixed_coefficients(condition: Condition, seed: int, protocol: CalibrationProtocol) -> NDArray[np.float32]:
    """The (read-only) float32 bilinear coefficients of a fixed calibration seed (cached; both engines'
    table of ``calibration_seed``).
    """
    n = coefficient_rows(calibration_grid_for(condition, protocol))
    coef = calibration_coefficients(condition, seed, protocol, out=np.empty((n, 8), dtype=np.float32))
    coef.flags.writeable = False
    return coef


def grid_points_bound(protocol: CalibrationProtocol, allowed_half_width_mm: float) -> int:
    """An upper bound of a calibration grid's points per axis, computed without building the grid (any
    ``grid_extent`` covers at most twice the allowed box; the engines' memory checks).
    """
    half = 2.0 * allowed_half_width_mm if protocol.half_span_mm is None else protocol.half_span_mm
    return int(min(2.0 * half / protocol.grid_step_mm, 2.0**62)) + 2


@functools.lru_cache(maxsize=64)
def _cached_calibration(condition: Condition, seed: int, protocol: CalibrationProtocol) -> CalibratedSensorModel:
    return CalibratedSensorModel(condition, seed, protocol)


SensorModelType = AnalyticSensorModel | CalibratedSensorModel


def make_sensor_model(
    kind: str, condition: Condition, seed: int = 0, protocol: CalibrationProtocol = DEFAULT_CALIBRATION
) -> SensorModelType:
    """Build (calibrated: cached per (condition, seed, protocol)) a sensor model by name."""
    if kind == "analytic":
        return AnalyticSensorModel(condition)
    if kind == "calibrated":
        return _cached_calibration(condition, int(seed), protocol)
    raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {kind!r}")
