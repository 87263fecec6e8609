"""The native batched vector env behind SB3's ``VecEnv``, and the rl-zoo3 hook that uses it.

SB3 cannot consume a Gymnasium ``VectorEnv``; it wants its own ``VecEnv`` protocol (auto-reset in
the same step, the final observation in ``infos[i]["terminal_observation"]``, a list of per-env info
dicts, ``reset_infos``). :class:`NativeVecEnv` speaks it on top of ``gym.make_vec(...,
vectorization_mode="vector_entry_point", autoreset_mode="same_step")``, so a training step is one
batched env step — no Python loop over envs in the math.

rl-zoo3 builds every env through SB3's ``make_vec_env(make_env, ..., vec_env_cls=...)`` and takes
``vec_env_cls`` from ``ExperimentManager.default_vec_env_cls`` when it is set (its hook for
batched simulators; ``rl_zoo3.enjoy`` reads it too). :func:`zoo_vec_env` is that callable: given
the per-env constructors it builds the native vector env of the same id and kwargs with a
``VecMonitor`` writing the same monitor file, or falls back to ``DummyVecEnv`` when the id has no
native vector env, an ``env_wrapper`` is configured, or the env renders (``enjoy``/``record_video``).
:mod:`electroloc_gym.train.zoo` installs it when rl-zoo3 imports it with ``--gym-packages``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from electroloc_gym.contract.observation import INFO_KEYS  # the info keys copied into every per-env info dict
from electroloc_gym.train.wrappers import VecPotentialShaping

__all__ = ["NativeVecEnv", "VecEpisodeReport", "make_native_vec_env", "zoo_vec_env"]

#: The vector info's keys behind the per-env info dicts: the single env's (numeric; the condition as its index).
_VECTOR_KEYS = INFO_KEYS


class NativeVecEnv(VecEnv):
    """SB3 ``VecEnv`` over a native Gymnasium vector env that autoresets in the same step.

    Per-env infos hold the single env's keys (the condition as ``condition_index``: its name is the vector
    env's ``condition_names`` or ``metadata["info_names"]["condition_index"]``),
    ``"TimeLimit.truncated"`` and, for the envs that
    finished this step, ``"terminal_observation"`` and ``"is_success"``; ``reset_infos[i]`` is the
    info of env ``i``'s latest reset. Seeds set with :meth:`seed` apply at the next :meth:`reset`
    (env ``i`` gets ``seed + i``), as SB3's ``DummyVecEnv`` seeds its envs: both train on identical
    episodes (tests/test_vector.py).

    Args:
        venv: a Gymnasium vector env with ``metadata["autoreset_mode"] == AutoresetMode.SAME_STEP``.
    """

    def __init__(self, venv: gym.vector.VectorEnv) -> None:
        if venv.metadata.get("autoreset_mode") is not AutoresetMode.SAME_STEP:
            raise ValueError(
                f"venv must autoreset in the same step (AutoresetMode.SAME_STEP), got "
                f"{venv.metadata.get('autoreset_mode')!r}"
            )
        self.venv = venv
        #: The single env's id and kwargs (set by :func:`make_native_vec_env`).
        self.env_id: str | None = None
        self.env_kwargs: dict[str, Any] = {}
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, info = self.venv.reset(seed=seeds, options=options)  # pyright: ignore[reportArgumentType]  # VectorEnv.reset says int; its vector envs take one seed per sub-env
        self.reset_infos = self._split_info(info)
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
        dones = terminated | truncated
        final_obs = info.get("final_obs")
        if dones.any():  # a finished env's info is its episode's last one (as DummyVecEnv), not the reset's
            now = self._split_info(info)
            for i in np.flatnonzero(dones):
                self.reset_infos[i] = now[i]
            final_info = info["final_info"]
            info = {
                k: np.where(dones.reshape((-1,) + (1,) * (np.ndim(v) - 1)), final_info[k], v)
                for k, v in info.items()
                if k in _VECTOR_KEYS
            }
        infos = self._split_info(info)
        timeout = (truncated & ~terminated).tolist()
        for i, d in enumerate(infos):
            d["TimeLimit.truncated"] = timeout[i]
        for i in np.flatnonzero(dones):
            if final_obs is None:
                raise RuntimeError("the vector env gave no info['final_obs'] for an env that finished (SAME_STEP)")
            infos[i]["terminal_observation"] = final_obs[i]
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

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call a method of the whole vector env once; its result is repeated per requested index."""
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]

    def _split_info(self, info: dict[str, Any]) -> list[dict[str, Any]]:
        """The vector env's dict of arrays as SB3's list of per-env dicts (positions as (2,) arrays, the single
        env's).
        """
        cols = {
            k: ([r.copy() for r in info[k]] if info[k].ndim == 2 else info[k].tolist())
            for k in _VECTOR_KEYS
            if k in info
        }
        return [dict(zip(cols, row, strict=True)) for row in zip(*cols.values(), strict=True)]


