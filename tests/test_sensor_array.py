"""The sensor array: layouts and their validation, the K-pair reading, its sensor models, fusing K readings."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

from electroloc_gym.kernels.fusion import assimilate_readings, grid_posterior
from electroloc_gym.sensor_models import AnalyticSensorModel, make_sensor_model
from electroloc_gym.sensor_models.pairs import (
    ArrayAnalyticSensorModel,
    ArrayCalibratedSensorModel,
    make_array_sensor_model,
    pair_seeds,
)
from electroloc_gym.world import physics, sensor
from electroloc_gym.world.conditions import PRESET_NAMES, Geometry, get_condition
from electroloc_gym.world.sensor_array import (
    BASELINE_TOLERANCE_V,
    LAYOUT_DESIGNS,
    LAYOUT_NAMES,
    SensorLayout,
    array_noisy_reading,
    array_reading,
    make_sensor_layout,
    named_layout,
)

FRESH = "fresh-steel-12.7"


def _offsets(seed: int, n: int, span: float = 90.0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-span, span, (n, 2))


# ---- the "single" layout is today's sensor, bit for bit -----------------------------------------------


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_single_layout_is_todays_sensor_bit_for_bit(name: str) -> None:
    c = get_condition(name)
    layout = named_layout("single")
    off = _offsets(1, 3000)
    for o in (off, off.astype(np.float32)):
        for sat in (True, False):
            got = array_reading(c, layout, o, saturate=sat)
            assert got.shape == (1, 3000) and got.dtype == o.dtype
            assert np.array_equal(got[0], sensor.expected_reading(c, o, saturate=sat))
    got = array_noisy_reading(c, layout, off, np.random.default_rng(7))
    assert np.array_equal(got[0], sensor.noisy_reading(c, off, np.random.default_rng(7)))


def test_single_layout_sensor_models_bit_for_bit() -> None:
    c = get_condition("salt-steel-12.7")
    layout = named_layout("single")
    off = _offsets(2, 2500, 50.0).astype(np.float32)
    assert np.array_equal(
        ArrayAnalyticSensorModel(c, layout).log_likelihood([0.4], off), AnalyticSensorModel(c).log_likelihood(0.4, off)
    )
    cal = ArrayCalibratedSensorModel(c, layout, seed=5)
    ref = make_sensor_model("calibrated", c, 5)
    assert np.array_equal(cal.log_likelihood([-1.3], off), ref.log_likelihood(-1.3, off))
    m, s = cal.mean_std(off)
    assert np.array_equal(m[0], ref.mean_std(off)[0]) and np.array_equal(s[0], ref.mean_std(off)[1])


def test_general_physics_path_equals_compiled_path() -> None:
    """The general path (emitter_field + sphere_perturbation per electrode) on the paper's pair and on a translated
    unit agrees with the compiled fast path: one physics, two evaluations.
    """
    from electroloc_gym.world.sensor_array import _general_pair

    c = get_condition("fresh-delrin-38.1")
    off = _offsets(3, 2000)
    a, chi = np.asarray(c.target.radius_mm), np.asarray(c.chi)
    for layout in (named_layout("single"), named_layout("grid-2x2")):
        for k, centre in enumerate(layout.paper_unit_centres):
            general = _general_pair(c, layout.electrodes[k], layout.emitters[k], off, a, chi) * c.amplifier.gain
            fast = sensor.expected_reading(c, off - np.asarray(centre), saturate=False)
            np.testing.assert_allclose(general, fast, rtol=1e-12, atol=1e-12 * np.abs(fast).max())


def test_compiled_general_pairs_equal_the_physics_module() -> None:
    """Pairs in the carriage's field and explicit pairs anywhere (own emitters, front end): the compiled pass of
    array_reading equals the physics module's emitter_field + sphere_perturbation.
    """
    from electroloc_gym.world.sensor_array import _general_pair

    c = get_condition("salt-steel-38.1")
    off = _offsets(8, 3000)
    radii = np.random.default_rng(9).uniform(5.0, 20.0, 3000)
    chis = np.random.default_rng(10).choice([1.0, -0.5], 3000)
    explicit = SensorLayout(
        [[[12.0, 40.0], [-30.0, -20.0]], [[70.0, 10.0], [50.0, 60.0]]],
        emitters_mm=[[[0.0, 0.0], [30.0, 0.0]], [[-60.0, 0.0], [-60.0, 40.0]]],
        subtract_baseline=True,
    )
    for layout in (named_layout("line-4"), named_layout("ring-8"), explicit):
        got = array_reading(c, layout, off, radius_mm=radii, chi=chis, saturate=False)
        for k in range(layout.n_pairs):
            ref = _general_pair(c, layout.electrodes[k], layout.emitters[k], off, radii, chis) * c.amplifier.gain
            np.testing.assert_allclose(got[k], ref, rtol=1e-11, atol=1e-12 * np.abs(ref).max())


def test_grid_2x2_is_four_stationary_copies_of_the_paper_sensor() -> None:
    """§7's four stationary pairs: unit k of the array at carriage p reads what the paper's sensor reads at p + c_k,
    and the array's likelihood of its four readings is the sum of the moving sensor's four likelihoods.
    """
    c = get_condition("salt-delrin-12.7")
    layout = named_layout("grid-2x2")
    carriage = np.array([3.0, -7.0])
    particles = _offsets(4, 1500, 50.0)
    readings = np.array([0.5, -0.2, 1.1, 0.0])
    mean = array_reading(c, layout, particles - carriage)
    single = AnalyticSensorModel(c)
    total = 0.0
    for k, centre in enumerate(layout.paper_unit_centres):
        position = carriage + np.asarray(centre)
        np.testing.assert_allclose(mean[k], sensor.expected_reading(c, particles - position), rtol=1e-12, atol=1e-15)
        total = total + single.log_likelihood(readings[k], particles - position)
    np.testing.assert_allclose(
        ArrayAnalyticSensorModel(c, layout).log_likelihood(readings, particles - carriage), total, rtol=1e-10
    )


# ---- no target: every named layout reads ≈ 0 V; noise and saturation are the paper's amplifier's ----------


@pytest.mark.parametrize("name", LAYOUT_NAMES)
def test_named_layouts_read_zero_without_target(name: str) -> None:
    layout = named_layout(name)
    assert layout.design == LAYOUT_DESIGNS[name]
    g = Geometry()
    elec = np.concatenate([layout.electrodes, np.zeros((layout.n_pairs, 2, 1))], axis=-1)
    emit = np.concatenate([layout.emitters, np.zeros((layout.n_pairs, 2, 1))], axis=-1)
    phi = physics.emitter_potential(
        elec, emit[:, None, 0], emit[:, None, 1], g.emitter_voltage_V, g.electrode_radius_mm
    )
    raw = phi[:, 0] - phi[:, 1]  # the emitters' own difference at each pair, V, before the gain
    for cname in PRESET_NAMES:
        c = get_condition(cname)
        assert np.all(np.abs(raw) * c.amplifier.gain < 1e-3 * c.noise_std_V)
        rng = np.random.default_rng(11)
        no_target = array_noisy_reading(c, layout, np.zeros((4000, 2)), rng, chi=0.0)  # a sphere of water
        far = array_reading(c, layout, np.array([1000.0, 1000.0]))  # a real sphere 1.4 m away
        assert no_target.shape == (layout.n_pairs, 4000)
        assert np.all(np.abs(no_target.mean(axis=1)) < 4 * c.noise_std_V / np.sqrt(4000))
        assert np.all(np.abs(far) < 1e-3 * c.noise_std_V)


def test_noise_is_the_amplifiers_per_pair_and_independent() -> None:
    c = get_condition("fresh-steel-38.1")
    layout = named_layout("ring-8")
    off = np.full((20000, 2), 70.0)  # a weak, non-zero signal
    r = array_noisy_reading(c, layout, off, np.random.default_rng(12))
    resid = r - array_reading(c, layout, off)
    np.testing.assert_allclose(resid.std(axis=1), c.noise_std_V, rtol=0.03)  # G·σ_s per pair
    corr = np.corrcoef(resid)
    assert np.all(np.abs(corr[~np.eye(layout.n_pairs, dtype=bool)]) < 0.04)


@pytest.mark.parametrize("name", LAYOUT_NAMES)
def test_saturation_is_the_amplifiers(name: str) -> None:
    c = get_condition("salt-steel-12.7")
    c = c.replace(signal_scale=20 * c.signal_scale)  # a strong signal: a target near any pair drives it past ±10 V
    layout = named_layout(name)
    axis = np.arange(-60.0, 60.1, 2.0)
    grid = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    mean = array_reading(c, layout, grid, saturate=False)
    assert np.all(np.abs(mean).max(axis=1) > c.saturation_V)  # every pair has offsets past ±10 V
    np.testing.assert_array_equal(array_reading(c, layout, grid), np.clip(mean, -c.saturation_V, c.saturation_V))
    noisy = array_noisy_reading(c, layout, grid, np.random.default_rng(3))
    assert np.max(np.abs(noisy)) == c.saturation_V
    inside = np.abs(mean) < c.saturation_V - 6 * c.noise_std_V  # far from the rails the noise is not clipped
    np.testing.assert_allclose((noisy - mean)[inside].std(), c.noise_std_V, rtol=0.05)


def test_vectorised_over_particles() -> None:
    c = get_condition(FRESH)
    layout = named_layout("line-4")
    off = _offsets(5, 60).reshape(3, 20, 2)
    got = array_reading(c, layout, off)
    assert got.shape == (4, 3, 20)
    one = np.stack([array_reading(c, layout, o)[:, 0] for o in off.reshape(-1, 1, 2)], axis=1)
    np.testing.assert_array_equal(got.reshape(4, -1), one)
    radii = np.linspace(5.0, 20.0, 20)
    per_sphere = array_reading(c, layout, off, radius_mm=radii, chi=-0.5)
    assert per_sphere.shape == (4, 3, 20)
    np.testing.assert_array_equal(
        per_sphere[:, 1, 7], array_reading(c, layout, off[1, 7], radius_mm=radii[7], chi=-0.5)
    )


# ---- bad layouts: one clear error naming sensor_layout --------------------------------------------------


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        (np.zeros((0, 2, 2)), r"at least one pair \(K ≥ 1\), got K = 0"),
        ([[[0.0, 10.0], [0.0, 10.5]]], "overlap"),
        ([[[0.0, 25.0], [0.0, -25.0]], [[0.0, 25.0], [0.0, -40.0]]], "overlap"),
        ([[[24.5, 0.0], [0.0, -25.0]]], "overlap"),  # on an emitter
        ([[[0.0, 150.0], [0.0, -25.0]]], "outside the carriage's reach"),
        ([[[0.0, np.nan], [0.0, -25.0]]], "finite"),
        ([[[0.0, np.inf], [0.0, -25.0]]], "finite"),
        ([[0.0, 25.0], [0.0, -25.0]], r"shape \(K, 2, 2\)"),
        (np.zeros((2, 3, 2)), r"shape \(K, 2, 2\)"),
        ([[[0.0, "a"], [0.0, 1.0]]], r"\(K, 2, 2\) array"),
        ("ring-9", "must be one of"),
        (None, "must be one of"),
        (np.zeros((65, 2, 2)), "K ≤ 64"),
        ([[[25.0, 25.0], [-25.0, 25.0]]], "off every equipotential"),  # mirrored about x = 0: Δφ = 2φ(25, 25)
    ],
)
def test_bad_layouts_raise_one_clear_error(spec, match: str) -> None:
    with pytest.raises(ValueError, match=match) as info:
        make_sensor_layout(spec)
    assert str(info.value).startswith("sensor_layout")


def test_equipotential_designs_and_the_front_end() -> None:
    """(x, y)–(x, −y) is on one equipotential for every x; (x, y)–(−x, y) sees 2φ(x, y) unless a front end
    subtracts it, and then reads ≈ 0 without a target.
    """
    for x, y in ((10.0, 25.0), (-37.0, 4.0), (60.0, 60.0)):
        assert make_sensor_layout([[[x, y], [x, -y]]]).baselines_V[0] == 0.0
    x, y, h = 25.0, 25.0, 25.0
    closed = 2.0 * 2.0 * 1.0 * (1.0 / np.hypot(x - h, y) - 1.0 / np.hypot(x + h, y))  # 2·V_e E (1/r₊ − 1/r₋)
    with pytest.raises(ValueError, match=f"{closed * 1e3:.4g} mV"):
        SensorLayout([[[x, y], [-x, y]]])
    fe = SensorLayout([[[x, y], [-x, y]]], subtract_baseline=True)
    assert fe.design == "baseline-subtracting front end"
    np.testing.assert_allclose(fe.baselines_V[0], closed, rtol=1e-12)
    c = get_condition("salt-steel-12.7")
    assert array_reading(c, fe, np.zeros(2), chi=0.0)[0] == 0.0
    assert abs(closed) * c.amplifier.gain > c.saturation_V  # without it, the pair would sit at the rail
    tiny = SensorLayout([[[0.0, 25.0], [1e-5, -25.0]]])  # a hair off x = 0: accepted, and its baseline kept
    assert 0 < abs(tiny.baselines_V[0]) <= BASELINE_TOLERANCE_V
    np.testing.assert_allclose(
        array_reading(get_condition(FRESH), tiny, np.array([500.0, 500.0]), chi=0.0)[0],
        tiny.baselines_V[0] * 191.0,
        rtol=1e-12,
    )


def test_layout_geometry_must_match_the_condition() -> None:
    layout = named_layout("single", Geometry(spacing_mm=40.0))
    assert layout.electrodes[0, 0, 1] == 20.0
    with pytest.raises(ValueError, match="sensor_layout: was built for"):
        array_reading(get_condition(FRESH), layout, np.zeros(2))


# ---- sensor models for K pairs ---------------------------------------------------------------------------


def test_calibrated_array_model_per_pair_tables() -> None:
    c = get_condition(FRESH)
    grid = ArrayCalibratedSensorModel(c, named_layout("grid-2x2"), seed=9)
    off = _offsets(6, 500, 50.0)
    seeds = pair_seeds(9, 4)
    assert seeds[0] == 9 and len(set(seeds)) == 4
    mean, std = grid.mean_std(off)
    for k, centre in enumerate(grid.sensor_layout.paper_unit_centres):  # the paper's calibration, shifted to the unit
        ref = make_sensor_model("calibrated", c, seeds[k]).mean_std(off - np.asarray(centre))
        np.testing.assert_array_equal(mean[k], ref[0])
        np.testing.assert_array_equal(std[k], ref[1])
    ring = named_layout("ring-8")  # pairs in the shared field: their own readings fill their tables
    cal = make_array_sensor_model("calibrated", c, ring, seed=9)
    ana = make_array_sensor_model("analytic", c, ring)
    m_cal, s_cal = cal.mean_std(off)
    m_ana, _ = ana.mean_std(off)
    diff = np.abs(m_cal - m_ana) / c.noise_std_V
    assert np.median(diff) < 0.3 and np.percentile(diff, 99) < 1.5
    np.testing.assert_allclose(np.median(s_cal, axis=1), c.noise_std_V, rtol=0.05)
    readings = array_noisy_reading(c, ring, np.array([10.0, -5.0]), np.random.default_rng(1))
    ll = cal.log_likelihood(readings, off)
    np.testing.assert_allclose(ll, sum(cal.pair_log_likelihood(k, readings[k], off) for k in range(8)), rtol=1e-12)
    with pytest.raises(ValueError, match="one reading per pair"):
        cal.log_likelihood(readings[:3], off)


# ---- the commutativity of §7 -------------------------------------------------------------------------------


def test_exact_posterior_is_the_same_at_once_or_one_by_one() -> None:
    c = get_condition(FRESH)
    layout = named_layout("grid-2x2")
    model = ArrayAnalyticSensorModel(c, layout)
    axis = np.arange(-50.0, 50.5, 1.0)
    grid = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    rng = np.random.default_rng(101)
    dropped = []
    for _ in range(5):
        carriage = rng.uniform(-40, 40, 2)
        readings = array_noisy_reading(c, layout, -carriage, rng)
        ll = np.stack([model.pair_log_likelihood(k, readings[k], grid - carriage) for k in range(4)])
        at_once = grid_posterior(ll, at_once=True)
        for order in ([0, 1, 2, 3], [3, 1, 0, 2], [2, 3, 1, 0]):
            np.testing.assert_allclose(
                grid_posterior(ll, at_once=False, order=order), at_once, rtol=0, atol=1e-12 * at_once.max()
            )
        dropped.append(np.abs(grid_posterior(ll[:3], at_once=True) - at_once).max() / at_once.max())
    assert max(dropped) > 0.05  # a missing reading is seen: the comparison can fail


def _filter_trials(
    seed: int,
    trials: int,
    n_particles: int,
    readings_used: int,
    at_once: bool,
    condition: str = FRESH,
    signal: str = "fitted",
) -> np.ndarray:
    """Posterior (mean x, mean y, spread) of the grid-2x2 array's four readings over ``trials`` fixed-seed trials."""
    c = get_condition(condition, signal)
    half = c.allowed_half_width_mm
    layout = named_layout("grid-2x2")
    model = ArrayAnalyticSensorModel(c, layout)
    gens = [[np.random.default_rng(s) for s in np.random.SeedSequence([seed, i]).spawn(3)] for i in range(trials)]
    carriage = np.array([g[0].uniform(-40, 40, 2) for g in gens])
    readings = np.stack([array_noisy_reading(c, layout, -p, g[0]) for p, g in zip(carriage, gens)])
    clouds = np.stack([g[1].uniform(-half, half, (2, n_particles)) for g in gens]).astype(np.float32)
    car32 = carriage.astype(np.float32)

    def pair_loglik(j: int, cl: np.ndarray) -> np.ndarray:
        return model.pair_log_likelihood(j, readings[:, j, None], cl.transpose(0, 2, 1) - car32[:, None, :])

    mean, cov = assimilate_readings(
        pair_loglik, readings_used, clouds, np.full(trials, half), [g[2] for g in gens], at_once=at_once
    )
    return np.column_stack([mean, np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])])


