"""ElectroLocGlobal-v0, the global self-localisation env (paper §6.5); its scene: tests/test_scene.py."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import electroloc_gym
from electroloc_gym.envs import GlobalEnv
from electroloc_gym.world.scene import BENCHMARK_SCENE

GLOBAL_ID = "ElectroLocGlobal-v0"


# ---------------------------------------------------------------------------------------------
# The environment
# ---------------------------------------------------------------------------------------------
def test_registered_and_idempotent() -> None:
    assert GLOBAL_ID in electroloc_gym.ENV_IDS
    electroloc_gym._register_builtin()
    assert GLOBAL_ID in gym.registry
    env = gym.make(f"electroloc_gym:{GLOBAL_ID}", n_particles=100)
    assert isinstance(env.unwrapped, GlobalEnv)


@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_gymnasium_check_env(observation: str, sensor_model: str) -> None:
    env = gym.make(GLOBAL_ID, observation=observation, sensor_model=sensor_model, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped, skip_render_check=True)
    assert not [str(w.message) for w in record]


@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_sb3_check_env(observation: str, action_type: str) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(GLOBAL_ID, observation=observation, action_type=action_type, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    assert not [str(w.message) for w in record]


def _rollout(seed: int, n: int = 40, **kwargs):
    env = gym.make(GLOBAL_ID, **kwargs)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), 0.0, False, False, info, env.unwrapped.belief.particles.copy())]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append((obs.copy(), r, term, trunc, info, env.unwrapped.belief.particles.copy()))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs.copy(), 0.0, False, False, info, env.unwrapped.belief.particles.copy()))
    return out


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(n_particles=500),
        dict(n_particles=500, sensor_model="analytic"),
        dict(n_particles=300, layout="random", observation="raw"),
    ],
)
def test_seeded_rollouts_are_identical(kwargs) -> None:
    a = _rollout(11, **kwargs)
    b = _rollout(11, **kwargs)
    assert len(a) == len(b)
    for (oa, ra, ta, tra, ia, pa), (ob, rb, tb, trb, ib, pb) in zip(a, b):
        np.testing.assert_array_equal(oa, ob)
        np.testing.assert_array_equal(pa, pb)
        assert (ra, ta, tra) == (rb, tb, trb)
        np.testing.assert_equal(ia, ib)
    c = _rollout(12, n=3, **kwargs)
    assert any(not np.array_equal(x[0], y[0]) for x, y in zip(a, c))


def test_random_layout_changes_with_the_seed_only() -> None:
    env = GlobalEnv(layout="random", n_particles=100, sensor_model="analytic")
    env.reset(seed=1)
    s1 = env.scene
    env.reset(seed=1)
    assert env.scene == s1
    env.reset(seed=2)
    assert env.scene != s1 and len(env.scene.objects) == 6


def test_info_contract_truth_and_odometry() -> None:
    env = GlobalEnv(n_particles=500, observation="raw")
    obs, info = env.reset(seed=3)
    assert set(info) == {
        "position_mm",
        "estimate_mm",
        "error_mm",
        "spread_mm",
        "reading_V",
        "n_observations",
        "success",
        "condition_index",
    }
    assert info["n_observations"] == 1 and env.condition.name == BENCHMARK_SCENE.name
    assert info["condition_index"] == -1  # not one of the eight presets
    np.testing.assert_array_equal(obs[:2], 0.0)  # raw: odometry, not the (unknown) true position
    assert np.all(np.abs(env.position_mm) <= BENCHMARK_SCENE.start_half_width_mm)
    obs, _, _, _, info = env.step(np.array([0.5, -1.0], np.float32))
    np.testing.assert_allclose(env.odometry_mm, [5.0, -10.0])
    np.testing.assert_allclose(obs[:2], np.array([5.0, -10.0]) / 80.0, rtol=1e-6)
    np.testing.assert_array_equal(info["position_mm"], env.position_mm)
    assert info["error_mm"] == pytest.approx(float(np.hypot(*(np.array(info["estimate_mm"]) - env.position_mm))))
    lo, hi = env.move_bounds_mm
    np.testing.assert_array_equal(lo, [-10.0, -10.0])
    np.testing.assert_array_equal(hi, [10.0, 10.0])


def test_motion_shifts_particles_and_keeps_carriage_in_the_box() -> None:
    env = GlobalEnv(n_particles=400, sensor_model="analytic")
    env.reset(seed=4)
    before = env.belief.particles.copy()
    pos = env.position_mm
    core = env._sim  # the motion half of a step (no reading)
    core.task.move(core.state, slice(None), np.array([[10.0, -10.0]]))
    np.testing.assert_allclose(env.belief.particles, np.clip(before + [10.0, -10.0], -80, 80), atol=1e-5)
    np.testing.assert_allclose(env.position_mm, np.clip(pos + [10.0, -10.0], -80, 80))
    for _ in range(30):  # drive into the corner: truth and particles stay inside the box
        _, _, term, trunc, _ = env.step(np.array([1.0, 1.0], np.float32))
        if term or trunc:
            break
    assert np.all(env.position_mm <= 80.0) and np.all(env.belief.particles <= 80.0)


def test_predicted_reading_model_matches_the_map_and_the_v0_convention() -> None:
    env = GlobalEnv(n_particles=200, sensor_model="analytic")
    env.reset(seed=5)
    parts = np.array([[0.0, 0.0], [75.0, -78.0], [-30.0, 44.0]], dtype=np.float32)
    moves = np.array([[0.0, 0.0], [10.0, -10.0], [-3.0, 7.0]])
    mean, std = env.predicted_reading_model(parts, moves)
    assert mean.shape == std.shape == (3, 3) and mean.dtype == np.float32
    after = env.predicted_particles_mm(parts, moves)
    np.testing.assert_allclose(after[1, 1], [80.0, -80.0])  # clipped at the walls like the carriage
    np.testing.assert_allclose(mean, BENCHMARK_SCENE.expected_reading(after.astype(np.float64)), rtol=1e-4, atol=1e-4)
    m1, _ = env.predicted_reading_model(parts, moves[2])
    np.testing.assert_allclose(m1, mean[2])
    # ElectroLoc-v0 offers the same call with offsets = particle − clip(carriage + move).
    v0 = gym.make("ElectroLoc-v0", n_particles=100, sensor_model="analytic").unwrapped
    v0.reset(seed=0)
    low, high = v0.allowed_box_mm
    mv, _ = v0.predicted_reading_model(parts / 2, moves)
    carriages = np.clip(v0.position_mm + moves, low, high)[:, None].astype(np.float32)
    ref = v0.sensor_model.mean_std(parts[None] / 2 - carriages)[0]
    np.testing.assert_array_equal(mv, ref)
    np.testing.assert_array_equal(v0.predicted_particles_mm(parts, moves), np.broadcast_to(parts, (3, 3, 2)))
    with pytest.raises(ValueError, match="moves_mm"):
        env.predicted_reading_model(parts, np.zeros(3))
    with pytest.raises(ValueError, match="particles_mm"):
        env.predicted_reading_model(np.zeros(4), moves)


def _square_spiral(n: int) -> list[np.ndarray]:
    """A fixed, informative path: an outward square spiral of 10 mm moves."""
    dirs = [np.array(d, np.float32) for d in ((1, 0), (0, 1), (-1, 0), (0, -1))]
    out, leg, k = [], 1, 0
    while len(out) < n:
        for _ in range(2):
            out += [dirs[k % 4]] * leg
            k += 1
        leg += 1
    return out[:n]


@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_belief_converges_on_a_fixed_informative_path(sensor_model: str) -> None:
    """Along a fixed spiral the belief tightens on the true position in (nearly) every trial."""
    good = 0
    seeds = range(8)
    for seed in seeds:
        env = GlobalEnv(sensor_model=sensor_model)
        _, info = env.reset(seed=seed)
        spreads = [info["spread_mm"]]
        for a in _square_spiral(34):
            _, _, term, trunc, info = env.step(a)
            spreads.append(info["spread_mm"])
            if term or trunc:
                break
        assert spreads[-1] < spreads[0]
        good += bool(info["success"] and info["error_mm"] < 5.0)
    assert good >= 7


def test_multimodal_belief_spread_and_no_crash() -> None:
    """Two far-apart clusters: the spread is the mixture's √trace Σ, not a cluster's, and steps work."""
    env = GlobalEnv(n_particles=1000, sensor_model="calibrated")
    env.reset(seed=6)
    rng = np.random.default_rng(0)
    a = rng.normal([-50.0, -50.0], 1.0, size=(500, 2))
    b = rng.normal([50.0, 50.0], 1.0, size=(500, 2))
    env._sim.set_particles(0, np.concatenate([a, b]))
    # Equal clusters at ±50 mm per axis: var per axis = 50² + 1 → √trace Σ ≈ √(2·2501) ≈ 70.7 mm.
    assert env.belief.spread() == pytest.approx(np.sqrt(2 * 2501.0), rel=0.01)
    obs = env._sim.observation()[0]
    assert env.observation_space.contains(obs)
    hist = obs[12:76].reshape(8, 8)  # allocentric 20 mm cells over ±80 mm
    assert hist[1, 1] == pytest.approx(0.5, abs=0.02) and hist[6, 6] == pytest.approx(0.5, abs=0.02)
    assert not env._sim.info()["success"][0]
    for _ in range(5):
        obs, _, term, trunc, info = env.step(np.array([0.3, -0.2], np.float32))
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        assert np.all(np.isfinite(env.belief.particles)) and np.isfinite(info["spread_mm"])
        if term or trunc:
            break
    mean, std = env.predicted_reading_model(env.belief.particles, np.zeros((16, 2)))
    assert np.all(np.isfinite(mean)) and np.all(std > 0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(layout="moon"), "layout"),
        (dict(observation="pixels"), "observation"),
        (dict(sensor_model="magic"), "sensor_model"),
        (dict(n_particles=0), "n_particles"),
        (dict(max_observations=0), "max_observations"),
        (dict(success_spread_mm=-1.0), "success_spread_mm"),
        (dict(action_type="joystick"), "action_type"),
        (dict(position_blur_mm=-2.0), "position_blur_mm"),
    ],
)
def test_bad_kwargs_raise_clear_errors(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        GlobalEnv(**kwargs)


def test_rgb_render_returns_frame() -> None:
    env = gym.make(GLOBAL_ID, n_particles=300, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0], np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8 and frame.std() > 10
    env.close()


def test_cli_eev_global_writes_a_png(tmp_path) -> None:
    from cli_inproc import run_cli  # the command in this process

    out = tmp_path / "fig14.png"
    res = run_cli("eev", "--env", "global", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert out.stat().st_size > 10_000 and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_table2_statistics_with_the_paper_controllers() -> None:
    """Table 2 (§6.5) in small: rnd-wlk and min-var, 20 seeded trials each, calibrated map model."""
    agent_mod = pytest.importorskip("electroloc_gym.baselines.agent")
    env = gym.make(GLOBAL_ID)
    for name, min_success, max_median_err, max_median_steps in (("rnd-wlk", 17, 2.5, 20), ("min-var", 18, 3.0, 9)):
        ok, errors, steps = 0, [], []
        for k in range(20):
            agent = agent_mod.make_agent(name)
            obs, info = env.reset(seed=1000 + k)
            agent.seed(k)
            agent.reset(env)
            term = trunc = False
            while not (term or trunc):
                action, _ = agent.predict(obs)
                obs, _, term, trunc, info = env.step(action)
            ok += bool(term and info["success"])
            errors.append(info["error_mm"])
            steps.append(info["n_observations"])
        assert ok >= min_success, (name, ok)
        assert np.median(errors) <= max_median_err, (name, np.median(errors))
        assert np.median(steps) <= max_median_steps, (name, np.median(steps))


def test_bench_runs_table2_layout(tmp_path) -> None:
    """`electroloc bench --env global`: the runner's Table-2 path (serial backend, 2 trials of rnd-wlk)."""
    pytest.importorskip("electroloc_gym.baselines.agent")
    from electroloc_gym.bench.runner import BenchConfig, run_benchmark, trial_seeds

    GLOBAL_CONDITION = "six-cylinders"  # the map's name (info['condition'])

    config = BenchConfig(agents=("rnd-wlk",), conditions=("ignored",), trials=2, env_id="ElectroLocGlobal-v0")
    assert config.conditions == (GLOBAL_CONDITION,)
    assert trial_seeds(0, GLOBAL_CONDITION, 1) != trial_seeds(0, "salt-delrin-38.1", 1)
    summary = run_benchmark(config, tmp_path, workers=1, backend="serial", progress=False, log=None)
    row = next(r for r in summary["rows"] if r["condition"] == GLOBAL_CONDITION and r["agent"] == "rnd-wlk")
    assert row["trials"] == 2
    table = (tmp_path / "table.md").read_text()
    assert "Table 2" in table and "48(2)" in table and "11.8/11" in table
    recs = [line for line in (tmp_path / "trials.jsonl").read_text().splitlines() if line]
    assert len(recs) == 2
    import json

    for rec in map(json.loads, recs):  # error is measured against the true final carriage position
        if rec["estimate"] is not None:
            est, tgt = np.asarray(rec["estimate"]), np.asarray(rec["target"])
            assert rec["error_mm"] == pytest.approx(float(np.hypot(*(est - tgt))))
