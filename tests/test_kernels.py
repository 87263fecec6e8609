"""The compiled kernels (electroloc_gym.kernels) against the numpy expressions they stand for."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from reference_filter import (
    ParticleBelief,
    egocentric_histogram,
    normalise_log_weights,
    table_standard_normal,
    weight_sums,
)
from scipy import stats

from electroloc_gym import kernels as K
from electroloc_gym.contract.observation import HIST_BINS, belief_observation
from electroloc_gym.kernels.streams import normal_table, uniform_in_box
from electroloc_gym.sensor_models import CalibratedSensorModel
from electroloc_gym.world.conditions import get_condition


def _mean_cov(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K.mean_cov_rows of clouds (..., M, 2), any layout."""
    flat = p.reshape((-1,) + p.shape[-2:])
    mean, cov = np.empty((flat.shape[0], 2)), np.empty((flat.shape[0], 2, 2))
    K.mean_cov_rows(flat[..., 0], flat[..., 1], mean, cov)
    return mean.reshape(p.shape[:-2] + (2,)), cov.reshape(p.shape[:-2] + (2, 2))


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
    mean, cov = _mean_cov(p)
    x = p.astype(np.float64)
    ref_mean = x.mean(axis=1)
    d = x - ref_mean[:, None]
    ref_cov = np.einsum("kmi,kmj->kij", d, d) / x.shape[1]
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-10)
    soa = np.ascontiguousarray(p.transpose(0, 2, 1))
    m2, c2 = _mean_cov(soa.transpose(0, 2, 1))
    assert np.array_equal(m2, mean) and np.array_equal(c2, cov)
    m3, c3 = _mean_cov(p[2])
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
    ll = np.empty((k, m), dtype=np.float32)
    scratch = (np.empty(m, np.float32), np.empty(m, np.int32), np.empty(m, np.float32), np.empty(m, np.float32))
    for e in range(k):  # one env of the fused update's lookup, offsets = particle − carriage
        px, py = np.ascontiguousarray(particles[e, :, 0]), np.ascontiguousarray(particles[e, :, 1])
        o = position[e].astype(np.float32)
        K.lookup._calibrated_ll_one(
            px,
            py,
            o[0],
            o[1],
            np.float32(1.0),
            np.float32(model.grid_mm[0]),
            np.float32(1.0 / model.grid_step_mm),
            n1,
            0,
            table,
            np.float32(reading[e]),
            ll[e],
            *scratch,
        )
    for e in range(k):
        ref = model.log_likelihood(reading[e], particles[e] - position[e].astype(np.float32))
        assert ref.dtype == np.float32 and np.array_equal(ll[e], ref)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_egocentric_counts_equal_the_weighted_numpy_path(dtype: type) -> None:
    rng = np.random.default_rng(4)
    p = rng.uniform(-80, 80, size=(3, 1500, 2)).astype(dtype)
    carriage = rng.uniform(-40, 40, size=(3, 2))
    hw = np.array([60.0, 75.0, 40.0])
    counts = np.empty((3, HIST_BINS * HIST_BINS))
    K.egocentric_counts(p[..., 0], p[..., 1], carriage.astype(dtype), (2 * hw).astype(dtype), HIST_BINS, counts)
    ones = np.ones((3, 1500))  # the numpy path counts with weight 1 per particle
    assert np.array_equal(counts, egocentric_histogram(p, ones, carriage, hw))
    np.testing.assert_allclose(counts.sum(axis=-1), 1500)


def test_uniform_in_box_is_numpy_uniform_bit_for_bit() -> None:
    low, high = np.array([-60.0, -47.5]), np.array([60.0, 47.5])
    a = np.random.default_rng(9).uniform(low, high, size=(2501, 2))
    b = uniform_in_box(np.random.default_rng(9), low, high, 2501)
    assert np.array_equal(a, b)
    soa = np.empty((2, 2501), dtype=np.float32)
    assert uniform_in_box(np.random.default_rng(9), low, high, 2501, out_xy=(soa[0], soa[1])) is None
    assert np.array_equal(soa, a.astype(np.float32).T)


