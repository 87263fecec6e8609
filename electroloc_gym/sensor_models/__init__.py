"""What an agent believes about the sensor: mean and standard deviation of Φ for a target offset.

* :class:`AnalyticSensorModel` — the noise-free reading of the physics (§3.1, saturation included) and
  the amplifier noise ``G·σ_s``.
* :class:`CalibratedSensorModel` — what the paper did (§5.3): a grid of sample means and spreads taken
  with the target in place, interpolated bilinearly (:class:`CalibrationProtocol` holds every choice).

Offsets are always ``target − carriage centre`` in mm, shape (..., 2).
"""

from electroloc_gym.sensor_models.analytic import AnalyticSensorModel
from electroloc_gym.sensor_models.calibrated import (
    DEFAULT_CALIBRATION,
    GRID_EXTENTS,
    PAPER_CALIBRATION,
    SENSOR_MODEL_NAMES,
    STD_ESTIMATORS,
    CalibratedSensorModel,
    CalibrationProtocol,
    calibration_coefficients,
    calibration_grid_for,
    calibration_grid_mm,
    calibration_statistics,
    coefficient_rows,
    fixed_coefficients,
    grid_points_bound,
    make_sensor_model,
    noise_free_calibration_grid,
)
from electroloc_gym.sensor_models.likelihood import SensorModel, gaussian_log_likelihood
from electroloc_gym.sensor_models.map import DEFAULT_POSITION_BLUR_MM, MapAnalyticSensorModel, make_map_sensor_model

__all__ = [
    "SensorModel",
    "gaussian_log_likelihood",
    "AnalyticSensorModel",
    "CalibratedSensorModel",
    "CalibrationProtocol",
    "DEFAULT_CALIBRATION",
    "PAPER_CALIBRATION",
    "GRID_EXTENTS",
    "SENSOR_MODEL_NAMES",
    "STD_ESTIMATORS",
    "calibration_coefficients",
    "calibration_grid_for",
    "calibration_grid_mm",
    "calibration_statistics",
    "make_sensor_model",
    "noise_free_calibration_grid",
    "coefficient_rows",
    "fixed_coefficients",
    "grid_points_bound",
    "DEFAULT_POSITION_BLUR_MM",
    "MapAnalyticSensorModel",
    "make_map_sensor_model",
]
