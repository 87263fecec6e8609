"""ElectroLocTrack-v0: the moving target, the filter's motion model, the tracking metric and the checks."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.engines.numba_core.step import Simulation
from electroloc_gym.engines.numba_core.track_task import (
    CAPTURE_DISTANCE_MM,
    MAX_TARGET_SPEED_MM,
    MOTION_MODELS,
    TARGET_MOTIONS,
    reflect,
)
from electroloc_gym.kernels.streams import normal_table, table_normal_indices
from electroloc_gym.world.conditions import Condition, get_condition
from tests.vector_equivalence import assert_native_equals_sync

ID = "ElectroLocTrack-v0"
SMALL: dict[str, Any] = {"n_particles": 200, "sensor_model": "analytic", "max_observations": 12}
TRACK_KEYS = ("tracking_error_mm", "carriage_distance_mm", "captured", "error_mm", "spread_mm")


def _sim(n: int, **kw: Any) -> Simulation:
    params = EnvParams.from_kwargs("track", {**SMALL, **kw}, ID)
    sim = Simulation(params, n)
    for i in range(n):
        sim.seed(i, 100 + i)
    sim.reset()
    return sim


def test_check_env_gymnasium_and_sb3() -> None:
    env = gym.make(ID, **SMALL)
    check_env(env.unwrapped)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(gym.make(ID, **SMALL).unwrapped, warn=True)
    assert env.unwrapped.params.task == "track"
    assert gym.make(ID).unwrapped.params.max_observations == 70  # the entry's default episode length


def test_same_seed_same_episode_and_different_seeds_differ() -> None:
    def run(seed: int) -> list[Any]:
        env = gym.make(ID, **SMALL, target_motion="random_walk", target_speed_mm=3.0)
        env.action_space.seed(7)
        obs, info = env.reset(seed=seed)
        out = [obs, info["target_mm"]]
        for _ in range(11):
            obs, r, te, tr, info = env.step(env.action_space.sample())
            out += [obs, r, info["target_mm"], info["tracking_error_mm"]]
        return out

    a, b, c = run(3), run(3), run(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("motion", ["random_walk", "swimmer"])
def test_vector_env_equals_single_envs(mode: AutoresetMode, motion: str) -> None:
    kwargs = {**SMALL, "max_observations": 6, "target_motion": motion, "target_speed_mm": 4.0, "condition": "random"}
    assert_native_equals_sync(ID, kwargs, mode, TRACK_KEYS, n=3, steps=14, min_ended=3)


def test_vector_env_type_and_info_shapes() -> None:
    vec = gym.make_vec(ID, num_envs=3, vectorization_mode="vector_entry_point", **SMALL)
    assert type(vec.unwrapped).__name__ == "TrackVectorEnv"
    _, info = vec.reset(seed=0)
    assert info["target_mm"].shape == (3, 2) and info["captured"].dtype == bool
    assert np.array_equal(vec.unwrapped.target_mm, info["target_mm"])
    vec.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"target_motion": "levy"}, r"target_motion must be one of \['random_walk', 'swimmer'\]"),
        ({"target_motion": 3}, r"target_motion must be one of"),
        ({"target_speed_mm": -0.1}, r"target_speed_mm must be a finite number ≥ 0 and ≤ 20"),
        ({"target_speed_mm": 20.5}, r"target_speed_mm must be a finite number ≥ 0 and ≤ 20"),
        ({"target_speed_mm": float("nan")}, r"target_speed_mm must be a finite number"),
        ({"target_speed_mm": True}, r"target_speed_mm must be a finite number"),
        ({"turn_std_rad": -1.0}, r"turn_std_rad must be a finite number ≥ 0 and ≤ 3.14159"),
        ({"turn_std_rad": 4.0}, r"turn_std_rad must be a finite number ≥ 0 and ≤ 3.14159"),
        ({"motion_model": "kalman"}, r"motion_model must be one of \['random_walk', 'static', 'swimmer'\]"),
        ({"motion_step_mm": 21.0}, r"motion_step_mm must be a finite number ≥ 0 and ≤ 20"),
        ({"motion_step_mm": "big"}, r"motion_step_mm must be a finite number"),
        # options that contradict each other: one set to a value that has no effect under the other
        (
            {"target_motion": "random_walk", "turn_std_rad": 2.0},
            r"^turn_std_rad applies only when target_motion is 'swimmer' \(the random walk has no heading\); got "
            r"target_motion='random_walk' with turn_std_rad=2\.0: leave turn_std_rad at its default 0\.5 or "
            r"choose target_motion='swimmer'$",
        ),
        (
            {"motion_model": "static", "motion_step_mm": 5.0},
            r"^motion_step_mm applies only when motion_model is 'random_walk' \(only the random-walk filter takes a "
            r"Gaussian step\); got motion_model='static' with motion_step_mm=5\.0: leave motion_step_mm None or "
            r"choose motion_model='random_walk'$",
        ),
        (
            {"motion_model": "swimmer", "motion_step_mm": 2.0},
            r"^motion_step_mm applies only when motion_model is 'random_walk' .*got motion_model='swimmer'",
        ),
        # the swimmer filter's own options: their ranges, and only under motion_model="swimmer"
        (
            {"motion_turn_std_rad": 0.3},
            r"^motion_turn_std_rad applies only when motion_model is 'swimmer' \(only the swimmer filter's particles "
            r"have a heading\); got motion_model='random_walk' with motion_turn_std_rad=0\.3: leave "
            r"motion_turn_std_rad None or choose motion_model='swimmer'$",
        ),
        (
            {"motion_model": "static", "motion_speed_mm": (0.5, 2.0)},
            r"^motion_speed_mm applies only when motion_model is 'swimmer' \(only the swimmer filter's particles have "
            r"a speed\); got motion_model='static' with motion_speed_mm=\(0\.5, 2\.0\)",
        ),
        (
            {"motion_model": "swimmer", "motion_turn_std_rad": 4.0},
            r"^motion_turn_std_rad must be a finite number ≥ 0 and ≤ 3.14159",
        ),
        ({"motion_model": "swimmer", "motion_turn_std_rad": "wide"}, r"^motion_turn_std_rad must be a finite number"),
        (
            {"motion_model": "swimmer", "motion_speed_mm": (2.0, 1.0)},
            r"^motion_speed_mm must be \(low, high\) with low ≤ high, got \(2\.0, 1\.0\)$",
        ),
        (
            {"motion_model": "swimmer", "motion_speed_mm": (0.0, 25.0)},
            r"^motion_speed_mm must be a finite number ≥ 0 and ≤ 20, got 25\.0$",
        ),
        (
            {"motion_model": "swimmer", "motion_speed_mm": 1.0},
            r"^motion_speed_mm must be a tuple of 2 numbers in \[0, 20\] mm, got 1\.0$",
        ),
        (
            {"motion_model": "swimmer", "motion_speed_mm": (1.0, float("nan"))},
            r"^motion_speed_mm must be a finite number",
        ),
        ({"motion_model": "static", "motion_step_mm": 0.0}, r"^motion_step_mm applies only when motion_model is"),
        (
            {"target_motion": "random_walk", "turn_std_rad": 0.0, "motion_model": "static", "motion_step_mm": 1.0},
            r"^turn_std_rad applies only when target_motion is 'swimmer'",  # the first of two contradictions
        ),
    ],
)
def test_every_bad_motion_option_is_one_clear_error(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(ID, **SMALL, **kwargs)
    with pytest.raises(ValueError, match=match):
        gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", **SMALL, **kwargs)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"target_motion": "random_walk"},  # turn_std_rad at its default: no contradiction
        {"target_motion": "random_walk", "turn_std_rad": 0.5},  # the default given explicitly
        {"motion_model": "static"},
        {"motion_model": "static", "motion_step_mm": None},
        {"target_motion": "swimmer", "turn_std_rad": 2.0, "motion_model": "random_walk", "motion_step_mm": 5.0},
        {"target_motion": "random_walk", "motion_step_mm": 5.0},  # a model mismatch, allowed
        {"target_speed_mm": 0.0, "turn_std_rad": 1.0},  # a still swimmer: the speed sweep's end, allowed
        {"motion_model": "swimmer"},
        {"motion_model": "swimmer", "motion_turn_std_rad": None, "motion_speed_mm": None},
        {"motion_model": "swimmer", "motion_turn_std_rad": 0.0, "motion_speed_mm": [1.0, 1.0]},  # one speed
        {"motion_model": "swimmer", "target_motion": "random_walk", "motion_speed_mm": (0.0, 20.0)},  # a mismatch
    ],
)
def test_options_that_do_not_contradict_each_other_are_taken(kwargs: dict[str, Any]) -> None:
    assert gym.make(ID, **SMALL, **kwargs).unwrapped.params.task == "track"
    gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", **SMALL, **kwargs).close()


def test_motion_options_belong_to_the_track_env_only() -> None:
    with pytest.raises(ValueError, match=r"unexpected argument\(s\) \['target_speed_mm'\]"):
        gym.make("ElectroLoc-v0", target_speed_mm=2.0)


def test_torch_engine_refuses_the_track_env() -> None:
    with pytest.raises(ValueError, match="backend"):
        gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", backend="torch", **SMALL)


def _box_condition(half_mm: float) -> Condition:
    """fresh-steel-12.7 in an allowed box of ±``half_mm`` (the carriage starting anywhere in it, the target
    at the centre).
    """
    return dataclasses.replace(
        get_condition("fresh-steel-12.7"),
        allowed_half_width_mm=half_mm,
        start_half_width_mm=half_mm,
        target_xy_mm=(0, 0),
    )


def _motion_kwargs(motion: str, speed: float, turn: float = 0.5) -> dict[str, Any]:
    """The target's motion options (``turn_std_rad`` only for the swimmer: the random walk has no heading)."""
    return {
        "target_motion": motion,
        "target_speed_mm": speed,
        **({"turn_std_rad": turn} if motion == "swimmer" else {}),
    }


