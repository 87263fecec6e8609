"""SB3 adapter for the native batched vector env: train directly on N batched tanks.

Stable-Baselines3 cannot consume a Gymnasium ``VectorEnv``; it wants its own ``VecEnv`` protocol
(auto-reset in the same step, the final observation in ``infos[i]["terminal_observation"]``, a list
of per-env info dicts). :class:`NativeVecEnv` speaks that protocol on top of
:class:`electroloc_gym.envs.vector.ElectroLocVectorEnv` built with ``autoreset_mode=SAME_STEP``, so a
training step is one batched env step — no Python loop over envs in the math.

    from electroloc_gym.train.native_vec import make_native_vec_env
    venv = make_native_vec_env("ElectroLoc-v0", n_envs=16, seed=1000, env_kwargs={"condition": "random"})
    model = PPO("MlpPolicy", venv).learn(100_000)

This lives in ``train/`` (not ``electroloc_gym``) because SB3 imports torch.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.train.wrappers import FrameStacker, check_shaping, shaped_reward, spread_potential, stacked_space

__all__ = ["NativeVecEnv", "VecFlatFrameStack", "VecPotentialShaping", "make_native_vec_env"]

#: Info keys of the single env copied into every per-env info dict.
_INFO_KEYS = ("position_mm", "estimate_mm", "error_mm", "spread_mm", "reading_V", "n_observations", "success",
              "condition")


class NativeVecEnv(VecEnv):
    """SB3 ``VecEnv`` over a native Gymnasium vector env that autoresets in the same step.

    Per-env infos hold the single env's keys (``position_mm``/``estimate_mm`` as tuples, like
    ElectroLoc-v0), ``"TimeLimit.truncated"`` (truncated and not terminated) and, for the envs
    that finished this step, ``"terminal_observation"`` and ``"is_success"`` (the final ``success``).
    Seeds set with :meth:`seed` apply at the next :meth:`reset` (env ``i`` gets ``seed + i``),
    exactly as SB3's ``DummyVecEnv`` seeds its envs, so both train on identical episodes.

    Args:
        venv: a Gymnasium vector env with ``metadata["autoreset_mode"] == AutoresetMode.SAME_STEP``
            (e.g. ``gym.make_vec("ElectroLoc-v0", ..., vectorization_mode="vector_entry_point",
            autoreset_mode="same_step")``).
    """

    def __init__(self, venv: gym.vector.VectorEnv) -> None:
        if venv.metadata.get("autoreset_mode") is not AutoresetMode.SAME_STEP:
            raise ValueError(f"venv must autoreset in the same step (AutoresetMode.SAME_STEP), got "
                             f"{venv.metadata.get('autoreset_mode')!r}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._final_obs: np.ndarray | None = None
        #: Belief spread (mm) of every env's current state — after the autoreset for finished envs.
        self.current_spread_mm = np.zeros(self.num_envs)

    # ---- VecEnv protocol ----------------------------------------------------------------------
    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, info = self.venv.reset(seed=seeds, options=options)
        self.reset_infos = self._split_info(info)
        self.current_spread_mm = np.asarray(info["spread_mm"], dtype=float).copy()
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_async() must be called before step_wait()")
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        self._actions = None
        self._final_obs = info.get("final_obs")
        self.current_spread_mm = np.asarray(info["spread_mm"], dtype=float).copy()
        dones = terminated | truncated
        if dones.any():  # a finished env's info is its episode's last one (as DummyVecEnv), not the reset's
            final_info = info["final_info"]
            info = {k: np.where(dones.reshape((-1,) + (1,) * (np.ndim(v) - 1)), final_info[k], v)
                    for k, v in info.items() if k in _INFO_KEYS}
        infos = self._split_info(info)
        timeout = (truncated & ~terminated).tolist()
        for i, d in enumerate(infos):
            d["TimeLimit.truncated"] = timeout[i]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = self._final_obs[i]
            infos[i]["is_success"] = bool(infos[i]["success"])
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's attribute, once per requested index (the sub-envs share one object)."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of the whole vector env (sub-envs cannot be set individually)."""
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        """Call a method of the whole vector env once; its result is repeated per requested index."""
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]

    # ---- internals ----------------------------------------------------------------------------
    def _split_info(self, info: dict[str, Any]) -> list[dict[str, Any]]:
        """The vector env's dict of arrays as SB3's list of per-env dicts."""
        cols: dict[str, Iterable[Any]] = {}
        for key in _INFO_KEYS:
            if key in info:
                v = info[key]
                cols[key] = [tuple(r) for r in v.tolist()] if v.ndim == 2 else v.tolist()
        keys = list(cols)
        return [dict(zip(keys, row, strict=True)) for row in zip(*cols.values(), strict=True)]


