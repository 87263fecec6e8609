"""Gymnasium wrappers used in training: flat frame stacking and potential-based reward shaping.

Both act on a single env (inside the vector env), so the auto-reset machinery of every SB3 vector
env sees the wrapped env as an ordinary one.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

__all__ = ["FrameStacker", "FlatFrameStack", "PotentialShaping", "spread_potential"]


class FrameStacker:
    """The last ``k`` observations, oldest first, as one flat vector; zeros before the first one.

    Shared by :class:`FlatFrameStack` (training) and the loaded agent (:mod:`electroloc_gym.train.policy`), so the
    policy sees at decision time exactly what it saw in training.

    >>> s = FrameStacker(3, 2)
    >>> s.reset(); s.push(np.array([1.0, 2.0], dtype=np.float32)).tolist()
    [0.0, 0.0, 0.0, 0.0, 1.0, 2.0]
    """

    def __init__(self, k: int, dim: int) -> None:
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise ValueError(f"frame_stack must be an integer ≥ 1, got {k!r}")
        self.k = k
        self.dim = dim
        self._buf = np.zeros((k, dim), dtype=np.float32)

    def reset(self) -> None:
        """Forget every frame (start of an episode)."""
        self._buf[:] = 0.0

    def push(self, obs: NDArray) -> NDArray[np.float32]:
        """Append ``obs`` (shape (dim,)) and return the stacked (k·dim,) vector (a copy)."""
        self._buf = np.roll(self._buf, -1, axis=0)
        self._buf[-1] = np.asarray(obs, dtype=np.float32).reshape(self.dim)
        return self._buf.reshape(-1).copy()


class FlatFrameStack(gym.ObservationWrapper):
    """Observation = the last ``k`` observations flattened (k·d,), zero-padded after reset.

    >>> import electroloc_gym  # doctest: +SKIP
    >>> env = FlatFrameStack(gym.make("ElectroLoc-v0", observation="raw"), 4)  # doctest: +SKIP
    >>> env.observation_space.shape  # doctest: +SKIP
    (12,)
    """

    def __init__(self, env: gym.Env, k: int) -> None:
        super().__init__(env)
        box = env.observation_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"FlatFrameStack needs a 1-D Box observation space, got {box}")
        d = box.shape[0]
        self._stacker = FrameStacker(k, d)
        low = np.minimum(np.tile(box.low, k), 0.0).astype(np.float32)
        high = np.maximum(np.tile(box.high, k), 0.0).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._stacker.reset()
        return super().reset(seed=seed, options=options)

    def observation(self, observation: NDArray) -> NDArray[np.float32]:
        return self._stacker.push(observation)


def spread_potential(spread_mm: float, success_spread_mm: float, coef: float) -> float:
    """Φ(s) = −c·ln(spread / success spread): rises as the belief tightens; ≈ 0 at success."""
    return -coef * float(np.log(max(spread_mm, 1e-6) / success_spread_mm))


class PotentialShaping(gym.Wrapper):
    """Adds F = γ·Φ(s′) − Φ(s) to the reward, Φ from the belief spread in ``info["spread_mm"]``.

    Potential-based shaping (Ng, Harada & Russell 1999) leaves the optimal policy unchanged; Φ of a
    terminal (success) state is taken as 0 so the episodic return is shifted by −Φ(s₀) only. On
    truncation Φ(s′) is kept, consistent with the value bootstrap SB3 applies there.
    """

    def __init__(self, env: gym.Env, coef: float, gamma: float) -> None:
        super().__init__(env)
        if coef < 0:
            raise ValueError(f"shaping_coef must be ≥ 0, got {coef!r}")
        if not 0.0 <= gamma <= 1.0:
            raise ValueError(f"gamma must be in [0, 1], got {gamma!r}")
        self.coef = float(coef)
        self.gamma = float(gamma)
        self._phi = 0.0

    def _potential(self, info: dict[str, Any]) -> float:
        success_mm = float(getattr(self.env.unwrapped, "success_spread_mm", 10.0))
        return spread_potential(float(info["spread_mm"]), success_mm, self.coef)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._phi = self._potential(info)
        return obs, info

    def step(self, action) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        phi_next = 0.0 if terminated else self._potential(info)
        shaped = float(reward) + self.gamma * phi_next - self._phi
        self._phi = phi_next
        return obs, shaped, terminated, truncated, info
