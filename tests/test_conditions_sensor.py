"""Conditions (validation, presets), the sensor reading and the agent's sensor models."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from electroloc_gym.sensor_models import (
    PAPER_CALIBRATION,
    AnalyticSensorModel,
    CalibratedSensorModel,
    CalibrationProtocol,
    SensorModel,
    calibration_coefficients,
    calibration_statistics,
    make_sensor_model,
)
from electroloc_gym.world.conditions import (
    PRESET_NAMES,
    Amplifier,
    Condition,
    Geometry,
    Target,
    Water,
    get_condition,
)
from electroloc_gym.world.sensor import calibration_readings, electrode_positions_mm, expected_reading, noisy_reading

# ---- conditions -------------------------------------------------------------------------------


def test_presets_match_design_table() -> None:
    rows = {
        "fresh-steel-12.7": (12.7, 1.0, 160, 191, 0.25, 40, 50),
        "fresh-delrin-12.7": (12.7, -0.5, 160, 191, 0.23, 40, 50),
        "fresh-steel-38.1": (38.1, 1.0, 160, 103, 0.92, 55, 60),
        "fresh-delrin-38.1": (38.1, -0.5, 160, 103, 0.86, 55, 60),
        "salt-steel-12.7": (12.7, 1.0, 56000, 1977, 0.24, 40, 50),
        "salt-delrin-12.7": (12.7, -0.5, 56000, 1977, 0.35, 40, 50),
        "salt-steel-38.1": (38.1, 1.0, 56000, 148, 0.49, 55, 60),
        "salt-delrin-38.1": (38.1, -0.5, 56000, 148, 0.31, 55, 60),
    }
    assert tuple(rows) == PRESET_NAMES
    for name, (diam, chi, water, gain, noise, start, allowed) in rows.items():
        c = get_condition(name)
        assert c.target.diameter_mm == pytest.approx(diam)
        assert c.chi == pytest.approx(chi, abs=1e-4)  # steel is not infinitely conductive
        assert c.water.conductivity_uScm == water
        assert (c.amplifier.gain, c.amplifier.noise_rms_mV) == (gain, noise)
        assert (c.start_half_width_mm, c.allowed_half_width_mm) == (start, allowed)
        assert c.depth_mm == pytest.approx(diam / 2 + 3.0)
        assert c.noise_std_V == pytest.approx(gain * noise * 1e-3)
        assert c.target_xy_mm == (0.0, 0.0)


def test_paper_variant_has_unit_scale() -> None:
    assert get_condition("salt-steel-12.7", "paper").signal_scale == 1.0
    assert get_condition("salt-steel-12.7", 2.5).signal_scale == 2.5
    c = get_condition("fresh-steel-12.7")
    assert get_condition(c) is c


def test_conditions_are_frozen_and_hashable() -> None:
    c = get_condition("fresh-steel-12.7")
    with pytest.raises(AttributeError):
        c.signal_scale = 3.0  # type: ignore[misc]
    assert hash(c) == hash(get_condition("fresh-steel-12.7"))


def test_dict_round_trip_and_unknown_keys() -> None:
    c = get_condition("salt-delrin-38.1").replace(target_xy_mm=(3.0, -4.0))
    d = json.loads(json.dumps(c.to_dict()))
    assert Condition.from_dict(d) == c
    d["amplifier"]["gian"] = 3
    with pytest.raises(ValueError, match="gian"):
        Condition.from_dict(d)
    with pytest.raises(ValueError, match="colour"):
        Condition.from_dict({**c.to_dict(), "colour": "red"})


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: Target(radius_mm=-1.0, conductivity_uScm=1.0), "radius_mm"),
        (lambda: Target(radius_mm=float("nan"), conductivity_uScm=1.0), "radius_mm"),
        (lambda: Target.sphere(12.7, "gold"), "material"),
        (lambda: Target(radius_mm=1.0, conductivity_uScm=-3.0), "conductivity_uScm"),
        (lambda: Water(0.0), "conductivity_uScm"),
        (lambda: Amplifier(gain=0.0, noise_rms_mV=0.2), "gain"),
        (lambda: Amplifier(gain=10.0, noise_rms_mV=-0.2), "noise_rms_mV"),
        (lambda: Geometry(spacing_mm=0.0), "spacing_mm"),
        (lambda: get_condition("fresh-steel-12.7").replace(start_half_width_mm=70.0), "start_half_width_mm"),
        (lambda: get_condition("fresh-steel-12.7").replace(target_xy_mm=(0.0, 80.0)), "target_xy_mm"),
        (lambda: get_condition("fresh-steel-12.7").replace(signal_scale=0.0), "signal_scale"),
        (lambda: get_condition("fresh-gold-12.7"), "condition"),
        (lambda: get_condition("fresh-steel-12.7", "loud"), "signal"),
    ],
)
def test_nonsense_is_rejected_with_the_argument_named(build, match) -> None:
    with pytest.raises(ValueError, match=match):
        build()


def test_custom_condition_conductivities_give_chi() -> None:
    c = Condition(
        name="x",
        target=Target(5.0, conductivity_uScm=320.0),
        water=Water(160.0),
        amplifier=Amplifier(100.0, 0.3),
        start_half_width_mm=30,
        allowed_half_width_mm=40,
    )
    assert c.chi == pytest.approx((320 - 160) / (320 + 320))


# ---- sensor -----------------------------------------------------------------------------------


def test_reading_is_gain_times_scaled_difference_and_saturates() -> None:
    c = get_condition("fresh-steel-12.7")
    off = np.array([[10.0, 12.0], [-7.0, 3.0]])
    base = expected_reading(c.replace(signal_scale=1.0), off)
    np.testing.assert_allclose(expected_reading(c, off), c.signal_scale * base, rtol=1e-12)
    loud = c.replace(signal_scale=1e4)
    r = expected_reading(loud, off)
    assert np.all(np.abs(r) == 10.0)
    assert np.all(np.abs(expected_reading(loud, off, saturate=False)) > 10.0)


def test_reading_zero_on_the_symmetry_axes_far_and_centre() -> None:
    c = get_condition("fresh-steel-12.7")
    assert expected_reading(c, np.zeros(2)) == pytest.approx(0.0, abs=1e-15)
    # The EEV's zero lines pass through the sensor centre (§4.2): target on x = 0 or y = 0.
    line = np.stack([np.linspace(-40, 40, 9), np.zeros(9)], -1)
    np.testing.assert_allclose(expected_reading(c, line), 0.0, atol=1e-14)
    np.testing.assert_allclose(expected_reading(c, line[:, ::-1]), 0.0, atol=1e-14)
    assert abs(expected_reading(c, np.array([500.0, 500.0]))) < 1e-6


def test_noisy_reading_statistics() -> None:
    c = get_condition("fresh-delrin-12.7")
    rng = np.random.default_rng(0)
    off = np.broadcast_to(np.array([12.0, 9.0]), (20000, 2))
    r = noisy_reading(c, off, rng)
    assert r.mean() == pytest.approx(float(expected_reading(c, off[0])), abs=4 * c.noise_std_V / np.sqrt(20000))
    assert r.std() == pytest.approx(c.noise_std_V, rel=0.03)
    sat = noisy_reading(c.replace(signal_scale=1e5), off[:100], rng)
    assert np.all(np.abs(sat) <= 10.0)


def test_electrode_positions() -> None:
    el = electrode_positions_mm(get_condition("fresh-steel-12.7"), (1.0, 2.0))
    np.testing.assert_allclose(el["emitter+"], (26.0, 2.0))
    np.testing.assert_allclose(el["S2"], (1.0, -23.0))


# ---- sensor models ----------------------------------------------------------------------------


def test_analytic_model() -> None:
    c = get_condition("salt-steel-12.7")
    m = make_sensor_model("analytic", c)
    assert isinstance(m, AnalyticSensorModel) and isinstance(m, SensorModel)
    off = np.random.default_rng(0).uniform(-50, 50, (100, 2))
    mean, std = m.mean_std(off)
    np.testing.assert_allclose(mean, expected_reading(c, off))
    np.testing.assert_allclose(std, c.noise_std_V)
    ll = m.log_likelihood(0.3, off)
    np.testing.assert_allclose(ll, -0.5 * ((0.3 - mean) / c.noise_std_V) ** 2)


@pytest.mark.parametrize("name, n", [("fresh-steel-12.7", 26), ("fresh-delrin-38.1", 31)])
def test_calibrated_grid_is_the_papers(name: str, n: int) -> None:
    m = CalibratedSensorModel(get_condition(name), 0, PAPER_CALIBRATION)
    assert m.grid_shape == (n, n)
    assert m.grid_mm[1] - m.grid_mm[0] == 4.0
    assert m.grid_mm[-1] - m.grid_mm[0] == 4.0 * (n - 1)


def test_calibrated_interpolation_equals_scipy_and_falls_back_outside() -> None:
    c = get_condition("fresh-steel-38.1")
    m = CalibratedSensorModel(c, 3, PAPER_CALIBRATION)
    rgi_m = RegularGridInterpolator((m.grid_mm, m.grid_mm), m.mean_table_V)
    rgi_s = RegularGridInterpolator((m.grid_mm, m.grid_mm), m.std_table_V)
    rng = np.random.default_rng(1)
    inside = rng.uniform(-60, 60, (3000, 2))
    inside[:4] = [[-60, -60], [60, 60], [-60, 60], [60, -60]]  # the corners
    mean, std = m.mean_std(inside)
    np.testing.assert_allclose(mean, rgi_m(inside), atol=1e-12)
    np.testing.assert_allclose(std, rgi_s(inside), atol=1e-12)
    outside = np.array([[60.5, 0.0], [0.0, -61.0], [300.0, 300.0]])
    mean, std = m.mean_std(outside)
    np.testing.assert_allclose(mean, 0.0)
    np.testing.assert_allclose(std, c.noise_std_V)
    m32, s32 = m.mean_std(inside.astype(np.float32))
    assert m32.dtype == np.float32
    np.testing.assert_allclose(m32, rgi_m(inside), atol=1e-5)


def test_calibration_is_a_noisy_estimate_of_the_truth() -> None:
    c = get_condition("fresh-steel-12.7")
    # Five calibrations pooled (3380 grid points): the mean's error is N(0, σ²/10).
    models = [CalibratedSensorModel(c, seed=s) for s in range(5)]
    m = models[0]
    gx, gy = np.meshgrid(m.grid_mm, m.grid_mm, indexing="ij")
    truth = expected_reading(c, np.stack([gx, gy], -1))
    z = np.stack([(mm.mean_table_V - truth) / (c.noise_std_V / np.sqrt(10)) for mm in models])
    assert abs(z.mean()) < 0.06 and z.std() == pytest.approx(1.0, abs=0.05)
    # Sample std of 10 readings is ≈ G·σ_s where unsaturated; floored where saturated.
    assert np.median(m.std_table_V) == pytest.approx(c.noise_std_V, rel=0.1)
    assert m.std_table_V.min() >= 0.25 * c.noise_std_V


def test_calibration_is_seeded_and_cached() -> None:
    c = get_condition("fresh-steel-12.7")
    a = make_sensor_model("calibrated", c, 11)
    assert make_sensor_model("calibrated", c, 11) is a
    b = CalibratedSensorModel(c, seed=11)
    np.testing.assert_array_equal(a.mean_table_V, b.mean_table_V)
    assert not np.array_equal(CalibratedSensorModel(c, seed=12).mean_table_V, a.mean_table_V)


def test_saturated_calibration_has_floored_std() -> None:
    c = get_condition("fresh-steel-12.7", 1000.0)
    m = CalibratedSensorModel(c, seed=0)
    assert np.any(np.abs(m.mean_table_V) == 10.0)
    assert m.std_table_V.min() == pytest.approx(0.25 * c.noise_std_V)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(grid_step_mm=0), "grid_step_mm"),
        (dict(grid_step_mm=float("nan")), "grid_step_mm"),
        (dict(samples_per_point=1), "samples_per_point"),
        (dict(samples_per_point=2.5), "samples_per_point"),
        (dict(half_span_mm=-1.0), "half_span_mm"),
        (dict(std_estimator="median"), "std_estimator"),
        (dict(grid_extent="everything"), "grid_extent"),
        (dict(min_std_fraction=0.0), "min_std_fraction"),
        (dict(position_blur_mm=-0.1), "position_blur_mm"),
    ],
)
def test_calibration_protocol_bad_args(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        CalibrationProtocol(**kwargs)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_calibration_coefficients_equal_the_models(name: str) -> None:
    """The batched path (cached noise-free grid, coefficients only) equals the model built from readings."""
    c = get_condition(name)
    for protocol in (CalibrationProtocol(), CalibrationProtocol(std_estimator="pooled", half_span_mm=70.0)):
        for seed in (0, 123456789):
            ref = CalibratedSensorModel(
                c, seed, protocol, reading_fn=lambda offs, rng: calibration_readings(c, offs, rng)
            )
            fast = CalibratedSensorModel(c, seed, protocol)
            assert np.array_equal(fast.mean_table_V, ref.mean_table_V)
            assert np.array_equal(fast.std_table_V, ref.std_table_V)
            assert np.array_equal(calibration_coefficients(c, seed, protocol), ref._coef)
            out32 = np.zeros((ref._coef.shape[0] + 3, 8), dtype=np.float32)
            calibration_coefficients(c, seed, protocol, out=out32[: ref._coef.shape[0]])
            assert np.array_equal(out32[: ref._coef.shape[0]], ref._coef.astype(np.float32))


@pytest.mark.parametrize("name, n", [("fresh-steel-12.7", 51), ("salt-delrin-38.1", 61)])
def test_all_offsets_grid_covers_every_particle_carriage_offset(name: str, n: int) -> None:
    c = get_condition(name)
    m = CalibratedSensorModel(c, 0, CalibrationProtocol(grid_extent="all-offsets"))
    assert m.grid_shape == (n, n) and m.grid_mm[0] == -2 * c.allowed_half_width_mm
    paper = CalibratedSensorModel(c, 0, PAPER_CALIBRATION)
    # the two grids agree where both have readings (same draws only for the same grid: compare the truth)
    edge = np.array([[c.allowed_half_width_mm + 6.0, 0.5 * c.allowed_half_width_mm]])
    assert paper.mean_std(edge)[0][0] == 0.0  # beyond the paper's square: "no target"
    truth = expected_reading(c, edge)[0]
    assert abs(m.mean_std(edge)[0][0] - truth) < 3 * c.noise_std_V / np.sqrt(10) + 0.05 * abs(truth)


def test_pooled_statistics_equal_their_numpy_form() -> None:
    """The one-pass kernel against the estimator written out with numpy (mean variance over clean points)."""
    c = get_condition("fresh-steel-12.7", 300.0)
    protocol = CalibrationProtocol(std_estimator="pooled")
    samples = calibration_readings(
        c,
        np.zeros((10, 51, 51, 2)) + np.linspace(-40, 40, 51)[None, :, None, None] * np.array([1.0, 0.6]),
        np.random.default_rng(3),
    )
    mean, std = calibration_statistics(samples, protocol, c.noise_std_V, c.saturation_V)
    clean = np.all(np.abs(samples) < c.saturation_V, axis=0)
    assert 0 < clean.sum() < clean.size  # both kinds of point present
    np.testing.assert_allclose(mean, samples.mean(axis=0), rtol=1e-13, atol=1e-15)
    pooled = np.sqrt(samples.var(axis=0, ddof=1)[clean].mean())
    np.testing.assert_allclose(std[clean], pooled, rtol=1e-12)
    per_point = np.maximum(samples.std(axis=0, ddof=1), 0.25 * c.noise_std_V)
    np.testing.assert_allclose(std[~clean], per_point[~clean], rtol=1e-12)


def test_pooled_std_is_one_value_off_saturation() -> None:
    c = get_condition("fresh-steel-12.7", 300.0)  # strong enough to saturate near the target
    per_point = CalibratedSensorModel(c, 4, CalibrationProtocol(std_estimator="per-point"))
    pooled = CalibratedSensorModel(c, 4, CalibrationProtocol(std_estimator="pooled"))
    np.testing.assert_array_equal(pooled.mean_table_V, per_point.mean_table_V)
    saturated = np.abs(per_point.mean_table_V) > c.saturation_V - 6 * c.noise_std_V
    clean = pooled.std_table_V[~saturated]
    assert np.ptp(clean) == 0.0  # one value wherever no reading saturated
    assert clean[0] == pytest.approx(c.noise_std_V, rel=0.03)  # ≈ 6000 points × 9 degrees of freedom
    assert np.std(per_point.std_table_V[~saturated]) > 0.15 * c.noise_std_V  # the per-point estimate is noisy
    assert pooled.std_table_V.min() >= 0.25 * c.noise_std_V


def test_unknown_sensor_model_name() -> None:
    with pytest.raises(ValueError, match="sensor_model"):
        make_sensor_model("psychic", get_condition("fresh-steel-12.7"))


def test_coverage_signal_matches_paper_start_coverage() -> None:
    """§6.3: 78 % of the paper's starts were inside the 2σ detection region; the Table-3 fit gives ≈26 %."""
    from electroloc_gym.world.conditions import PAPER_START_COVERAGE, coverage_signal_multiplier, start_box_coverage

    fitted = np.mean([start_box_coverage(get_condition(n, "fitted")) for n in PRESET_NAMES])
    assert 0.15 < fitted < 0.35
    k = coverage_signal_multiplier()
    assert 5.0 < k < 15.0
    cov = [start_box_coverage(get_condition(n, "coverage")) for n in PRESET_NAMES]
    assert np.mean(cov) == pytest.approx(PAPER_START_COVERAGE, abs=0.01)
    for n in PRESET_NAMES:
        assert get_condition(n, "coverage").signal_scale == pytest.approx(get_condition(n, "fitted").signal_scale * k)


def test_start_box_coverage_limits() -> None:
    from electroloc_gym.world.conditions import start_box_coverage

    c = get_condition("fresh-steel-12.7")
    assert start_box_coverage(c.replace(signal_scale=1e-6)) == 0.0
    # The EEV's zero lines (x = 0, y = 0 through the target) are never inside the region, so < 1.
    assert 0.9 < start_box_coverage(c.replace(signal_scale=1e6)) < 1.0
