"""The torch vector env as a Stable-Baselines3 ``VecEnv`` (numpy at the boundary, SB3's autoreset).

SB3 expects a same-step reset: the step that ends an episode returns the next episode's first
observation, the last one in ``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]``. The
adapter steps the torch env, then resets the ended envs at once (``reset(options={"reset_mask": …})``)
— a host round trip per step, which SB3's numpy rollouts need anyway. SB3's actions are numpy arrays, so
they are checked on the host, as the numba engine checks them (:meth:`~electroloc_gym.engines.torch_core.
vector_env.TorchElectroLocVectorEnv.host_actions`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv
from electroloc_gym.utils.checks import check_seeds

__all__ = ["TorchSB3VecEnv"]


class TorchSB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over a :class:`~electroloc_gym.envs.torch_vector.TorchElectroLocVectorEnv`.

    Args:
        env: the torch vector env.
        seed: the seed of the first reset (None: fresh entropy; checked here as ``reset`` checks it).
    """

    def __init__(self, env: TorchElectroLocVectorEnv, seed: int | None = None) -> None:
        check_seeds(seed, env.num_envs)
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self.env = env
        self._seed = seed
        self._actions: Any = None

    def reset(self) -> np.ndarray:
        obs, _ = self.env.reset(seed=self._seed)
        self._seed = None
        return obs.cpu().numpy()

    def step_async(self, actions: np.ndarray) -> None:
        """Check ``actions`` on the host (the numba engine's rules: NaN, None, a wrong shape or dtype is one
        ValueError naming ``actions``, before anything changes) and keep them for :meth:`step_wait`.
        """
        self._actions = self.env.host_actions(actions)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        obs, rew, term, trunc, _ = self.env.step(self._actions)
        done = term | trunc
        obs_np = obs.cpu().numpy()
        done_np, trunc_np = done.cpu().numpy(), trunc.cpu().numpy()
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if done_np.any():
            for i in np.flatnonzero(done_np).tolist():
                infos[i] = {"terminal_observation": obs_np[i].copy(), "TimeLimit.truncated": bool(trunc_np[i])}
            new_obs, _ = self.env.reset(options={"reset_mask": done})
            obs_np = np.where(done_np[:, None], new_obs.cpu().numpy(), obs_np)
        return obs_np, rew.cpu().numpy().astype(np.float32), done_np, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise AttributeError(f"set_attr: the torch vector env's attributes are read-only ({attr_name!r})")

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
        raise AttributeError(f"env_method: the torch vector env has no per-sub-env methods ({method_name!r})")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))

    def seed(self, seed: int | None = None) -> list[int | None]:
        """The seed of the next reset, checked now (one ValueError naming ``seed``, as ``reset`` gives)."""
        check_seeds(seed, self.num_envs)
        self._seed = seed
        return [seed] * self.num_envs
