"""infotaxis: the expected entropy reduction (closed forms, a float64 reference), the agent on both target envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.agent import MAX_STEP_MM, make_agent, move_bounds_mm
from electroloc_gym.baselines.infotaxis import (
    InfotaxisAgent,
    expected_entropy_reduction,
    gauss_hermite,
    log_weight_entropy,
)


def _reference(mean, std, weights, voters, nodes):
    """float64, one reading at a time: H(w) − Σ_v w_v Σ_q ω_q H(w'(z_vq))."""
    w = np.asarray(weights, dtype=np.float64)
    offsets, quad = gauss_hermite(nodes)
    wv = w[voters] / w[voters].sum()
    out = []
    for mu, sd in zip(mean, std):
        expected = 0.0
        for v, a in zip(voters, wv):
            for t, b in zip(offsets, quad):
                z = mu[v] + sd[v] * t
                ll = np.log(w) - np.log(sd) - 0.5 * ((z - mu) / sd) ** 2
                expected += a * b * float(log_weight_entropy(ll))
        out.append(float(log_weight_entropy(np.log(w))) - expected)
    return np.array(out)


def test_an_option_whose_predicted_readings_are_all_equal_reduces_nothing() -> None:
    rng = np.random.default_rng(0)
    mean = rng.normal(0.0, 1.0, size=(4, 300))
    std = np.full((4, 300), 0.05)
    mean[2] = 0.37  # every hypothesis predicts the same reading
    gains = expected_entropy_reduction(mean, std, None, np.arange(0, 300, 3), nodes=3)
    assert gains[2] == 0.0
    assert np.all(np.delete(gains, 2) > 1.0)  # distinct readings: nats of information


def test_noise_free_distinct_readings_reveal_the_hypothesis() -> None:
    m = 64
    mean = np.linspace(-1.0, 1.0, m)[None, :]
    std = np.full((1, m), 1e-6)  # far below the spacing of the predictions
    gains = expected_entropy_reduction(mean, std, None, np.arange(m), nodes=1)
    np.testing.assert_allclose(gains, np.log(m), rtol=1e-6)  # all of the prior's entropy


@pytest.mark.parametrize("nodes", [1, 3, 5])
def test_matches_a_float64_reference_with_unequal_weights(nodes: int) -> None:
    rng = np.random.default_rng(1)
    m = 80
    mean = rng.normal(0.0, 0.3, size=(3, m))
    std = rng.uniform(0.05, 0.2, size=(3, m))
    w = rng.uniform(0.5, 1.5, size=m)
    w /= w.sum()
    voters = np.sort(rng.choice(m, size=20, replace=False))
    got = expected_entropy_reduction(mean, std, w, voters, nodes=nodes)
    np.testing.assert_allclose(got, _reference(mean, std, w, voters, nodes), rtol=2e-5, atol=2e-5)


def test_log_weight_entropy_closed_forms() -> None:
    assert log_weight_entropy(np.zeros(8)) == pytest.approx(np.log(8))
    assert log_weight_entropy(np.array([0.0, -np.inf, -np.inf])) == 0.0
    p = np.array([0.5, 0.25, 0.25])
    assert log_weight_entropy(np.log(p) + 3.0) == pytest.approx(-(p * np.log(p)).sum())


def test_bad_inputs_are_one_clear_error() -> None:
    with pytest.raises(ValueError, match="std_V must be > 0"):
        expected_entropy_reduction(np.zeros((2, 3)), np.zeros((2, 3)), None, np.arange(3))
    with pytest.raises(ValueError, match="shape"):
        expected_entropy_reduction(np.zeros(3), np.ones(3), None, np.arange(3))
    for spec, option in [
        ("infotaxis[n_options=0]", "n_options"),
        ("infotaxis[nodes=17]", "nodes"),
        ("infotaxis[n_voters=0]", "n_voters"),
        ("infotaxis[n_particles=1]", "n_particles"),
        ("infotaxis[nodes=2.5]", "nodes"),
    ]:
        with pytest.raises(ValueError, match=option):
            make_agent(spec)


def test_registry_and_bench_name() -> None:
    from electroloc_gym.bench.agents import agent_kind
    from electroloc_gym.bench.default_run import default_agents

    agent = make_agent("infotaxis[n_voters=64]", seed=0)
    assert isinstance(agent, InfotaxisAgent) and agent.n_voters == 64
    assert agent_kind("infotaxis") == "baseline"
    assert "infotaxis" not in [c.spec for c in default_agents()]  # beyond the paper: asked for by name


def _decisions(env, seed: int, steps: int = 3):
    agent = make_agent("infotaxis", seed=seed)
    obs, _ = env.reset(seed=4)
    agent.reset(env)
    moves = []
    for _ in range(steps):
        lo, hi = move_bounds_mm(env)
        action, _ = agent.predict(obs)
        u = np.asarray(action, dtype=np.float64) * MAX_STEP_MM
        assert np.all(u >= lo - 1e-5) and np.all(u <= hi + 1e-5)
        moves.append(u)
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            break
    return np.array(moves), agent


def test_decisions_are_seeded_and_within_the_move_limits() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=600, sensor_model="analytic")
    a, agent = _decisions(env, seed=3)
    b, _ = _decisions(env, seed=3)
    np.testing.assert_array_equal(a, b)
    assert agent.last_gains is not None and agent.last_gains.shape == (16,)
    assert np.all(np.isfinite(agent.last_gains))