def _widest_excursion(sim: Simulation, readings: int) -> float:
    """Step ``readings`` times without moving; the largest |coordinate| of the target over the box's
    half-width (≤ 1: never out of the box), the particles checked against the box at every reading too.
    """
    h = sim.state.half_mm
    worst = float(np.max(np.abs(sim.state.target_mm) / h[:, None]))
    for _ in range(readings):
        sim.step(np.zeros((sim.num_envs, 2)))
        worst = max(worst, float(np.max(np.abs(sim.state.target_mm) / h[:, None])))
        assert np.all(np.abs(sim.state.particles_mm) <= h[:, None, None].astype(np.float32))
    return worst


def _old_single_fold(x: np.ndarray, half: Any) -> np.ndarray:
    """The single fold at the crossed wall (exact for steps shorter than 2·half): the reference the fold
    must equal bit for bit there.
    """
    return np.where(x > half, 2 * half - x, np.where(x < -half, -2 * half - x, x))


def test_reflect_folds_at_the_crossed_wall() -> None:
    x, flipped = reflect(np.array([55.0, -53.0, 10.0, 50.0, 160.0, -275.0, 210.0]), 50.0)
    # 160 → 2·50 − 160 = −60 → −2·50 + 60 = −40 (two walls: the heading back as it was); −275 → −75 → −25
    assert np.array_equal(x, [45.0, -47.0, 10.0, 50.0, -40.0, -25.0, 10.0])
    assert flipped.tolist() == [True, True, False, False, False, True, False]