def test_particle_filter_at_once_and_one_by_one_agree_in_distribution() -> None:
    """Same readings and initial clouds, each fusion with its own resampling and jitter draws: the posterior
    mean and spread have the same distribution over 80 trials (KS, α = 0.01); the control that drops one
    reading is told apart (its spread), so the test has the power to fail.
    """
    at_once = _filter_trials(101, 80, 1000, 4, True)
    one_by_one = _filter_trials(101, 80, 1000, 4, False)
    control = _filter_trials(101, 80, 1000, 3, False)
    for j in range(3):
        assert stats.ks_2samp(at_once[:, j], one_by_one[:, j]).pvalue > 0.01
    assert stats.ks_2samp(one_by_one[:, 2], control[:, 2]).pvalue < 0.01
    assert not np.array_equal(at_once, one_by_one)  # really two different filters


def test_particle_filter_sharp_posterior_one_by_one_is_wider() -> None:
    """Where four readings pin the target down (the stronger "coverage" signal, 38.1 mm spheres), the filter is
    not commutative in its spread: one by one, every update adds the jitter's 1 mm² per axis, so the posterior
    spread is wider than fused at once (where one resampling of a uniform cloud also leaves few distinct
    particles); the estimate itself (mean x, y) still has the same distribution.
    """
    kw = dict(condition="salt-delrin-38.1", signal="coverage")
    at_once = _filter_trials(102, 80, 1000, 4, True, **kw)
    one_by_one = _filter_trials(102, 80, 1000, 4, False, **kw)
    for j in range(2):
        assert stats.ks_2samp(at_once[:, j], one_by_one[:, j]).pvalue > 0.01
    assert stats.ks_2samp(at_once[:, 2], one_by_one[:, 2]).pvalue < 0.01
    assert np.median(one_by_one[:, 2]) > np.median(at_once[:, 2])


