"""The hybrid controller: it searches with its explorer while the belief is wide and pursues once it is tight,
switching where it says; its options and the envs it refuses are one error each.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines import make_agent
from electroloc_gym.baselines.agent import AGENT_NAMES
from electroloc_gym.envs.agent_view import agent_view

KW = {"n_particles": 400, "sensor_model": "analytic"}


def _moves(switch_spread_mm: float | None, steps: int = 20) -> tuple[list[bool], list[np.ndarray], list[np.ndarray]]:
    """Per step of one track episode: whether it pursued, its move, and the move its explorer or pursuit would
    make from the same state (the explorer seeded as the hybrid's).
    """
    env = gym.make("ElectroLocTrack-v0", **KW)
    obs, _ = env.reset(seed=5)
    spec = "hybrid" if switch_spread_mm is None else f"hybrid[switch_spread_mm={switch_spread_mm}]"
    hybrid, explorer, pursuit = make_agent(spec, seed=1), make_agent("min-var", seed=1), make_agent("pursuit")
    for a in (hybrid, explorer, pursuit):
        a.reset(env)
    pursued, made, expected = [], [], []
    for _ in range(steps):
        spread = agent_view(env).belief.spread()
        threshold = 10.0 if switch_spread_mm is None else switch_spread_mm
        pursue = spread <= threshold
        other = (pursuit if pursue else explorer).choose_move_mm()
        move = hybrid.choose_move_mm()
        pursued.append(pursue)
        made.append(move)
        expected.append(other)
        obs, *_ = env.step(hybrid.action_of(move))
    return pursued, made, expected


@pytest.mark.parametrize("switch", [None, 6.0])
def test_it_searches_while_wide_and_pursues_once_tight(switch) -> None:
    pursued, made, expected = _moves(switch)
    assert not pursued[0] and any(pursued)  # a uniform belief first, then tight enough to pursue
    for p, m, e in zip(pursued, made, expected, strict=True):
        if p:  # pursuit is deterministic: the same move from the same state
            assert np.allclose(m, e)
    first = pursued.index(True)
    assert all(np.allclose(m, e) for m, e in zip(made[:first], expected[:first], strict=True))  # min-var, same seed


def test_it_is_registered_and_takes_its_options() -> None:
    assert "hybrid" in AGENT_NAMES
    agent = make_agent("hybrid[explore=infotaxis,switch_spread_mm=5]", seed=0)
    assert (agent.explore, agent.switch_spread_mm) == ("infotaxis", 5.0)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("hybrid[explore=rnd-wlk]", "explore must be one of"),
        ("hybrid[switch_spread_mm=0]", "switch_spread_mm must be"),
        ("hybrid[switch_spread_mm=nan]", "switch_spread_mm must be"),
        ("hybrid[depth=2]", "bad options for agent 'hybrid'"),
    ],
)
def test_bad_options_are_one_error(spec, message) -> None:
    with pytest.raises(ValueError, match=message):
        make_agent(spec)


def test_it_refuses_a_belief_over_the_robots_own_position() -> None:
    env = gym.make("ElectroLocGlobal-v0", **KW)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="hybrid needs a belief over the target's position"):
        make_agent("hybrid").reset(env)