@settings(max_examples=300, deadline=None)
@given(
    x=st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=40),
    half=st.floats(1e-3, 1e3),
)
def test_reflect_is_the_triangle_wave_and_the_single_fold_where_that_was_exact(x: list[float], half: float) -> None:
    """The fold of a straight path in [−H, H]: the triangle wave of period 4H (closed form), always inside
    the box in floating point, reflected an odd number of times exactly where ⌊(x + H)/2H⌋ is odd, and bit
    for bit the single fold for |x| ≤ 3H (a step shorter than 2H from inside the box).
    """
    xs = np.array(x)
    got, flipped = reflect(xs, half)
    closed = np.abs(np.mod(xs - half, 4 * half) - 2 * half) - half
    tol = 8 * np.finfo(float).eps * (np.abs(xs) + half)
    assert np.all(np.abs(got - closed) <= tol), (xs, got, closed)
    assert np.all(np.abs(got) <= half)
    crossings = np.floor((xs + half) / (2 * half))
    d = np.mod(xs + half, 2 * half)
    exact = np.minimum(d, 2 * half - d) > tol  # not on a wall (where the parity is either)
    assert np.array_equal(flipped[exact], (np.mod(crossings, 2) == 1)[exact])
    old = _old_single_fold(xs, half)
    near = (np.abs(xs) <= 3 * half) & (np.abs(old) <= half)
    assert np.array_equal(got[near], old[near])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    half=st.floats(0.5, 60.0),
    speed=st.floats(0.0, MAX_TARGET_SPEED_MM),
    motion=st.sampled_from(TARGET_MOTIONS),
    turn=st.floats(0.0, math.pi),
    model=st.sampled_from(MOTION_MODELS),
    seed=st.integers(0, 2**20),
)
def test_the_target_never_leaves_its_box(
    half: float, speed: float, motion: str, turn: float, model: str, seed: int
) -> None:
    """Any box, any step the options allow, either motion, either filter model: the true target and every
    particle stay in the allowed box over many readings.
    """
    kw = {**_motion_kwargs(motion, speed, turn), "motion_model": model, "n_particles": 20, "max_observations": 400}
    sim = _sim(3, condition=_box_condition(half), **kw)
    for i in range(3):
        sim.seed(i, seed + i)
    sim.reset()
    assert _widest_excursion(sim, 300) <= 1.0


