"""Hyper-parameter files for ``python -m electroloc_gym.train`` (strict YAML, one section per env id).

A file ``train/hyperparams/<algo>.yml`` maps env ids to hyper-parameters and may hold a ``default:``
section that every env id inherits from (the env's own section wins, key by key)::

    default:
      policy: MlpPolicy
      learning_rate: 3.0e-4
    ElectroLoc-v0:
      n_steps: 256
      normalize: {norm_obs: true, norm_reward: false}
      shaping_coef: 1.0

This is the project's own format, close to rl-zoo3's but not the same (rl-zoo3 has no ``default:``
inheritance and no ``shaping_coef``; for rl-zoo3 itself see ``train/hyperparams/rl_zoo3/``). Every
key must be either a keyword of the algorithm's constructor (``PPO(n_steps=...)``) or one of
:data:`EXTRA_KEYS`; anything else (a typo such as ``n_step``) is rejected with an error naming the
file, the section and the allowed keys — never silently ignored. Values are checked against their
documented ranges and ``policy_kwargs`` against the policy class (:mod:`electroloc_gym.train.validation`).

Value conventions:

* ``learning_rate: lin_3e-4`` — a linear schedule from 3e-4 down to 0 over training.
* ``policy_kwargs: {net_arch: [128, 128], activation_fn: tanh}`` — the activation by name.
"""

from __future__ import annotations

import copy
import inspect
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "ALGOS",
    "EXTRA_KEYS",
    "NORMALIZE_KEYS",
    "HYPERPARAMS_DIR",
    "ConfigError",
    "algo_class",
    "load_hyperparams",
    "resolve_hyperparams",
    "algo_kwargs",
    "linear_schedule",
]

#: Where the shipped YAML files live.
HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"

#: Algorithm name → "module:Class". sb3-contrib ones are imported only when asked for.
ALGOS: dict[str, str] = {
    "a2c": "stable_baselines3:A2C",
    "ppo": "stable_baselines3:PPO",
    "sac": "stable_baselines3:SAC",
    "td3": "stable_baselines3:TD3",
    "ddpg": "stable_baselines3:DDPG",
    "dqn": "stable_baselines3:DQN",
    "recurrentppo": "sb3_contrib:RecurrentPPO",
    "tqc": "sb3_contrib:TQC",
    "qrdqn": "sb3_contrib:QRDQN",
}

#: Keys this package understands on top of the algorithm's constructor keywords.
EXTRA_KEYS: dict[str, str] = {
    "n_envs": "default number of parallel envs (--n-envs overrides)",
    "n_timesteps": "default training budget in env steps (--timesteps overrides)",
    "env_kwargs": "mapping merged under --env-kwargs (the command line wins)",
    "normalize": "false, true or a mapping of VecNormalize options (norm_obs, norm_reward, clip_obs, ...)",
    "frame_stack": "integer k ≥ 1: the policy sees the last k observations (zero-padded at reset)",
    "shaping_coef": "c ≥ 0: potential-based shaping Φ(s) = −c·ln(spread/success spread) (0 = off)",
}

#: Options of ``VecNormalize`` accepted under ``normalize:``.
NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon")

# Constructor keywords the training script sets itself (never from YAML).
_RESERVED = {"self", "env", "seed", "device", "verbose", "tensorboard_log", "_init_setup_model"}

_ACTIVATIONS = ("tanh", "relu", "elu", "leaky_relu", "gelu", "silu")  # = policy_format.ACTIVATIONS


class ConfigError(ValueError):
    """A hyper-parameter file or value is malformed (unknown key, wrong type, missing section)."""


def algo_class(algo: str) -> type:
    """The SB3 / sb3-contrib class of ``algo`` (lower case), imported lazily.

    Raises:
        ConfigError: unknown name, or the package that provides it is not installed.
    """
    if algo not in ALGOS:
        raise ConfigError(f"--algo must be one of {sorted(ALGOS)}, got {algo!r}")
    module_name, cls_name = ALGOS[algo].split(":")
    try:
        module = __import__(module_name, fromlist=[cls_name])
    except ImportError as exc:
        raise ConfigError(f"--algo {algo} needs the package {module_name!r} "
                          f"(pip install 'electroloc-gym[train]'): {exc}") from exc
    return getattr(module, cls_name)


def allowed_keys(algo: str) -> set[str]:
    """Every key a YAML section may hold for ``algo``."""
    params = set(inspect.signature(algo_class(algo).__init__).parameters) - _RESERVED
    return params | set(EXTRA_KEYS)


