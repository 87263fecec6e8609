"""Privileged information for asymmetric actor-critics: the hidden state, as an opt-in wrapper.

An asymmetric actor-critic (Pinto et al., "Asymmetric Actor Critic for Image-Based Robot Learning", 2018)
trains its critic on what the simulator knows and its actor on what the robot sees; only the actor acts,
so the trained policy needs nothing privileged. :class:`PrivilegedInfo` adds the hidden state of the
episode to what an env returns, in one of two forms:

* ``mode="info"`` (default): ``info["privileged"]``, a float64 vector; the observation is unchanged, so
  any agent or policy of the env runs on the wrapped env as on the plain one;
* ``mode="dict"``: the observation becomes ``Dict({"observation": <the env's>, "privileged": Box})``.

What the vector holds (:func:`privileged_keys`), all in the tank's frame:

* ``ElectroLoc-v0``: the target centre (x, y), mm;
* ``ElectroLocGlobal-v0``: the robot's true carriage position (x, y), mm (its odometry is in the
  observation; the truth is what it localises);
* ``ElectroLocUnknownTarget-v0``: the target centre (x, y), mm, its radius, mm, and contrast factor χ.

It is off by default: ``gym.make`` never adds it; the benchmark builds its envs with ``gym.make`` and hands
its agents the env's agent view (:mod:`electroloc_gym.envs.agent_view`: the agent accessors, no
``hidden_state``, no ``unwrapped``), so it never shows the hidden state to an agent; and the datasets
store the same truth in their infos, not in observations.
The values come from the envs' documented evaluation accessors (``hidden_keys``, ``hidden_state()``:
each task's own hidden state, declared with the task).
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.registry import ENV_IDS, env_entry

__all__ = ["PrivilegedInfo", "privileged_keys", "PRIVILEGED_MODES"]

PRIVILEGED_MODES = ("info", "dict")


def privileged_keys(env_id: str) -> tuple[str, ...]:
    """The names of the privileged vector's entries for ``env_id`` (its task's hidden state).

    Raises:
        ValueError: an id that is not in the env table (the message lists the ids).
    """
    return tuple(env_entry(env_id).task_class.hidden_keys)


class PrivilegedInfo(gym.Wrapper):
    """Add the episode's hidden state (:func:`privileged_keys`) to ``info`` or to a ``Dict`` observation.

    Args:
        env: a single env of the registry (``gym.make(...)``, any wrappers).
        mode: ``"info"`` (``info["privileged"]``) or ``"dict"`` (a ``Dict`` observation).

    Raises:
        ValueError: an unknown mode or an env without privileged information.
    """

    def __init__(self, env: gym.Env, mode: str = "info") -> None:
        super().__init__(env)
        if mode not in PRIVILEGED_MODES:
            raise ValueError(f"mode must be one of {list(PRIVILEGED_MODES)}, got {mode!r}")
        core = env.unwrapped
        if not isinstance(core, CoreEnv):
            raise ValueError(f"env must be an env of the env table ({list(ENV_IDS)}), got {type(core).__name__}")
        self._core = core
        self.env_id = core.entry().env_id
        self.keys = core.hidden_keys
        self.mode = mode
        box = gym.spaces.Box(-np.inf, np.inf, (len(self.keys),), np.float64)
        if mode == "dict":
            self.observation_space = gym.spaces.Dict({"observation": env.observation_space, "privileged": box})
        self.privileged_space = box

    def privileged(self, info: dict[str, Any]) -> np.ndarray:
        """The hidden state now (:func:`privileged_keys`), float64."""
        return np.asarray(self._core.hidden_state(), dtype=np.float64)

    def _wrap(self, obs: Any, info: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
        p = self.privileged(info)
        if self.mode == "dict":
            return {"observation": obs, "privileged": p}, info
        return obs, {**info, "privileged": p}

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        return self._wrap(obs, info)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        obs, info = self._wrap(obs, info)
        return obs, reward, terminated, truncated, info
