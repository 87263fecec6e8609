"""Frame stacking and potential-based reward shaping: the one implementation of each.

:class:`FrameStacker` (the stack buffer) and :func:`shaped_reward` (one shaping step, element-wise)
are used by the single-env wrappers here (:class:`FlatFrameStack`, :class:`PotentialShaping`), by
the SB3 adapters of the native vector env (:mod:`electroloc_gym.train.native_vec`) and — the frame
stack — by the loaded agent (:mod:`electroloc_gym.train.policy`). The wrappers act on a single env
(inside the vector env), so the auto-reset machinery of every SB3 vector env sees the wrapped env
as an ordinary one.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

__all__ = ["FrameStacker", "FlatFrameStack", "PotentialShaping", "check_shaping", "shaped_reward", "spread_potential",
           "stacked_space"]


def _check_frames(k: Any) -> None:
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ValueError(f"frame_stack must be an integer ≥ 1, got {k!r}")


class FrameStacker:
    """The last ``k`` observations of each of ``n_envs`` envs, oldest first, as one flat vector per env.

    A row is all zeros before its first observation and after :meth:`reset` clears it. The one frame
    stacker of the project: :class:`FlatFrameStack` (training, one env), the loaded agent
    (:mod:`electroloc_gym.train.policy`, a row per observation of a batch) and
    :class:`electroloc_gym.train.native_vec.VecFlatFrameStack` (training on the native vector env)
    all use it, so the policy sees at decision time exactly what it saw in training.

    >>> s = FrameStacker(3, 2)
    >>> s.reset(); s.push(np.array([1.0, 2.0], dtype=np.float32)).tolist()
    [0.0, 0.0, 0.0, 0.0, 1.0, 2.0]

    Args:
        k: number of frames (≥ 1).
        dim: length of one observation.
        n_envs: number of rows (≥ 1).
    """

    def __init__(self, k: int, dim: int, n_envs: int = 1) -> None:
        _check_frames(k)
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs must be an integer ≥ 1, got {n_envs!r}")
        self.k = k
        self.dim = int(dim)
        self.n_envs = int(n_envs)
        self._buf = np.zeros((self.n_envs, k, self.dim), dtype=np.float32)

    def reset(self, rows: NDArray | None = None) -> None:
        """Forget every frame (start of an episode), or only those of the rows where ``rows`` is True."""
        if rows is None:
            self._buf[:] = 0.0
        else:
            self._buf[np.asarray(rows, dtype=bool).reshape(self.n_envs)] = 0.0

    def peek(self, obs: NDArray) -> NDArray[np.float32]:
        """The stack :meth:`push` would return for ``obs`` (shape (n_envs, dim)), without keeping it."""
        stacked = np.roll(self._buf, -1, axis=1)
        stacked[:, -1] = np.asarray(obs, dtype=np.float32).reshape(self.n_envs, self.dim)
        return stacked.reshape(self.n_envs, -1)

    def push(self, obs: NDArray) -> NDArray[np.float32]:
        """Append ``obs`` and return the stacked vectors (a copy).

        ``obs`` of shape (dim,) (one env) gives a (k·dim,) vector, (n_envs, dim) gives (n_envs, k·dim).
        """
        single = np.ndim(obs) == 1
        self._buf = np.roll(self._buf, -1, axis=1)
        self._buf[:, -1] = np.asarray(obs, dtype=np.float32).reshape(self.n_envs, self.dim)
        flat = self._buf.reshape(self.n_envs, -1).copy()
        return flat[0] if single else flat


def stacked_space(box: spaces.Box, k: int) -> spaces.Box:
    """The space of ``k`` stacked frames of the 1-D ``box``: its bounds tiled, widened to hold the zero padding."""
    if not isinstance(box, spaces.Box) or len(box.shape) != 1:
        raise ValueError(f"frame stacking needs a 1-D Box observation space, got {box}")
    _check_frames(k)
    low = np.minimum(np.tile(box.low, k), 0.0).astype(np.float32)
    high = np.maximum(np.tile(box.high, k), 0.0).astype(np.float32)
    return spaces.Box(low, high, dtype=np.float32)


class FlatFrameStack(gym.ObservationWrapper):
    """Observation = the last ``k`` observations flattened (k·d,), zero-padded after reset.

    >>> import electroloc_gym  # doctest: +SKIP
    >>> env = FlatFrameStack(gym.make("ElectroLoc-v0", observation="raw"), 4)  # doctest: +SKIP
    >>> env.observation_space.shape  # doctest: +SKIP
    (12,)
    """

    def __init__(self, env: gym.Env, k: int) -> None:
        super().__init__(env)
        self.observation_space = stacked_space(env.observation_space, k)
        self._stacker = FrameStacker(k, env.observation_space.shape[0])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._stacker.reset()
        return super().reset(seed=seed, options=options)

    def observation(self, observation: NDArray) -> NDArray[np.float32]:
        return self._stacker.push(observation)


def check_shaping(coef: float, gamma: float) -> None:
    """Raise ValueError unless ``coef`` ≥ 0 (finite) and ``gamma`` is in [0, 1]."""
    if not (np.isfinite(coef) and coef >= 0):
        raise ValueError(f"shaping_coef must be ≥ 0, got {coef!r}")
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma!r}")


def spread_potential(spread_mm: ArrayLike, success_spread_mm: float, coef: float) -> Any:
    """Φ(s) = −c·ln(spread / success spread): rises as the belief tightens; ≈ 0 at success.

    A float for a scalar spread (mm), an array for an array of them.
    """
    phi = -coef * np.log(np.maximum(np.asarray(spread_mm, dtype=np.float64), 1e-6) / success_spread_mm)
    return float(phi) if np.ndim(phi) == 0 else phi


def shaped_reward(reward: ArrayLike, phi: ArrayLike, next_spread_mm: ArrayLike, terminated: ArrayLike, *,
                  coef: float, gamma: float, success_spread_mm: float) -> tuple[Any, Any]:
    """Potential-based shaping of one step: the reward plus F = γ·Φ(s′) − Φ(s), and Φ(s′).

    Φ of a terminal (success) state is 0, so the episodic return is shifted by −Φ(s₀) only; on
    truncation Φ(s′) is kept, consistent with the value bootstrap SB3 applies there. Element-wise:
    scalars for one env (:class:`PotentialShaping`), arrays for a batch
    (:class:`electroloc_gym.train.native_vec.VecPotentialShaping`).

    Args:
        reward: the env's reward.
        phi: Φ(s) of the state the step started from.
        next_spread_mm: the belief spread after the step, mm.
        terminated: the step ended the episode by success.
        coef: shaping coefficient c ≥ 0.
        gamma: the algorithm's discount γ in [0, 1].
        success_spread_mm: the env's success spread, mm.

    Returns:
        (shaped reward, Φ(s′)) — float64.
    """
    phi_next = np.where(terminated, 0.0, spread_potential(next_spread_mm, success_spread_mm, coef))
    shaped = np.asarray(reward, dtype=np.float64) + gamma * phi_next - np.asarray(phi, dtype=np.float64)
    return shaped, phi_next


class PotentialShaping(gym.Wrapper):
    """Adds F = γ·Φ(s′) − Φ(s) to the reward, Φ from the belief spread in ``info["spread_mm"]``.

    Potential-based shaping (Ng, Harada & Russell 1999) leaves the optimal policy unchanged
    (:func:`shaped_reward`).
    """

    def __init__(self, env: gym.Env, coef: float, gamma: float) -> None:
        super().__init__(env)
        check_shaping(coef, gamma)
        self.coef = float(coef)
        self.gamma = float(gamma)
        self.success_spread_mm = float(getattr(env.unwrapped, "success_spread_mm", 10.0))
        self._phi = 0.0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._phi = spread_potential(float(info["spread_mm"]), self.success_spread_mm, self.coef)
        return obs, info

    def step(self, action) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        shaped, phi_next = shaped_reward(float(reward), self._phi, float(info["spread_mm"]), terminated,
                                         coef=self.coef, gamma=self.gamma, success_spread_mm=self.success_spread_mm)
        self._phi = float(phi_next)
        return obs, float(shaped), terminated, truncated, info
