"""The privileged-information wrapper: the hidden state, opt-in, in info or a Dict observation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401
from electroloc_gym.envs.privileged import PrivilegedInfo, privileged_keys


@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocGlobal-v0", "ElectroLocUnknownTarget-v0"])
def test_info_mode_holds_the_truth_and_leaves_the_observation(env_id):
    plain = gym.make(env_id, n_particles=200)
    wrapped = PrivilegedInfo(gym.make(env_id, n_particles=200))
    o1, i1 = plain.reset(seed=4)
    o2, i2 = wrapped.reset(seed=4)
    assert "privileged" not in i1  # off by default: gym.make (and so the benchmark) never adds it
    np.testing.assert_array_equal(o1, o2)
    assert wrapped.observation_space == plain.observation_space
    p = i2["privileged"]
    assert p.shape == (len(privileged_keys(env_id)),)
    # the truth: the estimate's error computed from it is the env's own error_mm
    assert np.hypot(*(np.asarray(i2["estimate_mm"]) - p[:2])) == pytest.approx(i2["error_mm"])
    action = np.array([0.5, -0.3], dtype=np.float32)
    o1, *_, i1 = plain.step(action)
    o2, *_, i2 = wrapped.step(action)
    np.testing.assert_array_equal(o1, o2)
    assert np.hypot(*(np.asarray(i2["estimate_mm"]) - i2["privileged"][:2])) == pytest.approx(i2["error_mm"])
    if env_id == "ElectroLocUnknownTarget-v0":
        assert i2["privileged"][2] == i2["target_radius_mm"] and i2["privileged"][3] == i2["target_chi"]


def test_dict_mode_observation_is_in_its_space():
    env = PrivilegedInfo(gym.make("ElectroLoc-v0", n_particles=200, randomize_target=True), mode="dict")
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    np.testing.assert_array_equal(obs["privileged"], env.unwrapped.target_mm)
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)


def test_bad_input():
    with pytest.raises(ValueError, match="mode must be one of"):
        PrivilegedInfo(gym.make("ElectroLoc-v0", n_particles=50), mode="obs")
    with pytest.raises(ValueError, match=r"env_id must be one of \['ElectroLoc-v0'"):
        privileged_keys("CartPole-v1")
    with pytest.raises(ValueError, match="env must be an env of the env table"):
        PrivilegedInfo(gym.make("CartPole-v1"))


def test_asymmetric_example_runs_and_its_actor_never_sees_the_truth(tmp_path):
    import importlib.util
    from pathlib import Path

    pytest.importorskip("torch")
    path = Path(__file__).resolve().parents[1] / "examples" / "asymmetric_critic.py"
    spec = importlib.util.spec_from_file_location("asymmetric_critic", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = mod.train(updates=2, n_steps=16, n_particles=200, seed=0)
    assert out["actor_input_dim"] == 81 and out["critic_input_dim"] == 81 + 2
    assert np.isfinite(out["value_loss"])
