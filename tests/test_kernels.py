"""The compiled kernels (electroloc_gym._kernels) against the numpy expressions they stand for."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from electroloc_gym import _kernels as K
from electroloc_gym.belief import normal_table, table_standard_normal, weighted_mean_cov
from electroloc_gym.conditions import get_condition
from electroloc_gym.envs.observation import HIST_BINS, _egocentric_histogram
from electroloc_gym.sensor_models import CalibratedSensorModel


def test_normal_table_is_a_unit_normal() -> None:
    t = normal_table()
    assert t.dtype == np.float32 and t.shape == (65536,) and not t.flags.writeable
    assert np.all(np.diff(t) > 0)
    assert np.array_equal(t, -t[::-1])  # symmetric quantiles
    assert abs(float(np.mean(t.astype(np.float64) ** 2)) - 1.0) < 1e-6
    assert 4.3 < float(t[-1]) < 4.35  # Φ⁻¹(1 − ½·2⁻¹⁶), rescaled
    draws = table_standard_normal(np.random.default_rng(0), (100_000,)).astype(np.float64)
    assert stats.kstest(draws, "norm").pvalue > 0.01
    assert abs(draws.mean()) < 0.01 and abs(draws.std() - 1.0) < 0.01
    # The same generator state gives the same draws; the shape is honoured.
    a = table_standard_normal(np.random.default_rng(5), (7, 2))
    b = table_standard_normal(np.random.default_rng(5), (7, 2))
    assert a.shape == (7, 2) and np.array_equal(a, b)


def test_mean_cov_rows_matches_numpy_and_is_layout_independent() -> None:
    rng = np.random.default_rng(1)
    p = rng.normal([10.0, -5.0], [3.0, 7.0], size=(4, 999, 2)).astype(np.float32)
    mean, cov = weighted_mean_cov(p)
    x = p.astype(np.float64)
    ref_mean = x.mean(axis=1)
    d = x - ref_mean[:, None]
    ref_cov = np.einsum("kmi,kmj->kij", d, d) / x.shape[1]
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-10)
    soa = np.ascontiguousarray(p.transpose(0, 2, 1))
    m2, c2 = weighted_mean_cov(soa.transpose(0, 2, 1))
    assert np.array_equal(m2, mean) and np.array_equal(c2, cov)
    m3, c3 = weighted_mean_cov(p[2])
    assert np.array_equal(m3, mean[2]) and np.array_equal(c3, cov[2])


def test_calibration_tables_and_coefficients_match_numpy() -> None:
    rng = np.random.default_rng(2)
    samples = rng.normal(0.0, 0.05, size=(10, 9, 9))
    samples[:, 0, 0] = 10.0  # saturated point: zero variance, floored
    mean, std = np.empty((9, 9)), np.empty((9, 9))
    K.calibration_tables(samples, 0.02, mean, std)
    np.testing.assert_allclose(mean, samples.mean(axis=0), rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(std, np.maximum(samples.std(axis=0, ddof=1), 0.02), rtol=1e-12)
    assert std[0, 0] == 0.02
    coef = np.empty((8 * 8 + 1, 8))
    K.bilinear_coefficients(mean, std, 0.5, coef)
    for j, t in enumerate((mean, std)):
        v00, v10, v01, v11 = t[:-1, :-1], t[1:, :-1], t[:-1, 1:], t[1:, 1:]
        for c, v in enumerate((v00, v10 - v00, v01 - v00, v11 - v10 - v01 + v00)):
            assert np.array_equal(coef[:-1, 4 * j + c], v.reshape(-1))
    assert np.array_equal(coef[-1], [0, 0, 0, 0, 0.5, 0, 0, 0])
    coef32 = np.empty((65, 8), dtype=np.float32)
    K.bilinear_coefficients(mean, std, 0.5, coef32)
    assert np.array_equal(coef32, coef.astype(np.float32))  # cast on store = astype


def test_calibrated_kernel_equals_sensor_model_log_likelihood() -> None:
    c = get_condition("salt-delrin-38.1")
    model = CalibratedSensorModel(c, seed=3)
    rng = np.random.default_rng(3)
    h = c.allowed_half_width_mm
    particles = rng.uniform(-h, h, size=(2, 3000, 2)).astype(np.float32)
    particles[0, :5] = [[-h, -h], [h, h], [h, -h], [0.0, h], [-h, 0.0]]  # grid edges: the last cell is used
    position = np.array([[3.5, -12.25], [-60.0, 60.0]])  # the second carriage: most offsets off the grid
    reading = np.array([0.3, -0.01])
    table = model._coef.astype(np.float32)
    n1 = model.grid_mm.size - 1
    k, m = 2, particles.shape[1]
    zterm, std = np.empty((k, m), dtype=np.float32), np.empty((k, m), dtype=np.float32)
    off = np.ascontiguousarray((particles - position.astype(np.float32)[:, None]).transpose(0, 2, 1))
    K.calibrated_zterm_std(off, np.full(k, model.grid_mm[0], dtype=np.float32),
                           np.full(k, 1.0 / model.grid_step_mm, dtype=np.float32), np.full(k, n1, dtype=np.int64),
                           np.zeros(k, dtype=np.int64), table, reading.astype(np.float32), zterm, std)
    ll = zterm - np.log(std)
    for e in range(k):
        ref = model.log_likelihood(reading[e], particles[e] - position[e].astype(np.float32))
        assert ref.dtype == np.float32 and np.array_equal(ll[e], ref)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_egocentric_counts_equal_the_weighted_numpy_path(dtype: type) -> None:
    rng = np.random.default_rng(4)
    p = rng.uniform(-80, 80, size=(3, 1500, 2)).astype(dtype)
    carriage = rng.uniform(-40, 40, size=(3, 2))
    hw = np.array([60.0, 75.0, 40.0])
    unweighted = _egocentric_histogram(p, None, carriage, hw)
    ones = np.ones((3, 1500))  # the numpy path counts with weight 1 per particle
    counts = _egocentric_histogram(p, ones, carriage, hw)
    assert unweighted.shape == (3, HIST_BINS * HIST_BINS)
    assert np.array_equal(unweighted, counts / 1500)
    np.testing.assert_allclose(unweighted.sum(axis=-1), 1.0)


def test_uniform_in_box_is_numpy_uniform_bit_for_bit() -> None:
    from electroloc_gym.belief import uniform_in_box

    low, high = np.array([-60.0, -47.5]), np.array([60.0, 47.5])
    a = np.random.default_rng(9).uniform(low, high, size=(2501, 2))
    b = uniform_in_box(np.random.default_rng(9), low, high, 2501)
    assert np.array_equal(a, b)