def test_detection_coverage_of_single_is_the_conditions() -> None:
    from electroloc_gym.world.conditions import start_box_coverage
    from electroloc_gym.world.sensor_array import detection_coverage

    for name in ("fresh-steel-12.7", "salt-delrin-38.1"):
        c = get_condition(name)
        assert detection_coverage(c, named_layout("single")) == start_box_coverage(c)
        assert detection_coverage(c, named_layout("ring-8")) > start_box_coverage(c)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(emitters_mm=[[[5.0, 30.0], [-40.0, 30.0]]] * 2), "one emitter pair per sensing pair"),
        (dict(emitters_mm=[[[0.0, 25.5], [-40.0, 30.0]]]), "overlap"),
        (dict(reach_mm=20.0), "outside the carriage's reach"),
        (dict(reach_mm=-1.0), "reach_mm must be"),
        (dict(subtract_baseline="yes"), "subtract_baseline must be True or False"),
        (dict(name=""), "name must be"),
        (dict(geometry="paper"), "geometry must be a Geometry"),
    ],
)
def test_bad_layout_fields_raise_one_clear_error(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match) as info:
        SensorLayout([[[0.0, 25.0], [0.0, -25.0]]], **kwargs)
    assert str(info.value).startswith("sensor_layout")


@pytest.mark.parametrize("coordinate", [1e300, -1e300, 1e20, 150.0])
def test_a_far_electrode_is_a_short_message_with_the_allowed_reach(coordinate) -> None:
    with pytest.raises(ValueError, match=r"^sensor_layout: .*outside the carriage's reach \(≤ 100 mm\)$") as exc:
        gym.make("ElectroLoc-v0", sensor_layout=[[[coordinate, 0.0], [0.0, 0.0]]])
    assert len(str(exc.value)) < 200 and "\n" not in str(exc.value)
