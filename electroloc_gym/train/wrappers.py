"""Potential-based reward shaping on the belief spread: one step rule, a single-env and a VecEnv wrapper.

F = γ·Φ(s′) − Φ(s) with Φ(s) = −c·ln(spread / success spread) (Ng, Harada & Russell 1999: the
optimal policy is unchanged). :func:`shaped_reward` is the one implementation of the step;
:class:`PotentialShaping` applies it inside one env (plain SB3), :class:`VecPotentialShaping` to a
whole ``VecEnv`` (rl-zoo3's ``vec_env_wrapper:`` key, any VecEnv that fills ``reset_infos``).

The shaping is part of the training objective, not of the task: rl-zoo3 builds the same wrapper
stack for its evaluation env and for ``rl_zoo3.enjoy``, so :class:`VecPotentialShaping` starts
*inactive* (rewards pass through unchanged) and the training callback
(:class:`electroloc_gym.train.callbacks.BenchEvalCallback`) switches on the one in the training env.
Every return that evaluation, ``enjoy`` and the monitors report is the task's own (−1 per reading).
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from electroloc_gym.protocol import SUCCESS_SPREAD_MM

__all__ = ["PotentialShaping", "VecPotentialShaping", "check_shaping", "shaped_reward", "spread_potential"]


def check_shaping(coef: float, gamma: float) -> None:
    """Raise ValueError unless ``coef`` ≥ 0 (finite) and ``gamma`` is in [0, 1]."""
    if isinstance(coef, bool) or not isinstance(coef, (int, float)) or not (np.isfinite(coef) and coef >= 0):
        raise ValueError(f"shaping coef must be a number ≥ 0, got {coef!r}")
    if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not 0.0 <= gamma <= 1.0:
        raise ValueError(f"shaping gamma must be in [0, 1], got {gamma!r}")


def spread_potential(spread_mm: ArrayLike, success_spread_mm: float, coef: float) -> Any:
    """Φ(s) = −c·ln(spread / success spread): rises as the belief tightens; ≈ 0 at success (float or array)."""
    phi = -coef * np.log(np.maximum(np.asarray(spread_mm, dtype=np.float64), 1e-6) / success_spread_mm)
    return float(phi) if np.ndim(phi) == 0 else phi


def shaped_reward(
    reward: ArrayLike,
    phi: ArrayLike,
    next_spread_mm: ArrayLike,
    terminated: ArrayLike,
    *,
    coef: float,
    gamma: float,
    success_spread_mm: float,
) -> tuple[Any, Any]:
    """One shaping step, element-wise: (reward + γ·Φ(s′) − Φ(s), Φ(s′)), float64.

    Φ of a terminal (success) state is 0, so an episode's shaped return is its return − Φ(s₀); on
    truncation Φ(s′) is kept, consistent with the value bootstrap SB3 applies there.
    """
    phi_next = np.where(terminated, 0.0, spread_potential(next_spread_mm, success_spread_mm, coef))
    shaped = np.asarray(reward, dtype=np.float64) + gamma * phi_next - np.asarray(phi, dtype=np.float64)
    return shaped, phi_next


class PotentialShaping(gym.Wrapper):
    """Adds F = γ·Φ(s′) − Φ(s) to one env's reward, Φ from ``info["spread_mm"]`` (always active)."""

    def __init__(self, env: gym.Env, coef: float, gamma: float) -> None:
        super().__init__(env)
        check_shaping(coef, gamma)
        self.coef, self.gamma = float(coef), float(gamma)
        self.success_spread_mm = float(getattr(env.unwrapped, "success_spread_mm", SUCCESS_SPREAD_MM))
        self._phi = 0.0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._phi = spread_potential(float(info["spread_mm"]), self.success_spread_mm, self.coef)
        return obs, info

    def step(self, action) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        shaped, phi_next = shaped_reward(
            float(reward),
            self._phi,
            float(info["spread_mm"]),
            terminated,
            coef=self.coef,
            gamma=self.gamma,
            success_spread_mm=self.success_spread_mm,
        )
        self._phi = float(phi_next)
        return obs, float(shaped), terminated, truncated, info


class VecPotentialShaping(VecEnvWrapper):
    """:func:`shaped_reward` on every env of a VecEnv at once; inactive until :attr:`active` is set.

    Reads the spread after each step from ``infos[i]["spread_mm"]`` (a finished env's final state)
    and the spread a finished env restarts from in ``reset_infos[i]`` (DummyVecEnv and
    :class:`electroloc_gym.train.native_vec.NativeVecEnv` both fill it). Put it outside the monitor
    (rl-zoo3's ``vec_env_wrapper:`` is) so that the logged episode return is the unshaped one.

    Args:
        venv: the VecEnv.
        coef: shaping coefficient c ≥ 0.
        gamma: the algorithm's discount γ in [0, 1].
        active: shape from the start (default False: switched on by the training callback).
    """

    def __init__(self, venv: VecEnv, coef: float, gamma: float, active: bool = False) -> None:
        super().__init__(venv)
        check_shaping(coef, gamma)
        self.coef, self.gamma, self.active = float(coef), float(gamma), bool(active)
        try:
            self.success_spread_mm = float(venv.get_attr("success_spread_mm", [0])[0])
        except AttributeError:
            self.success_spread_mm = SUCCESS_SPREAD_MM
        self._phi = np.zeros(self.num_envs)

    def _reset_phi(self, rows: np.ndarray) -> None:
        for i in np.flatnonzero(rows):
            self._phi[i] = spread_potential(
                float(self.unwrapped.reset_infos[i]["spread_mm"]), self.success_spread_mm, self.coef
            )

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self._reset_phi(np.ones(self.num_envs, dtype=bool))
        return obs

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        spread = np.array([d["spread_mm"] for d in infos], dtype=np.float64)
        timeout = np.array([d.get("TimeLimit.truncated", False) for d in infos], dtype=bool)
        shaped, self._phi = shaped_reward(
            rewards,
            self._phi,
            spread,
            dones & ~timeout,
            coef=self.coef,
            gamma=self.gamma,
            success_spread_mm=self.success_spread_mm,
        )
        self._reset_phi(dones)
        return obs, (shaped if self.active else rewards).astype(np.float32), dones, infos


def activate_shaping(venv: VecEnv) -> int:
    """Switch on every :class:`VecPotentialShaping` in ``venv``'s wrapper chain; returns how many."""
    n = 0
    while isinstance(venv, VecEnvWrapper):
        if isinstance(venv, VecPotentialShaping):
            venv.active = True
            n += 1
        venv = venv.venv
    return n
