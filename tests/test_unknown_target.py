"""ElectroLocUnknownTarget-v0: shape sensor models, the 4-D belief, the API, equivalence, bad inputs."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from vector_equivalence import assert_native_equals_sync

import electroloc_gym  # noqa: F401
from electroloc_gym.baselines import make_agent
from electroloc_gym.engines.numba_core.unknown import CONDUCTOR_CHI, INSULATOR_CHI, SHAPE_INFO_KEYS
from electroloc_gym.kernels import resample_indices
from electroloc_gym.sensor_models import CalibratedSensorModel
from electroloc_gym.sensor_models.shape import InterpolatedShapeModel, TheoreticalShapeModel
from electroloc_gym.world import physics
from electroloc_gym.world.conditions import PRESET_NAMES, Target, get_condition
from electroloc_gym.world.sensor import expected_reading, sphere_reading

ENV_ID = "ElectroLocUnknownTarget-v0"
_GRID = np.stack(np.meshgrid(np.linspace(-60, 60, 41), np.linspace(-60, 60, 37), indexing="ij"), axis=-1)


# ---- the shape sensor models -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_sphere_reading_of_the_condition_sphere_is_eq4_at_its_depth_bit_for_bit(name: str, dtype: type) -> None:
    """The per-hypothesis reading (and ElectroLoc-v0's, which is it for the condition's own sphere) is
    Eq. 4 with the condition's depth A + E + O and the signal scale times the gain, to the bit.
    """
    c = get_condition(name)
    off = _GRID.astype(dtype)
    a = sphere_reading(c, off, c.target.radius_mm, c.chi, saturate=False)
    g = c.geometry
    delta = physics.differential_perturbation(
        off,
        c.target.radius_mm,
        c.chi,
        c.depth_mm,
        spacing_mm=g.spacing_mm,
        emitter_voltage_V=g.emitter_voltage_V,
        electrode_radius_mm=g.electrode_radius_mm,
    )
    b = delta * delta.dtype.type(c.signal_scale * c.amplifier.gain)
    assert a.dtype == b.dtype == dtype
    assert np.array_equal(a, b)
    assert np.array_equal(expected_reading(c, off, saturate=False), a)


def test_theoretical_model_is_linear_in_chi_and_grows_with_the_radius() -> None:
    c = get_condition("salt-steel-38.1")
    model = TheoreticalShapeModel(c)
    off = _GRID.reshape(-1, 2)
    m1, s1 = model.mean_std(off, 8.0, 1.0)
    m2, _ = model.mean_std(off, 8.0, -0.5)
    np.testing.assert_allclose(m2, -0.5 * m1, rtol=1e-12, atol=1e-15)
    assert np.all(s1 == c.noise_std_V)
    # Eq. 4 with the sphere's centre at A + E + O below the electrodes (a bigger sphere sits deeper)
    for a in (6.0, 18.0):
        got, _ = model.mean_std(np.array([[20.0, 20.0]]), a, 1.0)
        want = (
            physics.differential_perturbation(np.array([20.0, 20.0]), a, 1.0, a + 1.0 + 2.0)
            * c.signal_scale
            * c.amplifier.gain
        )
        assert got[0] == pytest.approx(float(want), rel=1e-12)
    # per-particle shapes broadcast: one call equals the scalar calls
    radius = np.array([6.0, 12.0, 18.0])
    chi = np.array([1.0, -0.5, 0.3])
    p = np.array([[5.0, 9.0], [-14.0, 3.0], [22.0, -30.0]])
    batched, _ = model.mean_std(p, radius, chi)
    for k in range(3):
        assert batched[k] == model.mean_std(p[k : k + 1], radius[k], chi[k])[0][0]


def test_interpolated_model_at_a_calibrated_radius_is_that_calibration() -> None:
    c = get_condition("fresh-steel-12.7")
    model = InterpolatedShapeModel(c, (6.35, 19.05), seed=5)
    steel = CalibratedSensorModel(c.replace(target=Target(6.35, 1.4e10, "steel")), 5)
    off = _GRID.reshape(-1, 2)
    mean, std = model.mean_std(off, 6.35, model.chi_ref["steel"])
    ref_mean, ref_std = steel.mean_std(off)
    np.testing.assert_allclose(mean, np.clip(ref_mean, -10, 10), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(std, ref_std, rtol=1e-12)


@pytest.mark.parametrize("name", ["fresh-steel-38.1", "salt-delrin-12.7"])
def test_interpolated_model_of_unseen_sizes_is_within_the_calibration_noise(name: str) -> None:
    """The paper's 6.35 and 19.05 mm spheres and an 11 mm one, none of them calibrated: the interpolation
    errs by less than half the reading noise (RMS over the grid); from the paper's two sizes alone it
    errs by more.
    """
    c = get_condition(name)
    model = InterpolatedShapeModel(c, seed=1)
    coarse = InterpolatedShapeModel(c, (6.35, 19.05), seed=1)
    theory = TheoreticalShapeModel(c)
    off = _GRID.reshape(-1, 2)
    for radius, chi in ((6.35, 1.0), (19.05, -0.5), (11.0, 1.0), (11.0, -0.5)):
        t, _ = theory.mean_std(off, radius, chi)
        m, s = model.mean_std(off, radius, chi)
        assert np.sqrt(np.mean((m - t) ** 2)) < 0.5 * c.noise_std_V, (radius, chi)
        assert abs(np.median(s) / c.noise_std_V - 1) < 0.05  # (lower where the readings saturate)
    t, _ = theory.mean_std(off, 11.0, 1.0)
    m, _ = coarse.mean_std(off, 11.0, 1.0)
    assert np.sqrt(np.mean((m - t) ** 2)) > 0.5 * c.noise_std_V


# ---- the env -----------------------------------------------------------------------------------------------
def test_check_env_gymnasium_and_sb3() -> None:
    env = gym.make(ENV_ID, n_particles=300)
    check_env(env.unwrapped, skip_render_check=True)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(gym.make(ENV_ID, n_particles=300), warn=True)
    check_env(
        gym.make(ENV_ID, n_particles=200, sensor_model="interpolated", contrast="continuous").unwrapped,
        skip_render_check=True,
    )


def test_info_reports_the_estimates_and_the_truth() -> None:
    env = gym.make(ENV_ID, n_particles=400, target_draw="condition", condition="salt-delrin-38.1")
    _, info = env.reset(seed=3)
    assert set(SHAPE_INFO_KEYS) <= set(info)
    core = env.unwrapped
    p = core.belief.particles
    assert p.shape == (400, 4) and not p.flags.writeable
    assert info["target_radius_mm"] == 19.05 and info["target_chi"] == pytest.approx(-0.5, abs=1e-9)
    assert info["radius_mean_mm"] == pytest.approx(float(np.mean(p[:, 2].astype(np.float64))), rel=1e-9)
    assert info["radius_estimate_mm"] == float(np.median(p[:, 2].astype(np.float64)))
    assert info["p_conductor"] == np.count_nonzero(p[:, 3] > 0) / 400
    materials = env.unwrapped.metadata["info_names"]["material_index"]
    assert materials[info["material_index"]] == ("conductor" if info["p_conductor"] > 0.5 else "insulator")
    assert info["material_correct"] == (materials[info["material_index"]] == "insulator")
    assert info["radius_error_frac"] == pytest.approx(abs(info["radius_estimate_mm"] - 19.05) / 19.05)
    assert core.condition.name == "salt-delrin-38.1" and core.condition.target.radius_mm == 19.05
    for _ in range(3):
        _, _, _, _, info = env.step(np.array([0.5, -0.3], dtype=np.float32))
    assert info["n_observations"] == 4
    assert np.all((p[:, 2] >= 5.0) & (p[:, 2] <= 20.0)) and set(np.unique(p[:, 3])) <= {1.0, -0.5}


def test_prior_draws_cover_the_range_and_both_materials() -> None:
    env = gym.make(ENV_ID, n_particles=50, radius_range_mm=(6.0, 18.0))
    radii, chis, conditions = [], [], set()
    for s in range(60):
        _, info = env.reset(seed=s)
        radii.append(info["target_radius_mm"])
        chis.append(info["target_chi"])
        conditions.add(env.unwrapped.condition.name)
    assert min(radii) >= 6.0 and max(radii) <= 18.0 and max(radii) - min(radii) > 8.0
    assert set(chis) == {CONDUCTOR_CHI, INSULATOR_CHI} and len(conditions) >= 6
    env = gym.make(ENV_ID, n_particles=50, contrast="continuous")
    chis = [env.reset(seed=s)[1]["target_chi"] for s in range(40)]
    assert -0.5 <= min(chis) < 0 < max(chis) <= 1.0 and len(set(chis)) == 40


def test_predictions_take_four_column_hypotheses() -> None:
    env = gym.make(ENV_ID, n_particles=100, condition="fresh-steel-38.1", target_draw="condition")
    env.reset(seed=0)
    core = env.unwrapped
    p = core.belief.particles
    mean, std = core.predicted_reading_model(p, np.array([[0.0, 0.0], [10.0, -5.0]]))
    assert mean.shape == std.shape == (2, 100)
    model = core.sensor_model
    ref, _ = model.mean_std(p[:, :2] - core.position_mm.astype(np.float32), p[:, 2], p[:, 3])
    np.testing.assert_array_equal(mean[0], ref)
    assert core.predicted_particles_mm(p, np.array([[1.0, 1.0]])).shape == (1, 100, 4)
    with pytest.raises(ValueError, match=r"shape \(M, 4\)"):
        core.predicted_reading_model(p[:, :2], np.zeros(2))


def test_same_seed_same_episode_and_min_var_runs() -> None:
    def run() -> list[Any]:
        env = gym.make(ENV_ID, n_particles=300, target_draw="condition", condition="fresh-delrin-38.1")
        agent = make_agent("min-var", seed=1)
        obs, info = env.reset(seed=8)
        agent.reset(env.unwrapped)
        out = [obs]
        for _ in range(6):
            a, _ = agent.predict(obs)
            obs, _, term, trunc, info = env.step(a)
            out += [obs, info["radius_estimate_mm"], info["p_conductor"]]
            if term or trunc:
                break
        return out

    a, b = run(), run()
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"sensor_model": "calibrated"}, "sensor_model"),
        ({"radius_range_mm": (10.0, 5.0)}, "radius_range_mm"),
        ({"radius_range_mm": (0.0, 5.0)}, "radius_range_mm"),
        ({"radius_range_mm": 5.0}, "radius_range_mm"),
        ({"contrast": "ternary"}, "contrast"),
        ({"target_draw": "truth"}, "target_draw"),
        ({"eev_radii_mm": (6.0, 6.0)}, "eev_radii_mm"),
        ({"eev_radii_mm": ()}, "eev_radii_mm"),
        ({"layout": "benchmark"}, "unexpected argument"),
    ],
)
def test_bad_arguments(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, **kwargs)


def test_the_other_envs_refuse_the_unknown_target_arguments() -> None:
    with pytest.raises(ValueError, match="unexpected argument"):
        gym.make("ElectroLoc-v0", contrast="binary")
    with pytest.raises(ValueError, match="sensor_model"):
        gym.make("ElectroLoc-v0", sensor_model="interpolated")


# ---- equivalence: the native vector env is the single env, per env, on every CPU --------------------------
EQUIVALENCE_CASES = [
    pytest.param({"n_particles": 300}, AutoresetMode.NEXT_STEP, id="prior-next"),
    pytest.param(
        {"n_particles": 200, "target_draw": "condition", "contrast": "continuous", "max_observations": 8},
        AutoresetMode.SAME_STEP,
        id="condition-continuous-same-step",
    ),
    pytest.param(
        {"n_particles": 150, "sensor_model": "interpolated", "max_observations": 6},
        AutoresetMode.NEXT_STEP,
        id="interpolated",
    ),
]


@pytest.mark.parametrize(("kwargs", "mode"), EQUIVALENCE_CASES)
def test_native_equals_sync_of_single_envs(kwargs: dict[str, Any], mode: AutoresetMode) -> None:
    assert_native_equals_sync(
        ENV_ID,
        kwargs,
        mode,
        ("reading_V", "spread_mm", "radius_estimate_mm", "radius_mean_mm", "p_conductor", "chi_spread"),
        min_ended=1,
    )


def test_resample_indices_equal_searchsorted() -> None:
    rng = np.random.default_rng(0)
    ll = rng.normal(0, 3, (4, 501)).astype(np.float32)
    ll[1, :] = -np.inf  # all impossible: uniform weights
    u0 = rng.random(4)
    idx = np.empty((4, 501), dtype=np.int64)
    assert resample_indices(ll, u0, idx) == -1
    for e in range(4):
        w = np.ones(501) if e == 1 else np.exp((ll[e] - ll[e].max()).astype(np.float64))
        cum = np.cumsum(w / w.sum())
        ref = np.minimum(np.searchsorted(cum / cum[-1], (u0[e] + np.arange(501)) / 501, side="right"), 500)
        assert np.abs(idx[e] - ref).max() <= 1 and np.mean(idx[e] == ref) > 0.99
    ll[2, 7] = np.nan
    assert resample_indices(ll, u0, idx) == 2


# ---- the benchmark ----------------------------------------------------------------------------------------
def test_bench_unknown_target_records_identification_and_prints_its_table(tmp_path: Any) -> None:
    from electroloc_gym.bench.config import BenchConfig

    UNKNOWN_ENV_ID = "ElectroLocUnknownTarget-v0"
    from electroloc_gym.bench.records import read_trials
    from electroloc_gym.bench.runner import run_benchmark

    cfg = BenchConfig(
        agents=("rnd-wlk", "min-var[n_voters=32]"),
        conditions=("salt-steel-38.1",),
        trials=2,
        sensor_model="analytic",
        n_particles=300,
        max_observations=8,
        env_id=UNKNOWN_ENV_ID,
    )
    summary = run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    recs = read_trials(tmp_path / "trials.jsonl")
    assert len(recs) == 4
    for r in recs:
        assert r["env_id"] == UNKNOWN_ENV_ID and r["shape"]["target_radius_mm"] == 19.05
        assert r["shape"]["material_estimate"] in ("conductor", "insulator")
    table = (tmp_path / "table.md").read_text()
    assert "## Identification (unknown target, §7)" in table or not any(r["success"] for r in recs)
    assert summary["rows"]
    with pytest.raises(
        ValueError, match=r"sensor_model must be one of \[.*\] on ElectroLocUnknownTarget-v0, got 'calibrated'"
    ):
        BenchConfig(env_id=UNKNOWN_ENV_ID, sensor_model="calibrated")


def test_lookahead_refuses_shape_hypotheses_with_a_clear_error() -> None:
    env = gym.make(ENV_ID, n_particles=200)
    obs, _ = env.reset(seed=0)
    agent = make_agent("lookahead")
    with pytest.raises(ValueError, match="position hypotheses"):  # at reset, before any decision
        agent.reset(env.unwrapped)
