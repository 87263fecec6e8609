"""Running an agent from Python: shipped policies by name from any folder, and ``run_agent`` (one episode or a
batch, the agent's env arguments applied, stopped by the env or by the agent), with one error per bad input.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines import Episode, make_agent, run_agent
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.models import shipped_models
from electroloc_gym.policy import LearnedAgent, load_policy, shipped_policies
from electroloc_gym.registry import ENV_IDS

FAST = {"n_particles": 300, "sensor_model": "analytic"}


def test_a_shipped_policy_loads_by_name_from_any_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # not the checkout: the name, not a relative path, finds it
    for name in shipped_models():
        assert isinstance(load_policy(name), LearnedAgent)
        assert isinstance(make_agent(name), LearnedAgent)
    obs = np.zeros(81, dtype=np.float32)
    by_name, by_folder = load_policy("ppo-belief"), load_policy(shipped_models()["ppo-belief"])
    assert np.array_equal(by_name.predict(obs)[0], by_folder.predict(obs)[0])


def test_a_folder_of_the_same_name_in_the_working_directory_is_named_as_a_path(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ppo-belief").mkdir()
    assert load_policy("ppo-belief").env_kwargs["observation"] == "belief"  # the shipped one, as the benchmark's
    with pytest.raises(ValueError, match="refusing to load './ppo-belief': it has no policy.json"):
        load_policy("./ppo-belief")


def test_the_listing_names_every_shipped_policy_with_its_training_env() -> None:
    listed = shipped_policies()
    assert list(listed) == list(shipped_models())
    assert {p.env_id for p in listed.values()} <= set(ENV_IDS)
    assert listed["ppo-belief-track"].env_id == "ElectroLocTrack-v0"
    assert listed["ppo-belief-global"].env_id == "ElectroLocGlobal-v0"
    assert listed["ppo-belief-grid-2x2"].env_kwargs["sensor_layout"] == "grid-2x2"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: load_policy("ppo-nope"), r"policy path 'ppo-nope' does not exist .* shipped policy: \['ppo-belief'"),
        (lambda: make_agent("ppo-nope"), r"unknown agent 'ppo-nope'; choose from .* or a shipped policy"),
        (lambda: make_agent("ppo-belief[depth=2]"), r"the shipped policy 'ppo-belief' takes no options"),
        (lambda: run_agent("min-var", seeds=-1), r"^seeds must be an integer in \[0, "),
        (lambda: run_agent("min-var", seeds=[0, 1.5]), r"^seeds must be an integer"),
        (lambda: run_agent("min-var", seeds=[]), r"^seeds must be an int ≥ 0 or a non-empty sequence"),
        (lambda: run_agent("min-var", seeds=0, agent_seed=-3), r"^agent_seed must be an integer"),
        (lambda: run_agent("nope"), r"^unknown agent 'nope'"),
        (lambda: run_agent("min-var", "Nope-v0"), r"Nope"),
        (
            lambda: run_agent("zero-crossing", env_kwargs={"max_observations": 35}),
            r"^env_kwargs\['max_observations'\]=35 contradicts the agent's own env_kwargs\['max_observations'\]=",
        ),
    ],
)
def test_every_bad_input_is_one_value_error(call, message) -> None:
    with pytest.raises((ValueError, gym.error.Error), match=message):
        call()


def test_one_seed_is_one_episode_and_a_batch_is_a_list_in_order() -> None:
    one = run_agent("rnd-wlk", seeds=4, env_kwargs=FAST)
    batch = run_agent("rnd-wlk", seeds=[3, 4], env_kwargs=FAST)
    assert isinstance(one, Episode) and isinstance(batch, list) and len(batch) == 2
    assert one.ended_by in ("success", "cap") and one.info["n_observations"] == batch[1].info["n_observations"]
    assert np.array_equal(one.info["estimate_mm"], batch[1].info["estimate_mm"])  # seeded: the same episode


def test_an_episode_is_the_loop_by_hand() -> None:
    """``run_agent`` is ``run_episode`` on the env the agent's arguments make, the agent seeded as the episode."""
    ep = run_agent("min-var", seeds=2, env_kwargs={**FAST, "condition": "salt-delrin-12.7"})
    env = gym.make("ElectroLoc-v0", condition="salt-delrin-12.7", **FAST)
    by_hand = run_episode(env, make_agent("min-var"), 2, agent_seed=2)
    assert (ep.ended_by, ep.info["n_observations"]) == (by_hand.ended_by, by_hand.info["n_observations"])
    assert np.array_equal(ep.info["estimate_mm"], by_hand.info["estimate_mm"])


def test_an_agent_that_ends_the_episode_itself_stops_it_with_its_own_env_arguments() -> None:
    ep = run_agent("zero-crossing", seeds=0, env_kwargs={"sensor_model": "analytic"})
    assert ep.ended_by == "agent"
    assert ep.info["n_observations"] > 35  # its own budget of readings (the env's default cap is 35)
