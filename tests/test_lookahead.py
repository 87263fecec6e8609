"""The look-ahead planner: registry and options, seeded decisions, move bounds, both envs, informative moves."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.agent import MAX_STEP_MM, make_agent, move_bounds_mm
from electroloc_gym.baselines.lookahead import LookaheadAgent, posterior_spreads
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.sensor_models import make_sensor_model
from electroloc_gym.world.conditions import get_condition


def _moves(agent, env_id="ElectroLoc-v0", seed=5, steps=4, **env_kwargs):
    """Moves (mm) the agent requests over the first ``steps`` steps, and the bounds at each step."""
    env = gym.make(env_id, n_particles=200, **env_kwargs)
    obs, _ = env.reset(seed=seed)
    agent.reset(env)
    moves, bounds = [], []
    for _ in range(steps):
        bounds.append(move_bounds_mm(env))
        action, _ = agent.predict(obs)
        moves.append(np.asarray(action, dtype=np.float64) * MAX_STEP_MM)
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            break
    return np.array(moves), bounds


def test_registry_and_options() -> None:
    agent = make_agent("lookahead[depth=3,branches=4,budget_s=0.5,n_particles=256]", seed=1)
    assert isinstance(agent, LookaheadAgent)
    assert (agent.depth, agent.branches, agent.budget_s, agent.n_particles) == (3, 4, 0.5, 256)
    assert make_agent("lookahead").depth == 2


@pytest.mark.parametrize(
    "spec, option",
    [
        ("lookahead[depth=4]", "depth"),
        ("lookahead[depth=0]", "depth"),
        ("lookahead[branches=0]", "branches"),
        ("lookahead[budget_s=-1]", "budget_s"),
        ("lookahead[budget_s=nan]", "budget_s"),
        ("lookahead[n_particles=1]", "n_particles"),
        ("lookahead[continuations=2.5]", "continuations"),
        ("lookahead[rounds=0]", "rounds"),
        ("lookahead[n_options=0]", "n_options"),
        ("lookahead[foo=1]", "foo"),
    ],
)
def test_bad_options_name_the_option(spec: str, option: str) -> None:
    with pytest.raises(ValueError, match=option):
        make_agent(spec)


def test_decisions_reproducible_from_the_seed() -> None:
    a1, _ = _moves(make_agent("lookahead[n_particles=100]", seed=3))
    a2, _ = _moves(make_agent("lookahead[n_particles=100]", seed=3))
    np.testing.assert_array_equal(a1, a2)
    agent = make_agent("lookahead[n_particles=100]", seed=99)
    agent.seed(3)  # the runner's per-trial re-seed
    np.testing.assert_array_equal(_moves(agent)[0], a1)
    a3, _ = _moves(make_agent("lookahead[n_particles=100]", seed=4))
    assert not np.array_equal(a1, a3)


@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocGlobal-v0"])
def test_moves_within_bounds(env_id: str) -> None:
    moves, bounds = _moves(make_agent("lookahead[depth=3,continuations=2,branches=4]", seed=0), env_id, steps=5)
    assert len(moves) >= 1
    for u, (lo, hi) in zip(moves, bounds):
        assert np.all(u >= lo - 1e-5) and np.all(u <= hi + 1e-5)


def test_moves_within_the_box_near_a_wall() -> None:
    env = gym.make("ElectroLoc-v0", condition=get_condition("fresh-steel-12.7"), n_particles=200, max_observations=100)
    env.reset(seed=0)
    for _ in range(30):  # drive the carriage into the (+x, +y) corner
        _, _, term, trunc, _ = env.step(np.array([1.0, 1.0], dtype=np.float32))
        if term or trunc or np.all(move_bounds_mm(env)[1] < 1e-9):
            break
    lo, hi = move_bounds_mm(env)
    assert np.any(hi < MAX_STEP_MM)  # a wall is within reach
    agent = make_agent("lookahead", seed=0)
    agent.reset(env)
    for _ in range(5):
        u = agent.choose_move_mm()
        assert np.all(u >= lo - 1e-9) and np.all(u <= hi + 1e-9)


@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocGlobal-v0"])
def test_runs_an_episode_on_both_envs(env_id: str) -> None:
    env = gym.make(env_id, n_particles=200, max_observations=6)
    agent = make_agent("lookahead[depth=2,branches=4]")
    ep = run_episode(env, agent, seed=2, agent_seed=1)
    assert ep.ended_by in ("success", "cap")
    assert 1 <= len(ep.decision_s) <= 5
    assert agent.last_scores is not None and np.all(np.isfinite(agent.last_scores))
    assert agent.last_rounds == 1


def test_time_budget_runs_more_rounds() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=200)
    env.reset(seed=0)
    agent = make_agent("lookahead[depth=1,branches=2,n_particles=50,budget_s=0.05,max_rounds=8]", seed=0)
    agent.reset(env)
    agent.choose_move_mm()
    assert 1 <= agent.last_rounds <= 8


class _BimodalEnv:
    """A static-target env stand-in: a belief split in two clusters along x, the carriage far above."""

    belief_frame = "target"

    def __init__(self) -> None:
        rng = np.random.default_rng(0)
        x = np.concatenate([np.full((100, 2), [-20.0, 0.0]), np.full((100, 2), [20.0, 0.0])])
        self.belief = type(
            "B",
            (),
            {"particles": (x + rng.normal(0, 1.0, x.shape)).astype(np.float32), "weights": np.full(200, 1 / 200)},
        )()
        self.model = make_sensor_model("analytic", get_condition("fresh-steel-12.7"))
        self.position_mm = np.array([0.0, 40.0])
        self.allowed_box_mm = (np.array([-100.0, -100.0]), np.array([100.0, 100.0]))

    @property
    def unwrapped(self) -> _BimodalEnv:
        return self

    def predicted_reading_model(self, particles, moves):
        carriage = self.position_mm + np.asarray(moves, dtype=np.float64)
        offsets = np.asarray(particles)[None] - carriage.reshape(-1, 2)[:, None, :].astype(np.float32)
        mean, std = self.model.mean_std(offsets)
        return (np.asarray(mean)[0], np.asarray(std)[0]) if np.ndim(moves) == 1 else (mean, std)

    def predicted_particles_mm(self, particles, moves):
        return np.broadcast_to(particles, np.shape(moves)[:-1] + np.shape(particles)).copy()


def test_prefers_a_move_that_separates_the_modes() -> None:
    # Staying far above both clusters reads ≈ the same for both; moving toward one tells them apart.
    env = _BimodalEnv()
    wins = 0
    for seed in range(3):
        agent = make_agent("lookahead[depth=2,branches=16,n_particles=200]", seed=seed)
        agent.reset(env)
        move = agent.choose_move_mm()
        scores = agent.last_scores
        assert scores[0] > scores.min()  # "stay" is not the best option
        wins += bool(np.any(move != 0))
    assert wins == 3


def test_posterior_spreads_uninformative_and_exact_readings() -> None:
    x = np.array([[-10.0, 0.0], [10.0, 0.0]])
    flat = np.zeros((1, 1, 2))
    spread = posterior_spreads(flat, np.ones((1, 1, 2)), x, np.array([0, 1]), np.zeros((2, 1)))
    np.testing.assert_allclose(spread, 10.0)  # equal readings: the prior's spread
    sharp = np.array([[[-1.0, 1.0]]])
    spread = posterior_spreads(sharp, np.full((1, 1, 2), 1e-3), x, np.array([0, 1]), np.zeros((2, 1)))
    np.testing.assert_allclose(spread, 0.0, atol=1e-6)  # distinct, exact readings: collapsed


def test_bench_accepts_the_planner_by_name() -> None:
    from electroloc_gym.bench.agents import agent_kind
    from electroloc_gym.bench.default_run import default_agents

    assert agent_kind("lookahead[depth=1,branches=4]") == "baseline"
    assert "lookahead" not in [c.spec for c in default_agents()]  # beyond the paper: asked for by name
