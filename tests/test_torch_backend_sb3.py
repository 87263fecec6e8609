"""SB3 PPO learns through the torch backend's VecEnv adapter (a few hundred steps; SB3's own checker)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from stable_baselines3 import PPO  # noqa: E402

from electroloc_gym.envs.torch_sb3 import TorchSB3VecEnv  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402


def test_sb3_ppo_runs_through_the_adapter():
    torch.set_num_threads(1)
    venv = TorchSB3VecEnv(TorchElectroLocVectorEnv(num_envs=4, n_particles=200, max_observations=6), seed=0)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=256)
    assert model.num_timesteps >= 256
    assert any(not torch.equal(a, b) for a, b in zip(before, model.policy.parameters(), strict=True))


def test_adapter_resets_ended_envs_in_the_same_step():
    venv = TorchSB3VecEnv(TorchElectroLocVectorEnv(num_envs=3, n_particles=100, max_observations=2), seed=1)
    venv.reset()
    seen = False
    for _ in range(4):
        obs, rew, done, infos = venv.step(np.zeros((3, 2), dtype=np.float32))
        assert np.all(rew == -1.0)  # never a next-step reset's zero reward
        for i in np.flatnonzero(done):
            seen = True
            assert infos[i]["terminal_observation"].shape == (81,)
            assert obs[i][11] == pytest.approx(1 / 2)  # the new episode's first reading of 2
    assert seen


@pytest.mark.parametrize(
    ("actions", "match"),
    [
        (np.array([[np.nan, 0.0], [0.0, 0.0]], dtype=np.float32), "finite"),
        (np.array([[np.inf, 0.0], [0.0, 0.0]]), "finite"),
        (None, "actions"),
        (np.zeros((3, 2), dtype=np.float32), "shape"),
    ],
)
def test_adapter_refuses_bad_actions_in_one_error_before_anything_changes(actions, match):
    env = TorchElectroLocVectorEnv(num_envs=2, n_particles=50)
    venv = TorchSB3VecEnv(env, seed=0)
    venv.reset()
    before = {k: v.clone() for k, v in env.state.items()}
    with pytest.raises(ValueError, match=match):
        venv.step(actions)
    assert all(torch.equal(before[k], v) for k, v in env.state.items())
    venv.step(np.zeros((2, 2), dtype=np.float32))  # the adapter still steps