@pytest.mark.parametrize(
    ("motion", "half", "speed"),
    [("swimmer", 3.0, 20.0), ("swimmer", 3.0, 7.0), ("random_walk", 12.0, 20.0), ("random_walk", 3.0, 20.0)],
)
def test_a_box_smaller_than_the_step_keeps_the_target(motion: str, half: float, speed: float) -> None:
    """The reproducers: a ±3 mm box with a swimmer of 20 mm per reading (drifted ≈ 640 mm in 900 readings),
    and the random walk's Gaussian tails (RMS 20 mm) in a ±12 mm box.
    """
    kw = {**_motion_kwargs(motion, speed), "n_particles": 20, "max_observations": 1000}
    sim = _sim(4, condition=_box_condition(half), **kw)
    assert _widest_excursion(sim, 900) <= 1.0


def _steps_from_origin(sim: Simulation, n_steps: int) -> np.ndarray:
    """The target's steps from the tank's centre (set there before every step, so no wall is reached)."""
    out = []
    for _ in range(n_steps):
        sim.state.target_mm[:] = 0.0
        sim.step(np.zeros((sim.num_envs, 2)))
        out.append(sim.state.target_mm.copy())
    return np.concatenate(out)


def test_random_walk_step_std_is_speed_over_root_two() -> None:
    speed = 3.0
    sim = _sim(8, target_motion="random_walk", target_speed_mm=speed, max_observations=1000)
    d = _steps_from_origin(sim, 500)  # 4000 steps of 2 axes
    sigma = speed / math.sqrt(2)
    assert abs(d.std(axis=0) - sigma).max() < 0.04 * sigma  # the sample std's std ≈ σ/√8000 ≈ 1.1 %
    assert abs(d.mean(axis=0)).max() < 4 * sigma / math.sqrt(d.shape[0])
    assert abs(np.sqrt(np.mean(np.sum(d * d, axis=1))) - speed) < 0.03 * speed  # RMS step = the speed


def test_swimmer_speed_is_constant_and_its_turns_have_the_given_std() -> None:
    speed, turn = 2.5, 0.4
    sim = _sim(8, target_motion="swimmer", target_speed_mm=speed, turn_std_rad=turn, max_observations=1000)
    steps = []
    for _ in range(400):
        sim.state.target_mm[:] = 0.0
        sim.step(np.zeros((8, 2)))
        steps.append(sim.state.target_mm.copy())
    d = np.stack(steps)  # (T, N, 2)
    np.testing.assert_allclose(np.hypot(d[..., 0], d[..., 1]), speed, rtol=1e-12)
    heading = np.arctan2(d[..., 1], d[..., 0])
    turns = np.angle(np.exp(1j * np.diff(heading, axis=0))).ravel()  # wrapped to (−π, π]
    assert abs(turns.std() - turn) < 0.04 * turn
    assert abs(turns.mean()) < 4 * turn / math.sqrt(turns.size)


def _jittered_std(**kw: Any) -> float:
    """The per-axis std of a cloud of identical particles after one update (all weights equal: the
    resampled cloud is the point, the spread is the jitter's).
    """
    sim = _sim(2, n_particles=4000, **kw)
    s = sim.state
    s.particles_mm[:] = 0.0
    g = np.random.default_rng(0)
    jitter = np.stack([table_normal_indices(g, 2 * 4000) for _ in range(2)])
    ids = np.arange(2)
    assert sim.task.assimilate(s, ids, np.zeros(2), np.full(2, 0.5), jitter, normal_table()) < 0
    return float(s.particles_mm.astype(float).std(axis=2).mean())


def test_filter_motion_step_is_in_the_jitter() -> None:
    """The random walk's step (std σ_f = motion_step_mm/√2 per axis) adds to the paper's 1 mm jitter."""
    sigma_f = 4.0 / math.sqrt(2)
    assert _jittered_std(motion_step_mm=4.0) == pytest.approx(math.hypot(1.0, sigma_f), rel=0.03)
    assert _jittered_std(motion_model="static", target_speed_mm=4.0) == pytest.approx(1.0, rel=0.03)
    assert _jittered_std(target_speed_mm=2.0) == pytest.approx(math.hypot(1.0, math.sqrt(2.0)), rel=0.03)


def test_predicted_particles_are_the_belief_itself() -> None:
    """Between steps the belief is already the next reading's predicted belief: the prediction is the cloud."""
    env = gym.make(ID, **SMALL, target_speed_mm=2.0)
    env.reset(seed=1)
    core = env.unwrapped
    parts = core.belief.particles
    moves = np.array([[0.0, 0.0], [5.0, -5.0]])
    pred = core.predicted_particles_mm(parts, moves)
    assert pred.shape == (2, *parts.shape)
    np.testing.assert_array_equal(pred[1], parts)


