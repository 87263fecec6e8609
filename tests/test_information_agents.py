"""What infotaxis and eedi share: an episode on every env whose belief is over the target's x–y position,
and one clear refusal of the mapped tank's (whose belief is over the robot's own position)."""

import gymnasium as gym
import pytest

import electroloc_gym  # noqa: F401
from electroloc_gym.baselines.agent import make_agent
from electroloc_gym.baselines.rollout import run_episode

AGENTS = {"infotaxis": ("infotaxis[n_voters=32]", 600), "eedi": ("eedi[n_particles=64,grid_mm=10]", 500)}


@pytest.mark.parametrize("name", sorted(AGENTS))
@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocUnknownTarget-v0"])
def test_runs_an_episode_on_the_target_envs(name: str, env_id: str) -> None:
    spec, particles = AGENTS[name]
    env = gym.make(env_id, n_particles=particles, max_observations=6, sensor_model="analytic")
    ep = run_episode(env, make_agent(spec), seed=2, agent_seed=1)
    assert ep.ended_by in ("success", "cap")
    assert 1 <= len(ep.decision_s) <= 5


@pytest.mark.parametrize("name", sorted(AGENTS))
def test_refuses_the_global_env_in_one_line(name: str) -> None:
    env = gym.make("ElectroLocGlobal-v0", n_particles=200)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="ElectroLocGlobal-v0") as err:
        make_agent(name).reset(env)
    assert "\n" not in str(err.value)
