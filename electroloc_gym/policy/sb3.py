"""From a live Stable-Baselines3 model (or a trusted SB3 zip) to the pickle-free policy format.

Needs torch and SB3 (the ``train`` extra); :mod:`electroloc_gym.policy.load` imports it only for
stochastic actions and for ``trust_pickle=True``.
"""

from __future__ import annotations

import importlib
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from electroloc_gym.policy.format import (
    ACTIVATIONS,
    POLICY_CLASSES,
    ObsNormalization,
    PolicyFormatError,
    floats_to_json,
    space_from_json,
    space_to_json,
)
from electroloc_gym.registry import PAPER_ENV_ID

__all__ = [
    "model_from_sb3_zip",
    "export_meta",
    "model_weights",
    "normalization_from_vecnormalize",
    "read_zoo_yaml",
    "sb3_policy",
]

# Constructor keywords that only matter for training (the optimiser) or that are rebuilt here.
_DROPPED_KWARGS = ("optimizer_class", "optimizer_kwargs", "features_extractor_class", "features_extractor_kwargs")


class _ZooLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that also reads the ``OrderedDict`` tag rl-zoo3 writes into config.yml/args.yml."""


def _ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict[str, Any]:
    pairs = loader.construct_sequence(node.value[0], deep=True) if isinstance(node, yaml.SequenceNode) else []
    return {k: v for k, v in pairs}


def _python_tag(loader: yaml.SafeLoader, suffix: str, node: yaml.Node) -> str:
    return f"python/{suffix}"  # any other Python object rl-zoo3 wrote (e.g. an activation class): its name only


_ZooLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", _ordered_dict)
_ZooLoader.add_multi_constructor("tag:yaml.org,2002:python/", _python_tag)


def read_zoo_yaml(path: str | Path) -> dict[str, Any]:
    """An rl-zoo3 ``config.yml`` / ``args.yml`` as a dict; no Python tag is executed (other tags → their name).

    Raises:
        ValueError: not YAML, another Python tag, or not a mapping.
    """
    try:
        data = yaml.load(Path(path).read_text(encoding="utf-8"), Loader=_ZooLoader)  # noqa: S506 - safe subclass
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: not a plain rl-zoo3 YAML file: {exc}") from exc
    if isinstance(data, list):  # config.yml: an OrderedDict dumped as a list of pairs
        data = {k: v for k, v in data}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping, got {type(data).__name__}")
    return data


def normalization_from_vecnormalize(vn: Any) -> dict[str, Any] | None:
    """The JSON ``normalization`` section of a live ``VecNormalize`` (None when there is none)."""
    if vn is None:
        return None
    out: dict[str, Any] = {
        "norm_obs": bool(vn.norm_obs),
        "norm_reward": bool(vn.norm_reward),
        **{k: float(getattr(vn, k)) for k in ("clip_obs", "clip_reward", "epsilon", "gamma")},
        **dict.fromkeys(("obs_mean", "obs_var", "obs_count")),
    }
    if vn.norm_obs:
        if isinstance(vn.obs_rms, dict):
            raise PolicyFormatError("cannot export normalisation of a Dict observation space")
        out.update(
            obs_mean=floats_to_json(vn.obs_rms.mean),
            obs_var=floats_to_json(vn.obs_rms.var),
            obs_count=float(vn.obs_rms.count),
        )
    return out


def _architecture(model: Any) -> dict[str, Any]:
    """The policy's class name and the constructor keywords needed to rebuild it."""
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
    from stable_baselines3.common.torch_layers import FlattenExtractor

    policy = model.policy
    name = type(policy).__name__
    if POLICY_CLASSES.get(name) != f"{type(policy).__module__}:{name}":
        raise PolicyFormatError(
            f"cannot export a {type(policy).__module__}.{name} policy; supported: {sorted(POLICY_CLASSES)}"
        )
    kwargs = dict(model.policy_kwargs or {})
    if kwargs.get("features_extractor_class", FlattenExtractor) is not FlattenExtractor:
        raise PolicyFormatError("cannot export a custom features extractor (only the flat MLP input)")
    if getattr(model, "use_sde", False):
        raise PolicyFormatError("cannot export a policy trained with gSDE (use_sde)")
    for key in _DROPPED_KWARGS:
        kwargs.pop(key, None)
    for attr in ("net_arch", "activation_fn", "share_features_extractor", "n_quantiles"):
        if hasattr(policy, attr):
            kwargs[attr] = getattr(policy, attr)
    if isinstance(model, OnPolicyAlgorithm):
        kwargs["use_sde"] = False
    kwargs.update(getattr(policy, "batch_norm_params", {}))  # CrossQ's Batch Renorm settings, written out
    recurrent = None
    if name == "RecurrentActorCriticPolicy":
        recurrent = {
            "lstm_hidden_size": int(policy.lstm_actor.hidden_size),
            "n_lstm_layers": int(policy.lstm_actor.num_layers),
            "shared_lstm": bool(policy.shared_lstm),
            "enable_critic_lstm": policy.lstm_critic is not None,
        }
        kwargs.update(recurrent)
    act = kwargs.get("activation_fn")
    if act is not None:
        names = [k for k, v in ACTIVATIONS.items() if getattr(act, "__name__", None) == v]
        if not names:
            raise PolicyFormatError(f"cannot export activation_fn {act!r}; supported: {list(ACTIVATIONS)}")
        kwargs["activation_fn"] = names[0]
    return {"policy_class": name, "policy_kwargs": kwargs, "recurrent": recurrent}