def test_tracking_metric_capture_reward_and_episode_end() -> None:
    env = gym.make(ID, **{**SMALL, "max_observations": 10}, target_speed_mm=2.0)
    env.action_space.seed(0)
    _, info = env.reset(seed=11)
    errors = {int(info["n_observations"]): float(info["error_mm"])}
    terminated = truncated = False
    while not (terminated or truncated):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        errors[int(info["n_observations"])] = float(info["error_mm"])
        d = np.asarray(info["estimate_mm"]) - info["target_mm"]
        assert float(info["error_mm"]) == pytest.approx(math.hypot(*d))
        assert reward == pytest.approx(-float(info["error_mm"]) / CAPTURE_DISTANCE_MM)
        dist = math.hypot(*(np.asarray(info["position_mm"]) - info["target_mm"]))
        assert float(info["carriage_distance_mm"]) == pytest.approx(dist)
        assert bool(info["captured"]) == (dist <= CAPTURE_DISTANCE_MM)
    assert not terminated and truncated and info["n_observations"] == 10  # never terminated: a fixed length
    second = [errors[n] for n in range(6, 11)]  # readings 6..10 of 10: the second half
    assert float(info["tracking_error_mm"]) == pytest.approx(float(np.mean(second)), rel=1e-12)


def test_the_told_motion_model_tracks_better_than_the_static_filter() -> None:
    """The motion model matters: at 4 mm per reading, pursuit on the filter told the random walk follows the
    target better than on the paper's static filter (the same six seeds; their means 15 and 29 mm).
    """
    from electroloc_gym.baselines.agent import make_agent
    from electroloc_gym.baselines.rollout import run_episode

    def mean_error(model: str) -> float:
        kw = {"n_particles": 500, "sensor_model": "analytic", "max_observations": 30, "target_speed_mm": 4.0}
        env = gym.make(ID, **kw, target_motion="random_walk", motion_model=model, condition="fresh-steel-38.1")
        errs = [run_episode(env, make_agent("pursuit"), s, agent_seed=s).info["tracking_error_mm"] for s in range(6)]
        return float(np.mean(errs))

    assert mean_error("random_walk") < 0.75 * mean_error("static")


# ---- the controllers ------------------------------------------------------------------------------
def test_pursuit_moves_toward_the_predicted_mean_through_the_agent_view() -> None:
    from electroloc_gym.baselines.agent import make_agent

    env = gym.make(ID, **SMALL)
    env.reset(seed=2)
    agent = make_agent("pursuit", seed=0)
    agent.reset(env)
    core = env.unwrapped
    pred = core.predicted_particles_mm(core.belief.particles, np.zeros(2))
    goal = pred.astype(float).mean(axis=0)
    lo, hi = core.move_bounds_mm
    want = np.clip(goal - core.position_mm, lo, hi)
    action, _ = agent.predict(None)
    np.testing.assert_allclose(action, want / 10.0, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="pursuit needs a belief over the target's position"):
        g = gym.make("ElectroLocGlobal-v0", n_particles=50, sensor_model="analytic")
        g.reset(seed=0)
        agent.reset(g)
        agent.predict(None)


def test_the_controllers_run_through_the_agent_view() -> None:
    from electroloc_gym.baselines.agent import make_agent

    env = gym.make(ID, **SMALL, target_speed_mm=3.0)
    env.reset(seed=4)
    for name in ("rnd-wlk", "min-var", "pursuit"):
        agent = make_agent(name, seed=1)
        agent.reset(env)
        action, _ = agent.predict(None)
        assert env.action_space.contains(action)


def test_pursuit_keeps_closer_to_a_slow_target_than_the_random_walk() -> None:
    from electroloc_gym.baselines.agent import make_agent
    from electroloc_gym.baselines.rollout import run_episode

    def distance(name: str) -> float:
        env = gym.make(ID, n_particles=500, sensor_model="analytic", max_observations=40, condition="fresh-steel-38.1")
        out = []
        for seed in range(3):
            ep = run_episode(env, make_agent(name, seed=seed), seed, agent_seed=seed)
            out.append(float(ep.info["carriage_distance_mm"]))
        return float(np.mean(out))

    assert distance("pursuit") < distance("rnd-wlk")


# ---- the benchmark row ----------------------------------------------------------------------------
def _bench_args(argv: list[str]) -> Any:
    import argparse

    from electroloc_gym.bench import bench_command

    parser = argparse.ArgumentParser()
    bench_command.add_arguments(parser)
    return parser.parse_args(argv)


