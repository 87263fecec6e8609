"""Compiled (numba) loops of the simulation core, grouped by what they compute.

* :mod:`.mathf32` — float32 ``exp``/``log`` and fixed-order sums (the only non-exact steps);
* :mod:`.lookup` — the calibrated sensor model's table: statistics, coefficients, log-likelihood;
* :mod:`.filter` — the particle filter's measurement update (weights, resampling, jitter);
* :mod:`.moments` — the belief's mean, covariance and histogram;
* :mod:`.observation` — the belief observation's assembly;
* :mod:`.draws` — bulk transforms of random draws;
* :mod:`.fusion` — the fusion of a sensor array's K readings (imported by its users, not re-exported here).

Why compiled loops: at M = 2500 particles a numpy update is ~25 elementwise passes, each with its
own temporary; one kernel call takes one env at a time through a few passes over its particles
while they are in cache. Why they make results independent of the CPU and of the number of envs:
every kernel works one env at a time and uses only IEEE-exact operations (+ − × ÷, √, comparisons)
plus the fixed polynomials and summation orders of :mod:`.mathf32` (docs/design.md, "Results that do
not depend on the CPU"). Compiled on first use and cached on disk (a few seconds once per machine).
"""

from electroloc_gym.kernels.belief_rows import belief_observation_rows
from electroloc_gym.kernels.draws import box_affine, noisy_saturated
from electroloc_gym.kernels.filter import (
    calibrated_assimilate,
    calibrated_log_likelihood,
    jitter_resampled,
    loglik_assimilate,
    resample_indices,
)
from electroloc_gym.kernels.lookup import bilinear_coefficients, calibration_tables, pooled_calibration_tables
from electroloc_gym.kernels.mathf32 import exp32, exp_f32, log32, log_f32, row_sums
from electroloc_gym.kernels.moments import egocentric_counts, mean_cov_rows

__all__ = [
    "exp32",
    "log32",
    "exp_f32",
    "log_f32",
    "row_sums",
    "calibrated_assimilate",
    "loglik_assimilate",
    "calibrated_log_likelihood",
    "resample_indices",
    "jitter_resampled",
    "box_affine",
    "noisy_saturated",
    "mean_cov_rows",
    "egocentric_counts",
    "belief_observation_rows",
    "calibration_tables",
    "pooled_calibration_tables",
    "bilinear_coefficients",
]