def model_weights(model: Any) -> dict[str, np.ndarray]:
    """The policy's ``state_dict`` as numpy arrays (copies)."""
    return {k: v.detach().cpu().numpy().copy() for k, v in model.policy.state_dict().items()}


def export_meta(
    model: Any,
    *,
    env_id: str,
    env_kwargs: Mapping[str, Any],
    frame_stack: int,
    vecnormalize: Any,
    provenance: Mapping[str, Any],
    evaluation: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """``policy.json`` content (without ``weights``) for a live SB3 model.

    Args:
        model: a trained SB3 / sb3-contrib algorithm.
        env_id: the training env id.
        env_kwargs: the training env kwargs (``observation`` and ``action_type`` are read from them,
            else from the env's defaults: belief, continuous).
        frame_stack: frames stacked by ``VecFrameStack`` (1: none).
        vecnormalize: the training ``VecNormalize`` (or None).
        provenance: plain-data provenance (command, seed, timesteps, versions).
        evaluation: the evaluation row that chose this checkpoint, if any.
    """
    obs_space = model.policy.observation_space
    shape = list(obs_space.shape)
    if len(shape) != 1 or shape[0] % frame_stack:
        raise PolicyFormatError(f"observation shape {shape} does not fit frame_stack={frame_stack}")
    kw = dict(env_kwargs)
    return {
        "algo": type(model).__name__.lower(),
        "architecture": _architecture(model),
        "observation": {
            "env_id": env_id,
            "mode": str(kw.get("observation", "belief")),
            "frame_stack": int(frame_stack),
            "frame_dim": shape[0] // frame_stack,
            "shape": shape,
            "space": space_to_json(obs_space),
        },
        "action": {
            "action_type": str(kw.get("action_type", "continuous")),
            "space": space_to_json(model.policy.action_space),
        },
        "normalization": normalization_from_vecnormalize(vecnormalize),
        "env_kwargs": kw,
        "provenance": dict(provenance),
        "evaluation": None if evaluation is None else dict(evaluation),
    }


def sb3_policy(meta: Mapping[str, Any], weights: Mapping[str, np.ndarray]) -> Any:
    """The SB3 policy network of an export (for stochastic actions), weights loaded strictly."""
    import torch

    arch = meta["architecture"]
    module, attr = POLICY_CLASSES[arch["policy_class"]].split(":")
    cls = getattr(importlib.import_module(module), attr)
    kwargs = dict(arch["policy_kwargs"])
    if "activation_fn" in kwargs:
        kwargs["activation_fn"] = getattr(torch.nn, ACTIVATIONS[kwargs["activation_fn"]])
    try:
        policy = cls(
            space_from_json(meta["observation"]["space"]),
            space_from_json(meta["action"]["space"]),
            lambda _: 0.0,
            **kwargs,
        )
        policy.load_state_dict({k: torch.as_tensor(v) for k, v in weights.items()}, strict=True)
    except (TypeError, ValueError, RuntimeError, KeyError) as exc:
        raise PolicyFormatError(f"the weights do not fit the architecture: {type(exc).__name__}: {exc}") from exc
    policy.set_training_mode(False)
    return policy


def load_zoo_run(zip_path: str | Path) -> tuple[Any, Any, dict[str, Any]]:
    """A TRUSTED rl-zoo3 model zip → (model, VecNormalize or None, its run's config and args).

    Unpickles the zip and ``<run>/<env>/vecnormalize.pkl``: only for files you trust.
    """
    from rl_zoo3.utils import ALGOS

    zp = Path(zip_path)
    run = zp.parent
    env_dirs = [d for d in run.iterdir() if d.is_dir() and (d / "config.yml").is_file()]
    cfg = read_zoo_yaml(env_dirs[0] / "config.yml") if env_dirs else {}
    args = read_zoo_yaml(env_dirs[0] / "args.yml") if env_dirs and (env_dirs[0] / "args.yml").is_file() else {}
    algo = str(args.get("algo", "ppo"))
    custom = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
    try:
        model = ALGOS[algo].load(zp, device="cpu", custom_objects=custom)
    except Exception as exc:  # SB3 raises many kinds (BadZipFile, KeyError, pickle errors)
        raise ValueError(f"cannot load {zp} as a {algo} model: {type(exc).__name__}: {exc}") from exc
    vn = None
    vn_path = env_dirs[0] / "vecnormalize.pkl" if env_dirs else run / "vecnormalize.pkl"
    if vn_path.is_file():
        with vn_path.open("rb") as fh:
            vn = pickle.load(fh)  # noqa: S301 - trusted by the caller
    return model, vn, {"config": cfg, "args": args}


def model_from_sb3_zip(zip_path: str | Path) -> tuple[Any, dict[str, Any]]:
    """A TRUSTED SB3 zip of an rl-zoo3 run → (model, its export metadata), converted in memory (unpickles)."""
    model, vn, run = load_zoo_run(zip_path)
    args = run["args"]
    env_kwargs = {**dict(run["config"].get("env_kwargs") or {}), **dict(args.get("env_kwargs") or {})}
    meta = export_meta(
        model,
        env_id=str(args.get("env", PAPER_ENV_ID)),
        env_kwargs=env_kwargs,
        frame_stack=int(run["config"].get("frame_stack") or 1),
        vecnormalize=vn,
        provenance={"converted_from": str(zip_path)},
    )
    if vn is not None and vn.norm_obs:
        ObsNormalization(np.asarray(vn.obs_rms.mean), np.asarray(vn.obs_rms.var))  # validates the statistics
    return model, meta