def load_hyperparams(path: str | Path, algo: str) -> dict[str, dict[str, Any]]:
    """Read and validate a whole hyper-parameter file.

    Args:
        path: the YAML file.
        algo: the algorithm whose constructor keywords are allowed.

    Returns:
        Section name → mapping (``default`` and env ids), every key checked.

    Raises:
        ConfigError: missing/unreadable file, not a mapping of mappings, or an unknown key.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"--hyperparams: no such file {str(p)!r}")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"--hyperparams: {p} is not valid YAML: {exc}") from exc
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: the top level must map env ids (and 'default') to sections, got {type(data).__name__}")
    allowed = allowed_keys(algo)
    for section, body in data.items():
        if body is None:
            data[section] = body = {}
        if not isinstance(body, dict):
            raise ConfigError(f"{p}: section {section!r} must be a mapping, got {type(body).__name__}")
        unknown = sorted(set(body) - allowed)
        if unknown:
            raise ConfigError(f"{p}: section {section!r} has unknown key(s) {unknown} for --algo {algo}; "
                              f"allowed: {sorted(allowed)}")
        from electroloc_gym.train.validation import check_algo_values

        data[section] = body = {**body, **check_algo_values({k: v for k, v in body.items() if k not in EXTRA_KEYS},
                                                            algo, f"{p}: section {section!r}")}
        _check_values(body, f"{p}: section {section!r}")
    return data


def resolve_hyperparams(path: str | Path, algo: str, env_id: str) -> dict[str, Any]:
    """``default`` overlaid with the ``env_id`` section (a deep copy; the env's keys win).

    Raises:
        ConfigError: as :func:`load_hyperparams`, or when neither section exists.
    """
    data = load_hyperparams(path, algo)
    if "default" not in data and env_id not in data:
        raise ConfigError(f"{path}: no section for {env_id!r} and no 'default' section "
                          f"(sections: {sorted(data)})")
    out = copy.deepcopy(data.get("default", {}))
    out.update(copy.deepcopy(data.get(env_id, {})))
    from electroloc_gym.train.validation import check_algo_values, check_policy_kwargs

    where = f"{path}: section {env_id if env_id in data else 'default'!r}"
    check_algo_values({k: v for k, v in out.items() if k not in EXTRA_KEYS}, algo, where)
    if out.get("policy_kwargs"):
        check_policy_kwargs(out["policy_kwargs"], algo, out.get("policy", "MlpPolicy"), where)
    return out


def _check_values(body: Mapping[str, Any], where: str) -> None:
    if "n_envs" in body and not _is_int(body["n_envs"], 1):
        raise ConfigError(f"{where}: n_envs must be an integer ≥ 1, got {body['n_envs']!r}")
    if "n_timesteps" in body and not (_is_int(body["n_timesteps"], 1) or
                                      (isinstance(body["n_timesteps"], float) and body["n_timesteps"] >= 1)):
        raise ConfigError(f"{where}: n_timesteps must be a number ≥ 1, got {body['n_timesteps']!r}")
    if "frame_stack" in body and not _is_int(body["frame_stack"], 1):
        raise ConfigError(f"{where}: frame_stack must be an integer ≥ 1, got {body['frame_stack']!r}")
    if "shaping_coef" in body:
        c = body["shaping_coef"]
        if isinstance(c, bool) or not isinstance(c, (int, float)) or c < 0:
            raise ConfigError(f"{where}: shaping_coef must be a number ≥ 0, got {c!r}")
    if "env_kwargs" in body and not isinstance(body["env_kwargs"], dict):
        raise ConfigError(f"{where}: env_kwargs must be a mapping, got {body['env_kwargs']!r}")
    if "normalize" in body:
        n = body["normalize"]
        if isinstance(n, dict):
            bad = sorted(set(n) - set(NORMALIZE_KEYS))
            if bad:
                raise ConfigError(f"{where}: normalize has unknown key(s) {bad}; allowed: {list(NORMALIZE_KEYS)}")
        elif not isinstance(n, bool):
            raise ConfigError(f"{where}: normalize must be true, false or a mapping, got {n!r}")
    pk = body.get("policy_kwargs")
    if pk is not None:
        if not isinstance(pk, dict):
            raise ConfigError(f"{where}: policy_kwargs must be a mapping, got {pk!r}")
        act = pk.get("activation_fn")
        if act is not None and act not in _ACTIVATIONS:
            raise ConfigError(f"{where}: policy_kwargs.activation_fn must be one of {list(_ACTIVATIONS)}, got {act!r}")
    lr = body.get("learning_rate")
    if isinstance(lr, str):
        _parse_schedule(lr, where)


def _is_int(v: Any, low: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= low


def linear_schedule(initial: float) -> Callable[[float], float]:
    """SB3 schedule: ``initial`` at the start (progress_remaining = 1) down to 0 at the end."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _parse_schedule(value: str, where: str) -> float:
    if not value.startswith("lin_"):
        raise ConfigError(f"{where}: a string learning_rate must look like 'lin_3e-4', got {value!r}")
    try:
        v = float(value[4:])
    except ValueError as exc:
        raise ConfigError(f"{where}: cannot read the number in learning_rate {value!r}") from exc
    if v <= 0:
        raise ConfigError(f"{where}: learning_rate must be > 0, got {value!r}")
    return v


def algo_kwargs(hyperparams: Mapping[str, Any]) -> dict[str, Any]:
    """Constructor keywords for the algorithm from a resolved section (extra keys dropped, values built)."""
    kw = {k: copy.deepcopy(v) for k, v in hyperparams.items() if k not in EXTRA_KEYS}
    lr = kw.get("learning_rate")
    if isinstance(lr, str):
        kw["learning_rate"] = linear_schedule(_parse_schedule(lr, "learning_rate"))
    pk = kw.get("policy_kwargs")
    if pk and "activation_fn" in pk:
        import torch.nn as nn

        names = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU, "gelu": nn.GELU,
                 "silu": nn.SiLU}
        pk["activation_fn"] = names[pk["activation_fn"]]
    return kw