def test_bench_track_row_table_and_resume(tmp_path, capsys) -> None:
    import json

    from electroloc_gym.bench import bench_command

    out = tmp_path / "run"
    argv = ["--env", "track", "--trials", "3", "--conditions", "fresh-steel-12.7,salt-steel-38.1"]
    argv += ["--backend", "serial", "--workers", "1", "--out", str(out), "--no-progress"]
    argv += ["--sensor-model", "analytic", "--n-particles", "300", "--max-observations", "8"]
    assert bench_command.run(_bench_args(argv)) == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["env_id"] == ID
    records = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines()]
    # the row's controllers, then the shipped policy trained on this env (a default run's agents)
    assert len(records) == 24 and {r["agent"] for r in records} == {"rnd-wlk", "min-var", "pursuit", "ppo-belief-track"}
    assert all(r["readings"] == 8 and r["ended_by"] == "cap" and not r["success"] for r in records)
    for row in summary["rows"]:
        recs = [
            r["shape"] for r in records if r["agent"] == row["agent"] and row["condition"] in ("all", r["condition"])
        ]
        errs = [s["tracking_error_mm"] for s in recs]
        assert row["tracking_trials"] == len(recs)
        assert row["tracking_error_median_mm"] == pytest.approx(float(np.median(errs)))
        assert row["tracking_error_q25_mm"] <= row["tracking_error_median_mm"] <= row["tracking_error_q75_mm"]
        assert row["captures"] == sum(s["captured"] for s in recs)
        assert row["capture_rate_lo"] <= row["capture_rate"] <= row["capture_rate_hi"]
    table = (out / "table.md").read_text()
    assert "Tracking error median (mm)" in table and "Capture rate 95 % CI" in table and "pursuit" in table
    capsys.readouterr()
    assert bench_command.run(_bench_args([*argv, "--resume"])) == 0
    printed = capsys.readouterr()
    assert "24 already done, 0 to run" in printed.out + printed.err  # resumed: nothing ran again
    again = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines()]
    key = lambda r: (r["condition"], r["agent"], r["trial"])  # noqa: E731
    assert sorted(map(key, again)) == sorted(map(key, records))


def test_a_bad_tracking_record_is_refused() -> None:
    from electroloc_gym.bench.schema import _shape_problem

    good = {"tracking_error_mm": 3.0, "carriage_distance_mm": 12.0, "captured": False}
    assert _shape_problem(good) is None and _shape_problem(None) is None
    for bad in ({**good, "captured": "no"}, {**good, "tracking_error_mm": -1.0}, {**good, "radius_estimate_mm": 3.0}):
        assert "'shape' must be null or an object with exactly the keys" in (_shape_problem(bad) or "")


def test_a_reset_sets_the_tasks_own_arrays_back_over_their_declared_fields(monkeypatch) -> None:
    """Reset and autoreset put every field of the task's ``State`` (``State.task``) back to its fill value,
    row by row, before the task's draws: a field a task adds is reset without the step naming it."""
    import dataclasses

    from electroloc_gym.contract.task_spec import state_array
    from electroloc_gym.engines.numba_core import step as numba_step
    from electroloc_gym.engines.numba_core.track_task import TrackState, TrackTask

    @dataclasses.dataclass
    class Grown(TrackState):
        misses: np.ndarray = state_array(np.int64, fill=-7)

    class GrownTask(TrackTask):
        State = Grown

    monkeypatch.setattr(numba_step, "make_task", GrownTask)
    sim = _sim(3, max_observations=3)
    own = Grown.of(sim.state)
    assert own.misses.tolist() == [-7, -7, -7]
    own.misses[:] = 5
    own.track_error_count[:] = 9
    sim.reset(np.array([1]))
    assert own.misses.tolist() == [5, -7, 5] and own.track_error_count.tolist() == [9, 0, 9]
    own.misses[:] = 5
    moves = np.zeros((3, 2))
    for _ in range(2):
        sim.step(moves)  # the third reading ends every episode
    assert sim.state.done.all()
    sim.step(moves)  # next_step autoreset of all three
    assert own.misses.tolist() == [-7, -7, -7]


# ---- the swimmer filter: a belief over the target's position and velocity -----------------------------------
SWIM: dict[str, Any] = {"motion_model": "swimmer"}


def test_check_env_on_the_swimmer_filter_both_observations() -> None:
    for observation, dim in (("belief", 85), ("raw", 3)):
        env = gym.make(ID, **SMALL, **SWIM, observation=observation)
        check_env(env.unwrapped)
        assert env.observation_space.shape == (dim,)
        obs, info = env.reset(seed=0)
        assert obs.shape == (dim,) and env.unwrapped.belief.particles.shape == (200, 4)
        assert info["velocity_mean_mm"].shape == (2,) and float(info["velocity_spread_mm"]) > 0
    plain = gym.make(ID, **SMALL)
    _, info = plain.reset(seed=0)
    assert plain.observation_space.shape == (81,) and "velocity_mean_mm" not in info  # the other models: as before