class VecEpisodeReport(VecEnvWrapper):
    """Prints one line per finished episode of env 0: readings, success, error (mm) and the unshaped return.

    What ``rl_zoo3.enjoy`` and ``rl_zoo3.record_video`` show for these envs besides their own
    "Episode Reward" (the monitor's return: the task's own −1 per reading, since the shaping is
    inactive outside training).
    """

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self._ret = np.zeros(self.num_envs)

    def reset(self) -> VecEnvObs:
        self._ret[:] = 0.0
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        self._ret += rewards
        if dones[0]:
            d = infos[0]
            print(
                f"[electroloc] episode: {d['n_observations']} readings, success {bool(d['success'])}, "
                f"error {d['error_mm']:.1f} mm, return {self._ret[0]:.1f} (unshaped)",
                flush=True,
            )
        self._ret[dones] = 0.0
        return obs, rewards, dones, infos


def make_native_vec_env(
    env_id: str,
    n_envs: int,
    seed: int | None,
    env_kwargs: dict[str, Any] | None = None,
    monitor: bool = True,
    shaping_coef: float = 0.0,
    gamma: float = 0.99,
    monitor_file: str | None = None,
    info_keywords: tuple[str, ...] = (),
) -> VecEnv:
    """An SB3 ``VecEnv`` of ``n_envs`` sub-envs of ``env_id`` stepped by its native batched vector env.

    Args:
        env_id: a registered id with a ``vector_entry_point``.
        n_envs: number of sub-envs (≥ 1).
        seed: env ``i`` is reset with ``seed + i`` at the first reset; None: unseeded.
        env_kwargs: the single env's keyword arguments.
        monitor: wrap in ``VecMonitor`` (episode return/length in ``info["episode"]``).
        shaping_coef: if > 0, an active :class:`~electroloc_gym.train.wrappers.VecPotentialShaping`
            outside the monitor (the logged return stays unshaped).
        gamma: discount of the shaping (the algorithm's γ).
        monitor_file: the monitor's CSV file (None: none).
        info_keywords: info keys the monitor writes per episode.

    Raises:
        ValueError: the id has no native vector env, or bad ``n_envs``.
    """
    spec = gym.spec(env_id)
    if spec.vector_entry_point is None:
        raise ValueError(f"env_id {env_id} has no native vector env (vector_entry_point); use DummyVecEnv")
    if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer ≥ 1, got {n_envs!r}")
    venv = gym.make_vec(
        env_id,
        num_envs=int(n_envs),
        vectorization_mode="vector_entry_point",
        autoreset_mode=AutoresetMode.SAME_STEP,
        **dict(env_kwargs or {}),
    )
    wrapped: VecEnv = NativeVecEnv(venv)
    wrapped.env_id, wrapped.env_kwargs = env_id, dict(env_kwargs or {})
    if seed is not None:
        wrapped.seed(int(seed))
    if monitor:
        wrapped = VecMonitor(wrapped, filename=monitor_file, info_keywords=tuple(info_keywords))
    if shaping_coef > 0:
        wrapped = VecPotentialShaping(wrapped, shaping_coef, gamma, active=True)
    return wrapped


def _main_module() -> str:
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    return getattr(spec, "name", "") or ""


def zoo_vec_env(env_fns: list[Callable[[], gym.Env]], **vec_env_kwargs: Any) -> VecEnv:
    """rl-zoo3's ``vec_env_cls``: the native vector env for the ids that have one, else ``DummyVecEnv``.

    ``env_fns`` are SB3 ``make_vec_env``'s constructors (each a ``Monitor``-wrapped env). One is
    built to read the id, kwargs and monitor settings, then closed; the native env takes over the
    monitor file. Under ``rl_zoo3.enjoy`` / ``record_video`` a :class:`VecEpisodeReport` is added.
    """
    probe = env_fns[0]()
    spec = probe.unwrapped.spec
    native: tuple[str, str | None, tuple[str, ...], dict[str, Any]] | None = None  # id, monitor file, keys, kwargs
    if (
        isinstance(probe, Monitor)
        and spec is not None
        and spec.vector_entry_point is not None
        and spec.kwargs.get("render_mode") is None
        and not vec_env_kwargs
    ):
        writer = probe.results_writer
        monitor_file = None if writer is None else writer.file_handler.name
        info_keywords = tuple(probe.info_keywords)
        kwargs = {k: v for k, v in spec.kwargs.items() if k != "render_mode"}
        native = (spec.id, monitor_file, info_keywords, kwargs)
    probe.close()
    if native is not None:
        env_id, monitor_file, info_keywords, kwargs = native
        venv = make_native_vec_env(
            env_id, len(env_fns), seed=None, env_kwargs=kwargs, monitor_file=monitor_file, info_keywords=info_keywords
        )
    else:
        venv = DummyVecEnv(env_fns, **vec_env_kwargs)
    if _main_module() in ("rl_zoo3.enjoy", "rl_zoo3.record_video"):
        venv = VecEpisodeReport(venv)
    return venv
