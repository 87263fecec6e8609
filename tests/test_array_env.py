"""ElectroLoc-v0 with a sensor array (``sensor_layout=``) and the stationary carriage (``fixed_carriage=``)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import electroloc_gym  # noqa: F401
from electroloc_gym.engines.numba_core import step as core_step
from electroloc_gym.engines.numba_core.electroloc import ElectroLocOptions
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.kernels import loglik_assimilate
from electroloc_gym.kernels.streams import normal_table, table_normal_indices
from electroloc_gym.world.sensor import saturated_reading
from electroloc_gym.world.sensor_array import LAYOUT_NAMES, SensorLayout, array_reading, named_layout

ID = "ElectroLoc-v0"
PAPER_PAIR = [[[0.0, 25.0], [0.0, -25.0]]]


def _rollout(env: gym.Env, seed: int, n_steps: int) -> list[Any]:
    out: list[Any] = []
    obs, info = env.reset(seed=seed)
    out.append((obs, info))
    rng = np.random.default_rng(5)
    for _ in range(n_steps):
        step = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        out.append(step)
        if step[2] or step[3]:
            obs, info = env.reset()
            out.append((obs, info))
    return out


def _same(a: list[Any], b: list[Any]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x[0], y[0])
        assert x[1:-1] == y[1:-1]
        assert x[-1].keys() == y[-1].keys() and all(np.array_equal(x[-1][k], y[-1][k]) for k in x[-1])


# ---- K = 1, the paper's pair: ElectroLoc-v0 bit for bit -------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_particles": 300},
        {"n_particles": 300, "sensor_model": "analytic", "condition": "random", "randomize_target": True},
    ],
)
def test_single_layout_is_the_paper_env_bit_for_bit(kwargs: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    default = _rollout(gym.make(ID, **kwargs), 4, 40)
    _same(default, _rollout(gym.make(ID, sensor_layout="single", **kwargs), 4, 40))
    _same(default, _rollout(gym.make(ID, sensor_layout=PAPER_PAIR, **kwargs), 4, 40))
    # the task before the array existed (core.localize's LocalizeTask), run by the same step
    monkeypatch.setattr(core_step, "make_task", LocalizeTask)
    _same(default, _rollout(gym.make(ID, **kwargs), 4, 40))


# ---- the array path -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", [n for n in LAYOUT_NAMES if n != "single"])
@pytest.mark.parametrize("observation", ["belief", "raw"])
def test_observation_and_info_carry_every_pair(name: str, observation: str) -> None:
    k = named_layout(name).n_pairs
    env = gym.make(ID, sensor_layout=name, observation=observation, n_particles=200, sensor_model="analytic")
    base = 81 if observation == "belief" else 3
    assert env.observation_space.shape == (base + k - 1,)
    obs, info = env.reset(seed=1)
    for _ in range(2):
        assert env.observation_space.contains(obs)
        pairs = info["pair_readings_V"]
        assert pairs.shape == (k,) and info["reading_V"] == pairs[0]
        assert info["n_readings"] == k * info["n_observations"]
        np.testing.assert_array_equal(env.unwrapped.last_readings_V, pairs)
        np.testing.assert_array_equal(obs[-(k - 1) :], np.clip(pairs[1:] / 10.0, -1, 1).astype(np.float32))
        np.testing.assert_array_equal(obs[2], np.float32(np.clip(pairs[0] / 10, -1, 1)))  # Φ_0 / V_sat
        obs, _, te, tr, info = env.step(np.zeros(2, np.float32))
        if te or tr:
            break


def test_a_step_fuses_its_k_readings_one_update_per_reading() -> None:
    """The documented draws (K noises, U, jitter; then U, jitter per further reading) and K kernel updates."""
    m = 300
    env = gym.make(ID, sensor_layout="grid-2x2", n_particles=m, sensor_model="analytic", fixed_carriage=True)
    env.reset(seed=9)
    core = env.unwrapped
    s = core._state
    g = np.random.Generator(np.random.PCG64())
    g.bit_generator.state = core.np_random.bit_generator.state
    cloud = s.particles_mm.copy()
    c, layout = core.condition, core.sensor_layout
    truth = array_reading(c, layout, s.target_mm[0] - s.position_mm[0], saturate=False)
    noise = g.normal(0.0, c.noise_std_V, 4)
    reading = saturated_reading(truth, noise, c.saturation_V)
    model = core.sensor_model
    half = np.array([c.allowed_half_width_mm], dtype=np.float32)
    origin = s.position_mm[:1].astype(np.float32)
    mean, cov, counts = np.empty((1, 2)), np.empty((1, 2, 2)), np.empty((1, 64))
    for j in range(4):
        u0 = np.array([g.random()])
        jitter = table_normal_indices(g, 2 * m)[None]
        off = (cloud[0] - origin[0][:, None]).T
        ll = np.asarray(model.pair_log_likelihood(j, reading[j], off), dtype=np.float32)[None]
        assert (
            loglik_assimilate(
                ll, cloud, origin, u0, jitter, normal_table(), half, cloud, mean, cov, 2 * half, 8, counts
            )
            < 0
        )
    _, _, _, _, info = env.step(np.ones(2, np.float32))
    np.testing.assert_array_equal(info["pair_readings_V"], reading)
    np.testing.assert_array_equal(s.particles_mm, cloud)
    np.testing.assert_array_equal(s.mean_mm, mean)


def test_fixed_carriage_never_moves_and_agents_predict_it() -> None:
    env = gym.make(
        ID,
        sensor_layout="ring-8",
        fixed_carriage=True,
        n_particles=200,
        sensor_model="analytic",
        max_observations=6,
        success_spread_mm=1e-3,
    )
    assert isinstance(env.action_space, gym.spaces.Box) and env.action_space.shape == (2,)
    _, info = env.reset(seed=2)
    core = env.unwrapped
    start = info["position_mm"]
    lo, hi = core.move_bounds_mm
    assert np.all(lo == 0) and np.all(hi == 0)
    p = core.belief.particles
    still = core.predicted_reading_model(p, np.zeros(2))
    moved = core.predicted_reading_model(p, np.array([[10.0, -10.0], [5.0, 5.0]]))
    assert still[0].shape == (200, 8) and moved[0].shape == (2, 200, 8)
    np.testing.assert_array_equal(moved[0][1], still[0])
    for _ in range(5):
        _, _, te, tr, info = env.step(np.ones(2, np.float32))
        assert np.array_equal(info["position_mm"], start)
    assert tr and not te and info["n_observations"] == 6
    # a moving carriage predicts from the moved position
    mov = gym.make(ID, sensor_layout="ring-8", n_particles=200, sensor_model="analytic")
    mov.reset(seed=2)
    a = mov.unwrapped.predicted_reading_model(p, np.array([[0.0, 0.0], [10.0, 0.0]]))[0]
    assert not np.array_equal(a[0], a[1])


@pytest.mark.parametrize("name", LAYOUT_NAMES)
def test_check_env_gymnasium_and_sb3(name: str) -> None:
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    for fixed in (False, True):
        env = gym.make(ID, sensor_layout=name, fixed_carriage=fixed, n_particles=100, sensor_model="analytic")
        check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(gym.make(ID, sensor_layout=name, fixed_carriage=fixed, n_particles=100), warn=False)


@pytest.mark.parametrize(
    ("layout", "match"),
    [
        ("hexagon", r"^sensor_layout: must be one of"),
        (np.zeros((0, 2, 2)), r"^sensor_layout: .*K ≥ 1"),
        ([[[0.0, 25.0], [0.0, 25.5]]], r"^sensor_layout: .*overlap"),
        ([[[0.0, 125.0], [0.0, -25.0]]], r"^sensor_layout: .*outside the carriage's reach"),
        ([[[0.0, np.nan], [0.0, -25.0]]], r"^sensor_layout: .*finite"),
        ([[[10.0, 25.0], [-10.0, 25.0]]], r"^sensor_layout: .*off every equipotential"),
        ([[0.0, 25.0], [0.0, -25.0]], r"^sensor_layout: .*shape \(K, 2, 2\)"),
        (3, r"^sensor_layout: must be one of"),
    ],
)
def test_bad_layouts_one_clear_error(layout: Any, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(ID, sensor_layout=layout)


def test_bad_combinations() -> None:
    with pytest.raises(ValueError, match="^fixed_carriage must be True or False"):
        gym.make(ID, fixed_carriage=1)
    with pytest.raises(ValueError, match="^sensor_layout: .*gain_levels"):
        gym.make(ID, sensor_layout="ring-8", gain_levels=(0.5, 1.0))
    with pytest.raises(ValueError, match="unexpected argument.*sensor_layout"):
        gym.make("ElectroLocGlobal-v0", sensor_layout="ring-8")
    assert isinstance(ElectroLocOptions(sensor_layout=PAPER_PAIR).sensor_layout, SensorLayout)


def test_native_vector_env_equals_single_envs() -> None:
    kw = {"sensor_layout": "line-4", "n_particles": 200, "max_observations": 4}
    n = 3
    native = gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", **kw)
    ref = gym.vector.SyncVectorEnv(
        [lambda: gym.make(ID, **kw) for _ in range(n)], autoreset_mode=AutoresetMode.NEXT_STEP
    )
    assert native.single_observation_space.shape == (84,)
    o1, i1 = native.reset(seed=[3, 4, 5])
    o2, i2 = ref.reset(seed=[3, 4, 5])
    assert np.array_equal(o1, o2) and np.array_equal(i1["pair_readings_V"], np.stack(i2["pair_readings_V"]))
    rng = np.random.default_rng(0)
    for _ in range(12):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        o1, r1, te1, tr1, i1 = native.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(te1, te2) and np.array_equal(tr1, tr2)
        assert np.array_equal(i1["reading_V"], i2["reading_V"])


# ---- agents ---------------------------------------------------------------------------------------------------
def test_min_var_moments_of_two_equal_pairs_are_one_pair_with_half_the_variance() -> None:
    from electroloc_gym.baselines.min_variance import weighted_moments

    rng = np.random.default_rng(0)
    x = rng.uniform(-40, 40, (300, 2))
    mean = rng.normal(0, 1, (5, 300))
    std = np.repeat(rng.uniform(0.3, 0.6, (5, 1)), 300, axis=1)  # one std per option: the 1/σ factors cancel
    voters = np.arange(0, 300, 7)
    one = weighted_moments(x, None, mean, std / np.sqrt(2.0), voters, kernel="difference")
    two = weighted_moments(x, None, np.stack([mean, mean], -1), np.stack([std, std], -1), voters)
    np.testing.assert_allclose(two[..., 1:], one[..., 1:], rtol=1e-3, atol=1e-2)  # float32 sums
    single = weighted_moments(x, None, mean, std, voters, kernel="difference")
    assert not np.allclose(single[..., 3], one[..., 3], rtol=1e-2)


def test_lookahead_step_log_likelihood_sums_the_pairs() -> None:
    from electroloc_gym.baselines.lookahead_objectives import _step_log_likelihoods

    rng = np.random.default_rng(1)
    mu, sd = rng.normal(0, 1, (2, 3, 20, 4)), rng.uniform(0.2, 1, (2, 3, 20, 4))
    hyp, eps = rng.integers(0, 20, 6), rng.normal(0, 1, (6, 2, 4))
    want = sum(_step_log_likelihoods(mu[..., q], sd[..., q], hyp, eps[..., q]) for q in range(4))
    np.testing.assert_allclose(_step_log_likelihoods(mu, sd, hyp, eps), want)


@pytest.mark.parametrize("agent", ["min-var", "lookahead", "rnd-wlk"])
def test_agents_run_on_an_array(agent: str) -> None:
    from electroloc_gym.baselines import make_agent
    from electroloc_gym.baselines.rollout import run_episode

    env = gym.make(
        ID,
        sensor_layout="grid-2x2",
        n_particles=500,
        sensor_model="analytic",
        max_observations=8,
        condition="fresh-steel-38.1",
    )
    ep = run_episode(env, make_agent(agent, seed=0), 101)
    assert ep.info["n_observations"] >= 1 and ep.ended_by in ("success", "cap")


def test_zero_crossing_refuses_an_array() -> None:
    from electroloc_gym.baselines import make_agent

    env = gym.make(ID, sensor_layout="ring-8", n_particles=100)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="zero-crossing .*sensor_layout='single'"):
        make_agent("zero-crossing", seed=0).reset(env)


def test_bench_sensor_layout_reaches_the_trials(tmp_path: Any, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from electroloc_gym.cli import main

    args = [
        "bench",
        "--sensor-layout",
        "ring-8",
        "--agents",
        "rnd-wlk",
        "--conditions",
        "fresh-steel-38.1",
        "--trials",
        "2",
        "--n-particles",
        "300",
        "--sensor-model",
        "analytic",
        "--workers",
        "1",
        "--backend",
        "serial",
        "--no-progress",
        "--out",
        str(tmp_path / "run"),
    ]
    assert main(args) == 0
    recs = [json.loads(line) for line in (tmp_path / "run" / "trials.jsonl").read_text().splitlines()]
    assert len(recs) == 2 and all(r["sensor_layout"] == "ring-8" for r in recs)
    assert main([*args[:-1], str(tmp_path / "other"), "--env", "global"]) == 2
    assert "--sensor-layout applies to --env target" in capsys.readouterr().err


def test_a_policy_runs_only_on_the_layout_it_was_trained_with(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    from electroloc_gym.bench.default_run import default_agents
    from electroloc_gym.cli import main

    base = [
        "bench",
        "--conditions",
        "fresh-steel-38.1",
        "--trials",
        "1",
        "--n-particles",
        "300",
        "--workers",
        "1",
        "--backend",
        "serial",
        "--no-progress",
    ]
    assert main([*base, "--agents", "ppo-belief-grid-2x2", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "trained with sensor_layout='grid-2x2', this run has sensor_layout='single'" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "a").exists()
    assert main([*base, "--sensor-layout", "grid-2x2", "--agents", "ppo-belief", "--out", str(tmp_path / "b")]) == 2
    assert "trained with sensor_layout='single', this run has sensor_layout='grid-2x2'" in capsys.readouterr().err
    assert (
        main([*base, "--sensor-layout", "grid-2x2", "--agents", "ppo-belief-grid-2x2", "--out", str(tmp_path / "c")])
        == 0
    )
    recs = [json.loads(line) for line in (tmp_path / "c" / "trials.jsonl").read_text().splitlines()]
    assert [r["sensor_layout"] for r in recs] == ["grid-2x2"]
    # a default run lists the array policy only on its own layout, and the single-pair policies only on theirs
    on_grid = {c.spec: c.skipped for c in default_agents(sensor_layout="grid-2x2")}
    on_single = {c.spec: c.skipped for c in default_agents()}
    assert on_grid["ppo-belief-grid-2x2"] is None and "sensor_layout='single'" in on_grid["ppo-belief"]
    assert "sensor_layout='grid-2x2'" in on_single["ppo-belief-grid-2x2"] and on_single["ppo-belief"] is None