def test_the_swimmer_filter_same_seed_same_episode() -> None:
    def run(seed: int) -> list[Any]:
        env = gym.make(ID, **SMALL, **SWIM, motion_speed_mm=(0.5, 3.0), target_speed_mm=2.0)
        env.action_space.seed(7)
        obs, info = env.reset(seed=seed)
        out = [obs, info["velocity_mean_mm"], env.unwrapped.belief.particles.copy()]
        for _ in range(11):
            obs, r, te, tr, info = env.step(env.action_space.sample())
            out += [obs, r, info["target_mm"], info["velocity_mean_mm"], info["velocity_spread_mm"]]
        return [*out, env.unwrapped.belief.particles.copy()]

    a, b, c = run(3), run(3), run(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_the_swimmer_filter_vector_env_equals_single_envs(mode: AutoresetMode, sensor_model: str) -> None:
    kwargs = {**SMALL, **SWIM, "max_observations": 6, "target_speed_mm": 4.0, "condition": "random"}
    kwargs.update(sensor_model=sensor_model, motion_speed_mm=(1.0, 6.0), motion_turn_std_rad=0.3)
    keys = (*TRACK_KEYS, "velocity_mean_mm", "velocity_spread_mm")
    assert_native_equals_sync(ID, kwargs, mode, keys, n=3, steps=14, min_ended=3)


def _swimmer_sim(n: int, half_mm: float = 50.0, **kw: Any) -> Simulation:
    return _sim(n, condition=_box_condition(half_mm), **SWIM, **kw)


def test_a_particle_steps_by_its_velocity_in_closed_form() -> None:
    """Without noise a particle at p with speed s and heading θ is at p + k·s·(cos θ, sin θ) after k steps, and
    a particle that meets a wall is folded back (the triangle wave), its heading mirrored; the agents'
    prediction is the engine's step bit for bit.
    """
    sim = _swimmer_sim(1, max_observations=400)
    s, m = sim.state, sim.state.n_particles
    rng = np.random.default_rng(0)
    x0 = rng.uniform(-5, 5, (2, m)).astype(np.float32)
    speed = rng.uniform(0.0, 1.5, m).astype(np.float32)
    heading = rng.uniform(-np.pi, np.pi, m).astype(np.float32)
    s.particles_mm[0], s.shape_particles[0, 0], s.shape_particles[0, 1] = x0, speed, heading
    before = np.concatenate([s.particles_mm[0], s.shape_particles[0]]).T.copy()
    predicted = sim.task.particles_after_move(s, 0, before, np.zeros((3, 2)))
    k = 20  # at most 30 mm from within ±5 mm: no wall of the ±50 mm box
    for step in range(k):
        sim.task.move(s, slice(None), np.zeros((1, 2)))
        if step == 0:
            after = np.concatenate([s.particles_mm[0], s.shape_particles[0]]).T
            assert all(np.array_equal(p, after) for p in predicted)  # the prediction is the engine's step
    v = speed.astype(float) * np.stack([np.cos(heading.astype(float)), np.sin(heading.astype(float))])
    np.testing.assert_allclose(s.particles_mm[0], x0 + k * v, atol=2e-5 * k)
    np.testing.assert_array_equal(s.shape_particles[0, 0], speed)  # the step changes no speed
    # toward the east wall: 3 mm per step from x = 40 mm, heading 0; after 7 steps x = 61 → 2·50 − 61 = 39 mm
    s.particles_mm[0, 0], s.particles_mm[0, 1] = 40.0, 0.0
    s.shape_particles[0, 0], s.shape_particles[0, 1] = 3.0, 0.0
    for _ in range(7):
        sim.task.move(s, slice(None), np.zeros((1, 2)))
    np.testing.assert_allclose(s.particles_mm[0, 0], 39.0, atol=1e-5)
    np.testing.assert_allclose(np.abs(s.shape_particles[0, 1]), np.pi, atol=1e-6)  # mirrored: heading west


def test_the_swimmer_filter_particles_stay_in_the_box_and_their_speeds_in_the_prior() -> None:
    for half, speed in ((3.0, 20.0), (12.0, 7.0), (50.0, 1.0)):
        sim = _swimmer_sim(3, half, target_speed_mm=speed, motion_speed_mm=(0.0, 20.0), max_observations=400)
        assert _widest_excursion(sim, 150) <= 1.0  # the target and every particle, every reading
        v = sim.state.shape_particles
        assert np.all((v[:, 0] >= 0.0) & (v[:, 0] <= 20.0)) and np.all(np.isfinite(v))


def test_the_swimmer_filters_jitter_turns_the_heading_by_its_turn_std() -> None:
    """After one update of identical hypotheses the spread is the jitter's: 1 mm per position axis, the turn
    std on the heading, :data:`SPEED_JITTER_MM` on a speed drawn from a range (none for one speed).
    """
    from electroloc_gym.engines.numba_core.track_task import SPEED_JITTER_MM

    def spreads(**kw: Any) -> np.ndarray:
        sim = _sim(2, n_particles=4000, **SWIM, **kw)
        s = sim.state
        s.particles_mm[:] = 0.0
        s.shape_particles[:, 0], s.shape_particles[:, 1] = 1.0, 0.5
        g = np.random.default_rng(0)
        jitter = np.stack([table_normal_indices(g, 4 * 4000) for _ in range(2)])
        assert sim.task.assimilate(s, np.arange(2), np.zeros(2), np.full(2, 0.5), jitter, normal_table()) < 0
        cloud = np.concatenate([s.particles_mm, s.shape_particles], axis=1).astype(float)
        return cloud.std(axis=2).mean(axis=0)

    got = spreads(motion_turn_std_rad=0.3, motion_speed_mm=(0.0, 2.0))
    np.testing.assert_allclose(got, [1.0, 1.0, SPEED_JITTER_MM, 0.3], rtol=0.03)
    got = spreads()  # one speed (the target's), the target's turn std (0.5 rad)
    np.testing.assert_allclose(got[[0, 1, 3]], [1.0, 1.0, 0.5], rtol=0.03)
    assert got[2] == 0.0


def test_the_velocity_info_and_observation_are_the_particles() -> None:
    from electroloc_gym.engines.numba_core.track_task import sin_cos

    env = gym.make(ID, **SMALL, **SWIM, motion_speed_mm=(0.0, 4.0))
    env.reset(seed=5)
    for _ in range(4):
        obs, _, _, _, info = env.step(np.array([0.3, -0.2], dtype=np.float32))
    p = env.unwrapped.belief.particles.astype(float)
    v = p[:, 2:3] * np.stack([np.cos(p[:, 3]), np.sin(p[:, 3])], axis=1)
    np.testing.assert_allclose(info["velocity_mean_mm"], v.mean(axis=0), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(info["velocity_spread_mm"], math.sqrt(v.var(axis=0).sum()), rtol=1e-9)
    np.testing.assert_allclose(obs[81:85], np.clip([*v.mean(axis=0), *v.std(axis=0)], -1, 1) / 4.0, rtol=1e-5)
    a = np.linspace(-40.0, 40.0, 10001)
    s, c = sin_cos(a)
    assert np.abs(s - np.sin(a)).max() < 1e-14 and np.abs(c - np.cos(a)).max() < 1e-14


def test_the_swimmer_filter_learns_a_persistent_targets_velocity() -> None:
    """A swimmer that barely turns (0.05 rad per reading, 3 mm per reading) followed by pursuit: at the end the
    belief's mean velocity points along the target's true heading (fixed seeds: cosines 0.95, 0.96, 0.45, 0.45;
    a belief that had learnt nothing would point anywhere).
    """
    from electroloc_gym.baselines.agent import make_agent
    from electroloc_gym.baselines.rollout import run_episode

    kw = {"n_particles": 1000, "sensor_model": "analytic", "max_observations": 40, "condition": "fresh-steel-38.1"}
    env = gym.make(ID, **kw, **SWIM, target_speed_mm=3.0, turn_std_rad=0.05)
    cosines = []
    for seed in range(4):
        ep = run_episode(env, make_agent("pursuit"), seed, agent_seed=seed)
        h = float(env.unwrapped._state.task.target_heading_rad[0])
        v = np.asarray(ep.info["velocity_mean_mm"])
        cosines.append(float(v @ [math.cos(h), math.sin(h)] / np.linalg.norm(v)))
    assert min(cosines) > 0.3 and np.mean(cosines) > 0.6, cosines


def test_the_agent_view_shows_the_sphere_whose_velocity_the_belief_carries() -> None:
    """The swimmer filter's hypotheses carry a velocity, not the sphere: the agent still sees the condition's
    sphere (the unknown target, whose hypotheses carry it, still hides it).
    """
    from electroloc_gym.envs.agent_view import agent_view

    env = gym.make(ID, **SMALL, **SWIM)
    env.reset(seed=0)
    view = agent_view(env)
    assert view.condition.target.radius_mm == env.unwrapped.condition.target.radius_mm
    unknown = gym.make("ElectroLocUnknownTarget-v0", n_particles=50)
    unknown.reset(seed=0)
    with pytest.raises(AttributeError):
        _ = agent_view(unknown).condition.target