def _ulp_error(approx: np.ndarray, x: np.ndarray, fn: Any) -> float:
    """Largest error of float32 ``approx`` against float64 ``fn(x)``, in float32 ulps of the result."""
    ref = fn(x.astype(np.float64))
    with np.errstate(over="ignore"):
        ref32 = ref.astype(np.float32)
    ok = np.isfinite(ref32) & (np.abs(ref32) >= np.finfo(np.float32).tiny)
    return float(np.max(np.abs(approx[ok].astype(np.float64) - ref[ok]) / np.spacing(np.abs(ref32[ok]))))


def test_exp32_within_one_ulp_and_its_special_values() -> None:
    rng = np.random.default_rng(6)
    x = np.concatenate(
        [
            -rng.random(400_000) * 104,
            rng.uniform(-88, 88, 200_000),
            rng.normal(0, 1, 100_000),
            -rng.random(10_000) * 1e-6,
        ]
    ).astype(np.float32)
    out = np.empty_like(x)
    K.exp_f32(x, out)
    assert _ulp_error(out, x, np.exp) <= 1.0
    special = np.array([0.0, -0.0, -103.0, -104.0, -1e30, -np.inf, 89.0, 1e30, np.inf, np.nan], dtype=np.float32)
    got = np.empty_like(special)
    K.exp_f32(special, got)
    assert got[0] == 1.0 and got[1] == 1.0  # the largest weight is exactly 1
    assert 0 < got[2] < 1e-44 and np.all(got[3:6] == 0.0)
    assert np.all(np.isinf(got[6:9])) and np.isnan(got[9])


def test_log32_within_one_ulp_and_its_special_values() -> None:
    rng = np.random.default_rng(7)
    x = np.concatenate(
        [np.exp(rng.uniform(-100, 88, 400_000)), rng.random(200_000), 1.0 + rng.normal(0, 1e-3, 50_000)]
    ).astype(np.float32)
    out = np.empty_like(x)
    K.log_f32(x, out)
    assert _ulp_error(out, x, np.log) <= 1.0
    sub = (np.float32(2.0) ** np.arange(-149, -126)).astype(np.float32)  # subnormals
    got = np.empty_like(sub)
    K.log_f32(sub, got)
    np.testing.assert_allclose(got, np.log(sub.astype(np.float64)), rtol=1e-6)
    special = np.array([1.0, 0.0, -0.0, -1.0, np.inf, np.nan], dtype=np.float32)
    got = np.empty_like(special)
    K.log_f32(special, got)
    assert got[0] == 0.0 and got[1] == -np.inf and got[2] == -np.inf
    assert np.isnan(got[3]) and got[4] == np.inf and np.isnan(got[5])


def test_weight_sums_are_exact_enough_and_the_same_batched_or_alone() -> None:
    rng = np.random.default_rng(8)
    for m in (1, 7, 8, 9, 2500, 2501):
        w = rng.random((3, m))
        s = weight_sums(w)
        np.testing.assert_allclose(s, np.sum(w, axis=-1), rtol=1e-13)
        assert all(weight_sums(w[i]) == s[i] for i in range(3))
    ll = rng.normal(size=(2, 2500)).astype(np.float32) * 30
    w, degenerate = normalise_log_weights(ll)
    assert not degenerate.any() and np.all(np.abs(weight_sums(w) - 1.0) < 1e-12)
    w, degenerate = normalise_log_weights(np.full((1, 5), -np.inf, dtype=np.float32))
    assert degenerate.all() and np.array_equal(w, np.full((1, 5), 0.2))
    with pytest.raises(ValueError, match="NaN"):
        normalise_log_weights(np.array([0.0, np.nan], dtype=np.float32))


