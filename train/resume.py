"""Continue training from a saved model directory without unpickling anything.

SB3's ``model.zip`` stores most of the algorithm as plain JSON, but a handful of entries — the
spaces, the policy class, schedules, episode buffers — are cloudpickled, and unpickling them is
how a crafted zip runs code. :func:`load_for_resume` reads the JSON entries itself, refuses any
pickled entry it does not know, and hands SB3 a replacement for every known one (the spaces of the
new vector env, the policy class named in the run's config, schedules rebuilt from the run's
hyper-parameters, fresh buffers). The tensors (``*.pth``) are read by SB3 with
``torch.load(weights_only=True)``, which cannot run code either. The observation statistics come
from ``policy.json`` (:func:`vec_normalize_from_export`), never from ``vecnormalize.pkl``.
"""

from __future__ import annotations

import inspect
import json
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from electroloc_gym.train.config import ConfigError

__all__ = ["zip_data", "zip_timesteps", "load_for_resume", "vec_normalize_from_export"]

# Pickled entries replaced by None: SB3 rebuilds them (_setup_model / _setup_learn) when absent.
_RESET_TO_NONE = ("_last_obs", "_last_episode_starts", "_last_original_obs", "ep_info_buffer", "ep_success_buffer",
                  "action_noise", "rollout_buffer_class", "replay_buffer_class", "exploration_schedule",
                  "lr_schedule", "_last_lstm_states")


def zip_data(zip_path: str | Path) -> dict[str, Any]:
    """The JSON ``data`` entry of an SB3 zip, parsed as JSON only (pickled entries stay base64 text).

    Raises:
        ConfigError: not a zip, no ``data`` entry, or not JSON.
    """
    try:
        with zipfile.ZipFile(zip_path) as archive:
            data = json.loads(archive.read("data").decode("utf-8"))
    except (zipfile.BadZipFile, KeyError, UnicodeDecodeError, json.JSONDecodeError, OSError) as exc:
        raise ConfigError(f"{zip_path} is not a saved SB3 model (corrupt or not a zip): {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{zip_path}: the 'data' entry is not a JSON object")
    return data


def zip_timesteps(zip_path: str | Path) -> int:
    """``num_timesteps`` stored in an SB3 zip (read as JSON)."""
    n = zip_data(zip_path).get("num_timesteps")
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ConfigError(f"{zip_path}: num_timesteps is missing or not an integer ≥ 0")
    return n


def load_for_resume(zip_path: str | Path, cls: type, venv: Any, algo_kw: Mapping[str, Any], *, device: str,
                    tensorboard_log: str | None, verbose: int) -> Any:
    """``cls.load(zip_path, env=venv)`` with every pickled entry replaced (nothing is unpickled).

    Args:
        zip_path: the model zip of the run being continued.
        cls: the SB3 algorithm class.
        venv: the new training vector env (its spaces replace the stored ones).
        algo_kw: the run's constructor keywords as built by ``config.algo_kwargs`` (``policy``,
            schedules, ``policy_kwargs`` …) — the same run's saved configuration.
        device: torch device.
        tensorboard_log: TensorBoard folder or None.
        verbose: SB3 verbosity.

    Raises:
        ConfigError: an unknown pickled entry (refused rather than unpickled), a policy name the
            algorithm does not know, or tensors that do not fit.
    """
    data = zip_data(zip_path)
    pickled = sorted(k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v)
    params = inspect.signature(cls.__init__).parameters
    kw = dict(algo_kw)
    policy_name = kw.pop("policy", "MlpPolicy")
    if policy_name not in cls.policy_aliases:
        raise ConfigError(f"policy {policy_name!r} is not one of {cls.__name__}'s {sorted(cls.policy_aliases)}")
    custom: dict[str, Any] = {"policy_class": cls.policy_aliases[policy_name],
                              "observation_space": venv.observation_space, "action_space": venv.action_space}
    unknown = []
    for key in pickled:
        if key in custom:
            continue
        if key in _RESET_TO_NONE:
            custom[key] = None
        elif key in kw:
            value = kw[key]
            custom[key] = tuple(value) if key == "train_freq" and isinstance(value, list) else value
        elif key in params and params[key].default is not inspect.Parameter.empty:
            custom[key] = params[key].default
        else:
            unknown.append(key)
    if unknown:
        raise ConfigError(f"{zip_path}: cannot resume without unpickling the entries {unknown}; refusing "
                          f"(a model zip from this project's trainer has none of these)")
    if "policy_kwargs" not in custom:  # stored as plain JSON; use the run's own (activation classes built)
        custom["policy_kwargs"] = kw.get("policy_kwargs") or {}
    try:
        return cls.load(zip_path, env=venv, device=device, custom_objects=custom, tensorboard_log=tensorboard_log,
                        verbose=verbose)
    except (ValueError, KeyError, RuntimeError, TypeError) as exc:
        raise ConfigError(f"cannot resume from {zip_path}: {type(exc).__name__}: {exc}") from exc


def vec_normalize_from_export(venv: Any, normalization: Mapping[str, Any], *, training: bool = True) -> Any:
    """A ``VecNormalize`` around ``venv`` with the statistics of a ``policy.json`` ``normalization`` section.

    Equivalent to ``VecNormalize.load("vecnormalize.pkl", venv)`` for a run of this project, without
    the pickle.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    n = normalization
    vn = VecNormalize(venv, training=training, norm_obs=bool(n["norm_obs"]), norm_reward=bool(n["norm_reward"]),
                      clip_obs=float(n["clip_obs"]), clip_reward=float(n["clip_reward"]), gamma=float(n["gamma"]),
                      epsilon=float(n["epsilon"]))
    if n["norm_obs"]:
        mean = np.asarray(n["obs_mean"], dtype=np.float64)
        if mean.shape != vn.obs_rms.mean.shape:
            raise ConfigError(f"the saved observation statistics have shape {mean.shape}, the env gives "
                              f"{vn.obs_rms.mean.shape}")
        vn.obs_rms.mean = mean
        vn.obs_rms.var = np.asarray(n["obs_var"], dtype=np.float64)
        vn.obs_rms.count = float(n["obs_count"])
    vn.ret_rms.mean = np.asarray(n["return_mean"], dtype=np.float64)
    vn.ret_rms.var = np.asarray(n["return_var"], dtype=np.float64)
    vn.ret_rms.count = float(n["return_count"])
    return vn