class VecPotentialShaping(VecEnvWrapper):
    """:class:`electroloc_gym.train.wrappers.PotentialShaping` for a :class:`NativeVecEnv` stack, all envs at once.

    The same step arithmetic (:func:`electroloc_gym.train.wrappers.shaped_reward`) on arrays; a finished
    env's next episode starts from Φ of its reset state — exactly what ``PotentialShaping`` inside
    each env of a ``DummyVecEnv`` does (tested). Put it *outside* ``VecMonitor`` so that the logged return is the
    unshaped one, as the dummy/subproc stacks of ``train/__main__.py`` log it.

    Args:
        venv: a VecEnv whose ``unwrapped`` is a :class:`NativeVecEnv`.
        coef: shaping coefficient c ≥ 0.
        gamma: the algorithm's discount γ in [0, 1].
    """

    def __init__(self, venv: VecEnv, coef: float, gamma: float) -> None:
        super().__init__(venv)
        if not isinstance(venv.unwrapped, NativeVecEnv):
            raise ValueError("VecPotentialShaping needs a NativeVecEnv stack (venv.unwrapped)")
        check_shaping(coef, gamma)
        self.coef = float(coef)
        self.gamma = float(gamma)
        self.success_spread_mm = float(venv.unwrapped.venv.success_spread_mm)
        self._phi = np.zeros(self.num_envs)

    def _potential(self, spread_mm: np.ndarray) -> np.ndarray:
        return spread_potential(spread_mm, self.success_spread_mm, self.coef)

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self._phi = self._potential(self.venv.unwrapped.current_spread_mm)
        return obs

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        spread = np.array([d["spread_mm"] for d in infos])  # a finished env's info is its final state's
        timeout = np.array([d.get("TimeLimit.truncated", False) for d in infos], dtype=bool)
        shaped, phi_next = shaped_reward(rewards, self._phi, spread, dones & ~timeout, coef=self.coef,
                                         gamma=self.gamma, success_spread_mm=self.success_spread_mm)
        self._phi = np.where(dones, self._potential(self.venv.unwrapped.current_spread_mm), phi_next)
        return obs, shaped.astype(np.float32), dones, infos


class VecFlatFrameStack(VecEnvWrapper):
    """:class:`electroloc_gym.train.wrappers.FlatFrameStack` for a VecEnv, all envs in one
    :class:`~electroloc_gym.train.wrappers.FrameStacker`.

    Each env's observation is its last ``k`` observations, oldest first, zero-padded after a reset;
    a finished env's ``infos[i]["terminal_observation"]`` is stacked the same way (its episode's last
    ``k``), and its next observation starts a new stack — what ``FlatFrameStack`` inside each env of
    a ``DummyVecEnv`` gives (tested).

    Args:
        venv: a VecEnv with a 1-D Box observation space.
        k: number of frames (≥ 1).
    """

    def __init__(self, venv: VecEnv, k: int) -> None:
        space = stacked_space(venv.observation_space, k)
        super().__init__(venv, observation_space=space)
        self._stacker = FrameStacker(k, venv.observation_space.shape[0], venv.num_envs)

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self._stacker.reset()
        return self._stacker.push(obs)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        done_rows = np.flatnonzero(dones)
        if done_rows.size:
            last = np.array(obs, dtype=np.float32)
            for i in done_rows:
                last[i] = infos[i]["terminal_observation"]
            final = self._stacker.peek(last)
            for i in done_rows:
                infos[i]["terminal_observation"] = final[i]
            self._stacker.reset(dones)
        return self._stacker.push(obs), rewards, dones, infos


def make_native_vec_env(env_id: str, n_envs: int, seed: int | None, env_kwargs: dict[str, Any] | None = None,
                        monitor: bool = True, shaping_coef: float = 0.0, gamma: float = 0.99,
                        frame_stack: int = 1) -> VecEnv:
    """An SB3 ``VecEnv`` of ``n_envs`` sub-envs of ``env_id`` stepped by its native batched vector env.

    Args:
        env_id: a registered id with a ``vector_entry_point`` (ElectroLoc-v0).
        n_envs: number of sub-envs (≥ 1).
        seed: env ``i`` is reset with ``seed + i`` at the first reset (as ``DummyVecEnv.seed``); None:
            unseeded.
        env_kwargs: the single env's keyword arguments.
        monitor: wrap in ``VecMonitor`` (episode return/length in ``info["episode"]``, like the
            ``Monitor`` the dummy/subproc envs of ``train/__main__.py`` carry).
        shaping_coef: if > 0, add potential-based shaping on the belief spread
            (:class:`VecPotentialShaping`, outside the monitor: the logged return stays unshaped).
        gamma: discount of the shaping (the algorithm's γ).
        frame_stack: if > 1, the policy sees the last ``frame_stack`` observations
            (:class:`VecFlatFrameStack`, outermost).

    Raises:
        ValueError: the id has no native vector env, or bad ``n_envs``/kwargs.
    """
    spec = gym.spec(env_id)
    if spec.vector_entry_point is None:
        raise ValueError(f"{env_id} has no native vector env (vector_entry_point); use --vec-env dummy or subproc")
    if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer ≥ 1, got {n_envs!r}")
    venv = gym.make_vec(env_id, num_envs=int(n_envs), vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, **dict(env_kwargs or {}))
    wrapped: VecEnv = NativeVecEnv(venv)
    if seed is not None:
        wrapped.seed(int(seed))
    if monitor:
        wrapped = VecMonitor(wrapped)
    if shaping_coef > 0:
        wrapped = VecPotentialShaping(wrapped, shaping_coef, gamma)
    if frame_stack != 1:
        wrapped = VecFlatFrameStack(wrapped, frame_stack)
    return wrapped