def test_calibrated_assimilate_is_the_single_env_update() -> None:
    """The fused kernel = CalibratedSensorModel.log_likelihood + the numpy reference filter, bit for bit."""

    c = get_condition("fresh-steel-12.7")
    model = CalibratedSensorModel(c, seed=11)
    h = np.float32(c.allowed_half_width_mm)
    n1 = model.grid_mm.size - 1
    rng = np.random.default_rng(11)
    k, m = 3, 1000
    particles = rng.uniform(-h, h, (k, m, 2)).astype(np.float32)
    particles[1] = rng.normal(10.0, 3.0, (m, 2)).clip(-h, h)  # a tight cloud
    position = rng.uniform(-20, 20, (k, 2))
    reading = np.array([0.05, -0.2, 3.0])
    u0 = rng.random(k)
    raw = rng.integers(0, 2**64, size=(k, (2 * m + 3) // 4), dtype=np.uint64)
    jitter_idx = np.ascontiguousarray(raw.view(np.uint16)[:, : 2 * m])
    src = np.ascontiguousarray(particles.transpose(0, 2, 1))
    out = np.empty_like(src)
    mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
    grid = (
        np.full(k, model.grid_mm[0], dtype=np.float32),
        np.full(k, 1 / model.grid_step_mm, dtype=np.float32),
        np.full(k, n1),
        np.zeros(k, dtype=np.int64),
        model._coef.astype(np.float32),
    )
    bad = K.calibrated_assimilate(
        src,
        position.astype(np.float32),
        np.float32(1.0),
        *grid,
        reading.astype(np.float32),
        u0,
        jitter_idx,
        normal_table(),
        np.full(k, h),
        out,
        mean,
        cov,
        np.full(k, 2 * h),
        HIST_BINS,
        counts,
    )
    assert bad == -1
    inplace, mean2, cov2, counts2 = src.copy(), np.empty_like(mean), np.empty_like(cov), np.empty_like(counts)
    assert (
        K.calibrated_assimilate(
            inplace,
            position.astype(np.float32),
            np.float32(1.0),
            *grid,
            reading.astype(np.float32),
            u0,
            jitter_idx,
            normal_table(),
            np.full(k, h),
            inplace,
            mean2,
            cov2,
            np.full(k, 2 * h),
            HIST_BINS,
            counts2,
        )
        == -1
    )
    assert np.array_equal(inplace, out) and np.array_equal(mean2, mean) and np.array_equal(counts2, counts)

    class _Fixed:  # replays the kernel's draws through the single env's calls
        def __init__(self, u: float, raw: np.ndarray) -> None:
            self.u, self.bit_generator = u, self
            self.random_raw = lambda n: raw[:n]

        def random(self, shape: tuple[int, ...]) -> np.ndarray:
            return np.full(shape, self.u)

    for e in range(k):
        b = ParticleBelief(m, (-h, -h), (h, h), dtype=np.float32)
        b.set_state(particles[e])
        b.assimilate(
            model.log_likelihood(reading[e], b.particles - position[e].astype(np.float32)), _Fixed(u0[e], raw[e])
        )
        assert np.array_equal(out[e].T, b.particles)
        assert np.array_equal(mean[e], b.mean()) and np.array_equal(cov[e], b.covariance())
        hist = egocentric_histogram(b.particles, None, position[e].astype(np.float32), np.asarray(float(h)))
        assert np.array_equal(counts[e] / m, hist)
    # A NaN reading is reported, not resampled from.
    bad = K.calibrated_assimilate(
        src,
        position.astype(np.float32),
        np.float32(1.0),
        *grid,
        np.array([0.0, np.nan, 0.0], dtype=np.float32),
        u0,
        jitter_idx,
        normal_table(),
        np.full(k, h),
        out,
        mean,
        cov,
        np.full(k, 2 * h),
        HIST_BINS,
        counts,
    )
    assert bad == 1


def test_noisy_saturated_equals_its_numpy_expression() -> None:
    rng = np.random.default_rng(12)
    idx = rng.integers(0, 65536, 5001).astype(np.uint16)
    mean = rng.normal(0.0, 8.0, 5001)
    got = np.empty_like(mean)
    K.noisy_saturated(mean, idx, normal_table(), 0.3, 10.0, got)
    ref = np.clip(mean + normal_table()[idx].astype(np.float64) * 0.3, -10.0, 10.0)
    assert np.array_equal(got, ref) and got.max() == 10.0 and got.min() == -10.0


def test_belief_observation_equals_its_numpy_formulas() -> None:
    """The compiled observation assembly against the formulas of the observation table (numpy)."""

    rng = np.random.default_rng(13)
    k = 6
    carriage = rng.uniform(-60, 60, (k, 2))
    reading = rng.normal(0, 4, k)
    particles = rng.normal(rng.uniform(-40, 40, (k, 1, 2)), rng.uniform(0.5, 30, (k, 1, 2)), (k, 700, 2))
    particles[0] = 5.0  # a collapsed cloud: zero spread, ρ = 0
    n_obs = rng.integers(0, 36, k)
    hw = rng.uniform(40, 60, k)
    noise, sat = rng.uniform(0.01, 0.3, k), np.full(k, 10.0)
    desc = rng.uniform(-1, 1, (k, 5)).astype(np.float32)
    mean, cov = _mean_cov(particles)
    hist = egocentric_histogram(particles, None, carriage, hw)
    obs = belief_observation(carriage, reading, mean, cov, hist, n_obs, 35, hw, noise, sat, 10.0, desc)
    sx, sy = np.sqrt(cov[:, 0, 0]), np.sqrt(cov[:, 1, 1])
    rho = np.where(sx * sy > 1e-12, cov[:, 0, 1] / np.maximum(sx * sy, 1e-12), 0.0)
    spread = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    scalars = np.stack(
        [
            carriage[:, 0] / hw,
            carriage[:, 1] / hw,
            reading / sat,
            np.tanh(reading / (3 * noise)),
            (mean[:, 0] - carriage[:, 0]) / (2 * hw),
            (mean[:, 1] - carriage[:, 1]) / (2 * hw),
            sx / hw,
            sy / hw,
            rho,
            spread / hw,
            np.log10(np.maximum(spread, 1e-6) / 10.0),
            n_obs / 35,
        ],
        axis=-1,
    )
    ref = np.concatenate([np.clip(scalars, -1, 1), hist, desc], axis=-1).astype(np.float32)
    assert obs.shape == (k, 81) and obs.dtype == np.float32
    np.testing.assert_allclose(obs, ref, rtol=1e-6, atol=1e-7)
    assert obs[0, 8] == 0.0 and obs[0, 10] == -1.0


def test_jitter_resampled_is_the_numpy_gather_jitter_and_clip() -> None:
    """The D-coordinate resampling kernel against its numpy statement, bit for bit (float32 throughout)."""
    rng = np.random.default_rng(5)
    k, m = 3, 257
    src = rng.uniform(-60, 60, (k, 4, m)).astype(np.float32)
    src[:, 3] = np.where(rng.random((k, m)) < 0.5, 1.0, -0.5)
    idx = np.sort(rng.integers(0, m, (k, m)), axis=1)
    jitter = rng.integers(0, 2**16, (k, 4 * m)).astype(np.uint16)
    table = normal_table()
    scale = np.array([1.0, 1.0, 0.5, 0.0], dtype=np.float32)
    lo = np.tile(np.array([-50, -50, 5, -0.5], dtype=np.float32), (k, 1))
    hi = np.tile(np.array([50, 50, 20, 1], dtype=np.float32), (k, 1))
    out = np.empty_like(src)
    K.jitter_resampled(idx, src, jitter, table, scale, lo, hi, out)
    z = table[jitter]
    rows = np.arange(k)[:, None]
    draws = (z[:, 0 : 2 * m : 2], z[:, 1 : 2 * m : 2], z[:, 2 * m :: 2], z[:, 2 * m + 1 :: 2])
    for d in range(4):
        want = np.minimum(np.maximum(src[:, d][rows, idx] + scale[d] * draws[d], lo[:, d : d + 1]), hi[:, d : d + 1])
        np.testing.assert_array_equal(out[:, d], want)
    assert set(np.unique(out[:, 3])) <= {np.float32(-0.5), np.float32(1.0)}  # scale 0: the contrast unjittered
