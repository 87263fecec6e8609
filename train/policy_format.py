"""The project's policy format: weights in safetensors, everything else in JSON — nothing is unpickled.

A model directory written by ``python -m electroloc_gym.train`` (and by
``python -m electroloc_gym.train.export``) holds::

    policy.json          architecture, observation layout and normalisation, action space, provenance
    policy.safetensors   the policy network's tensors (torch ``state_dict`` names and dtypes)
    model.zip            Stable-Baselines3's own file, for SB3 users — pickle inside, never read by default
    config.yml           the run's resolved configuration (read with ``yaml.safe_load``)

Loading rebuilds the network from ``policy.json`` — the policy class is looked up by name in
:data:`POLICY_CLASSES` (a fixed list, so the file cannot name arbitrary code), the activation in
:data:`ACTIVATIONS` — then loads the tensors with ``load_state_dict(strict=True)``. ``policy.json``
carries the SHA-256 of the weights file, so a weights file that does not belong to it is refused.
The JSON layout is documented field by field in :func:`export_policy`.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from electroloc_gym.fileio import atomic_write_bytes, atomic_write_text
from electroloc_gym.train.json_codec import (
    PolicyFormatError,
    dump_json,
    finite_or_none,
    floats_from_json,
    floats_to_json,
    json_value,
    space_from_json,
    space_to_json,
)

__all__ = [
    "ACTIVATIONS",
    "FORMAT",
    "FORMAT_VERSION",
    "POLICY_CLASSES",
    "POLICY_JSON",
    "WEIGHTS_FILE",
    "ObsNormalization",
    "PolicyExport",
    "PolicyFormatError",
    "build_policy",
    "dump_json",
    "export_policy",
    "normalization_from_vecnormalize",
    "read_export",
    "space_from_json",
    "space_to_json",
]

FORMAT = "electroloc-gym-policy"
FORMAT_VERSION = 1
POLICY_JSON = "policy.json"
WEIGHTS_FILE = "policy.safetensors"

#: Policy class name in policy.json → "module:attribute". Only these can be rebuilt.
POLICY_CLASSES: dict[str, str] = {
    "ActorCriticPolicy": "stable_baselines3.common.policies:ActorCriticPolicy",
    "RecurrentActorCriticPolicy": "sb3_contrib.common.recurrent.policies:RecurrentActorCriticPolicy",
    "SACPolicy": "stable_baselines3.sac.policies:SACPolicy",
    "TD3Policy": "stable_baselines3.td3.policies:TD3Policy",
    "DQNPolicy": "stable_baselines3.dqn.policies:DQNPolicy",
    "TQCPolicy": "sb3_contrib.tqc.policies:TQCPolicy",
    "QRDQNPolicy": "sb3_contrib.qrdqn.policies:QRDQNPolicy",
}

#: Activation name (as written in YAML and policy.json) → ``torch.nn`` class name.
ACTIVATIONS: dict[str, str] = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU",
                               "gelu": "GELU", "silu": "SiLU"}

# Constructor keywords that only matter for training (the optimiser) or are rebuilt here.
_DROPPED_KWARGS = ("optimizer_class", "optimizer_kwargs", "features_extractor_class", "features_extractor_kwargs")


@dataclass(frozen=True)
class ObsNormalization:
    """Frozen observation statistics: ``clip((x − mean) / sqrt(var + epsilon), −clip_obs, clip_obs)``.

    Attributes:
        mean: per-feature mean of the network input (after frame stacking), shape (d,).
        var: per-feature variance, shape (d,), ≥ 0.
        clip_obs: clip of the normalised value (> 0).
        epsilon: added to the variance (> 0).
    """

    mean: np.ndarray
    var: np.ndarray
    clip_obs: float = 10.0
    epsilon: float = 1e-8

    def __post_init__(self) -> None:
        mean = np.asarray(self.mean, dtype=np.float64)
        var = np.asarray(self.var, dtype=np.float64)
        if mean.ndim != 1 or var.shape != mean.shape or mean.size == 0:
            raise PolicyFormatError(f"normalisation mean and var must be equal-length 1-D arrays, got shapes "
                                    f"{mean.shape} and {var.shape}")
        if not (np.isfinite(mean).all() and np.isfinite(var).all() and (var >= 0).all()):
            raise PolicyFormatError("normalisation mean/var must be finite and var ≥ 0")
        for name in ("clip_obs", "epsilon"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise PolicyFormatError(f"normalisation {name} must be a finite number > 0, got {v!r}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "var", var)

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Normalise rows of ``x`` exactly as SB3's ``VecNormalize.normalize_obs`` does."""
        return np.clip((x - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs)


@dataclass(frozen=True)
class PolicyExport:
    """A parsed, validated ``policy.json`` plus its folder (weights are read by :func:`build_policy`)."""

    folder: Path
    meta: dict[str, Any]
    normalization: ObsNormalization | None

    @property
    def frame_stack(self) -> int:
        return int(self.meta["observation"]["frame_stack"])

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The env kwargs the policy depends on (observation mode, action type)."""
        return {"observation": self.meta["observation"]["mode"], "action_type": self.meta["action"]["action_type"]}

    @property
    def recurrent(self) -> bool:
        return self.meta["architecture"]["recurrent"] is not None


# --------------------------------------------------------------------------------- architecture
def _activation_name(cls: Any) -> str:
    for name, attr in ACTIVATIONS.items():
        if getattr(cls, "__name__", None) == attr and getattr(cls, "__module__", "").startswith("torch.nn"):
            return name
    raise PolicyFormatError(f"cannot export activation_fn {cls!r}; supported: {list(ACTIVATIONS)}")


def _architecture(model: Any) -> dict[str, Any]:
    """The policy's class name and the exact constructor keywords needed to rebuild it."""
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
    from stable_baselines3.common.torch_layers import FlattenExtractor

    policy = model.policy
    name = type(policy).__name__
    if name not in POLICY_CLASSES or POLICY_CLASSES[name] != f"{type(policy).__module__}:{name}":
        raise PolicyFormatError(f"cannot export a {type(policy).__module__}.{name} policy; supported: "
                                f"{sorted(POLICY_CLASSES)}")
    kwargs = dict(model.policy_kwargs or {})
    fe = kwargs.get("features_extractor_class", FlattenExtractor)
    if fe is not FlattenExtractor or kwargs.get("features_extractor_kwargs"):
        raise PolicyFormatError("cannot export a custom features extractor (only the flat MLP input)")
    for key in _DROPPED_KWARGS:
        kwargs.pop(key, None)
    for attr in ("net_arch", "activation_fn", "share_features_extractor"):  # explicit, not version defaults
        if hasattr(policy, attr):
            kwargs[attr] = getattr(policy, attr)
    if isinstance(model, OnPolicyAlgorithm):
        kwargs["use_sde"] = bool(model.use_sde)  # on-policy algorithms pass it beside policy_kwargs
    recurrent = None
    if name == "RecurrentActorCriticPolicy":
        recurrent = {"lstm_hidden_size": int(policy.lstm_actor.hidden_size),
                     "n_lstm_layers": int(policy.lstm_actor.num_layers),
                     "shared_lstm": bool(policy.shared_lstm),
                     "enable_critic_lstm": policy.lstm_critic is not None}
        kwargs.update(recurrent)
    if "activation_fn" in kwargs:
        kwargs["activation_fn"] = _activation_name(kwargs["activation_fn"])
    return {"policy_class": name, "policy_kwargs": json_value(kwargs, "policy_kwargs"), "recurrent": recurrent}


def normalization_from_vecnormalize(vn: Any) -> dict[str, Any] | None:
    """The JSON ``normalization`` section from a live ``VecNormalize`` (None when there is none).

    Observation statistics are what inference needs; the return statistics are kept so that a
    resumed run continues reward normalisation where it stopped.
    """
    if vn is None:
        return None
    out: dict[str, Any] = {
        "norm_obs": bool(vn.norm_obs), "norm_reward": bool(vn.norm_reward),
        "clip_obs": float(vn.clip_obs), "clip_reward": float(vn.clip_reward), "epsilon": float(vn.epsilon),
        "gamma": float(vn.gamma), "obs_mean": None, "obs_var": None, "obs_count": None,
        "return_mean": float(np.asarray(vn.ret_rms.mean)), "return_var": float(np.asarray(vn.ret_rms.var)),
        "return_count": float(vn.ret_rms.count),
    }
    if vn.norm_obs:
        rms = vn.obs_rms
        if isinstance(rms, dict):
            raise PolicyFormatError("cannot export normalisation of a Dict observation space")
        out.update(obs_mean=floats_to_json(rms.mean), obs_var=floats_to_json(rms.var), obs_count=float(rms.count))
    return out


# ------------------------------------------------------------------------------------- writing
def export_policy(model: Any, folder: str | Path, *, observation: Mapping[str, Any],
                  normalization: Mapping[str, Any] | None, provenance: Mapping[str, Any],
                  evaluation: Mapping[str, Any] | None = None) -> Path:
    """Write ``policy.safetensors`` then ``policy.json`` for ``model`` (both atomically).

    ``policy.json`` (format ``electroloc-gym-policy``, version 1) holds:

    * ``format``, ``format_version``.
    * ``weights``: ``{"file": "policy.safetensors", "sha256": hex, "tensors": n}``.
    * ``algo`` (e.g. ``"ppo"``) and ``architecture``: ``{"policy_class": name in POLICY_CLASSES,
      "policy_kwargs": {net_arch, activation_fn (name), log_std_init, use_sde, ...},
      "recurrent": null | {lstm_hidden_size, n_lstm_layers, shared_lstm, enable_critic_lstm}}``.
    * ``observation``: ``{"env_id", "mode" ("belief"/"raw"), "frame_stack", "frame_dim" (one frame's
      length), "shape" (network input), "space" (the network's Box)}``.
    * ``action``: ``{"action_type" ("continuous"/"discrete"), "space"}``.
    * ``normalization``: null or ``{"norm_obs", "obs_mean", "obs_var", "obs_count", "clip_obs",
      "epsilon", "norm_reward", "clip_reward", "gamma", "return_mean", "return_var", "return_count"}``.
    * ``env_kwargs``: the training env kwargs (for reference); ``provenance``: command, seed,
      timesteps, git commit, package versions; ``evaluation``: null or the evaluation row that
      selected this model.

    Args:
        model: a trained SB3 / sb3-contrib algorithm.
        folder: the model directory.
        observation: ``env_id``, ``mode``, ``action_type``, ``frame_stack`` and ``env_kwargs``.
        normalization: :func:`normalization_from_vecnormalize` output, or None.
        provenance: plain-data provenance (command, seed, timesteps, git commit, versions).
        evaluation: the evaluation row of this model, if any.

    Raises:
        PolicyFormatError: the policy cannot be described by the format (custom classes, Dict spaces).
    """
    from safetensors.torch import save as save_tensors

    d = Path(folder)
    arch = _architecture(model)
    obs_space, act_space = model.policy.observation_space, model.policy.action_space
    frame_stack = int(observation.get("frame_stack", 1))
    obs_shape = list(getattr(obs_space, "shape", ()) or ())
    if len(obs_shape) != 1 or obs_shape[0] % frame_stack:
        raise PolicyFormatError(f"observation shape {obs_shape} does not fit frame_stack={frame_stack}")
    tensors = {k: v.detach().cpu().contiguous().clone() for k, v in model.policy.state_dict().items()}
    blob = save_tensors(tensors, metadata={"format": FORMAT})
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "weights": {"file": WEIGHTS_FILE, "sha256": hashlib.sha256(blob).hexdigest(), "tensors": len(tensors)},
        "algo": str(observation.get("algo") or type(model).__name__.lower()),
        "architecture": arch,
        "observation": {"env_id": str(observation["env_id"]), "mode": str(observation["mode"]),
                        "frame_stack": frame_stack, "frame_dim": obs_shape[0] // frame_stack,
                        "shape": obs_shape, "space": space_to_json(obs_space)},
        "action": {"action_type": str(observation["action_type"]), "space": space_to_json(act_space)},
        "normalization": None if normalization is None else json_value(dict(normalization), "normalization"),
        "env_kwargs": json_value(dict(observation.get("env_kwargs") or {}), "env_kwargs"),
        "provenance": json_value(dict(provenance), "provenance"),
        "evaluation": None if evaluation is None else json_value(finite_or_none(evaluation), "evaluation"),
    }
    atomic_write_bytes(d / WEIGHTS_FILE, blob)
    atomic_write_text(d / POLICY_JSON, dump_json(meta) + "\n")
    return d


# ------------------------------------------------------------------------------------- reading
def _need(d: Mapping[str, Any], key: str, types: type | tuple[type, ...], where: str) -> Any:
    if key not in d:
        raise PolicyFormatError(f"{where}: missing key {key!r}")
    v = d[key]
    allowed = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, allowed) or (isinstance(v, bool) and bool not in allowed):
        raise PolicyFormatError(f"{where}: {key!r} has the wrong type ({type(v).__name__})")
    return v


def read_export(folder: str | Path) -> PolicyExport:
    """Parse and validate ``folder/policy.json`` (the weights are checked by :func:`build_policy`).

    Raises:
        PolicyFormatError: no policy.json, invalid JSON, wrong format/version, a missing or mistyped
            field, or statistics that do not fit the observation shape.
    """
    d = Path(folder)
    path = d / POLICY_JSON
    if not path.is_file():
        raise PolicyFormatError(f"{d} has no {POLICY_JSON}")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PolicyFormatError(f"{path} is not valid JSON: {exc}") from exc
    where = str(path)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise PolicyFormatError(f"{where} is not an {FORMAT} file")
    if meta.get("format_version") != FORMAT_VERSION:
        raise PolicyFormatError(f"{where}: format_version {meta.get('format_version')!r} is not supported "
                                f"(this version reads {FORMAT_VERSION})")
    weights = _need(meta, "weights", dict, where)
    if weights.get("file") != WEIGHTS_FILE or not isinstance(weights.get("sha256"), str):
        raise PolicyFormatError(f"{where}: weights must name {WEIGHTS_FILE!r} and its sha256")
    _need(meta, "algo", str, where)
    arch = _need(meta, "architecture", dict, where)
    if arch.get("policy_class") not in POLICY_CLASSES:
        raise PolicyFormatError(f"{where}: architecture.policy_class must be one of {sorted(POLICY_CLASSES)}, "
                                f"got {arch.get('policy_class')!r}")
    pk = _need(arch, "policy_kwargs", dict, f"{where} architecture")
    if "activation_fn" in pk and pk["activation_fn"] not in ACTIVATIONS:
        raise PolicyFormatError(f"{where}: activation_fn must be one of {list(ACTIVATIONS)}, "
                                f"got {pk['activation_fn']!r}")
    if arch.get("recurrent") is not None and not isinstance(arch["recurrent"], dict):
        raise PolicyFormatError(f"{where}: architecture.recurrent must be null or an object")
    obs = _need(meta, "observation", dict, where)
    for key, types in (("env_id", str), ("mode", str), ("frame_stack", int), ("frame_dim", int), ("shape", list)):
        _need(obs, key, types, f"{where} observation")
    space = space_from_json(obs.get("space"), f"{where} observation.space")
    if list(space.shape) != obs["shape"] or obs["frame_stack"] < 1 or obs["frame_dim"] * obs["frame_stack"] != \
            obs["shape"][0]:
        raise PolicyFormatError(f"{where}: observation shape {obs['shape']} does not match its space, frame_stack "
                                f"{obs['frame_stack']} and frame_dim {obs['frame_dim']}")
    act = _need(meta, "action", dict, where)
    _need(act, "action_type", str, f"{where} action")
    space_from_json(act.get("space"), f"{where} action.space")
    norm = meta.get("normalization")
    stats = None
    if norm is not None:
        if not isinstance(norm, dict):
            raise PolicyFormatError(f"{where}: normalization must be null or an object")
        if norm.get("norm_obs", False):
            if norm.get("obs_mean") is None or norm.get("obs_var") is None:
                raise PolicyFormatError(f"{where}: normalization.norm_obs is true but the observation statistics "
                                        f"(obs_mean, obs_var) are missing — refusing to run on raw observations")
            stats = ObsNormalization(floats_from_json(norm["obs_mean"], f"{where} obs_mean"),
                                     floats_from_json(norm["obs_var"], f"{where} obs_var"),
                                     clip_obs=norm.get("clip_obs", 10.0), epsilon=norm.get("epsilon", 1e-8))
            if stats.mean.shape[0] != obs["shape"][0]:
                raise PolicyFormatError(f"{where}: normalisation statistics have {stats.mean.shape[0]} features, "
                                        f"the observation has {obs['shape'][0]}")
    return PolicyExport(folder=d, meta=meta, normalization=stats)


def _import(spec: str) -> Any:
    module, attr = spec.split(":")
    try:
        return getattr(importlib.import_module(module), attr)
    except ImportError as exc:
        raise PolicyFormatError(f"rebuilding this policy needs the package {module.split('.')[0]!r} "
                                f"(pip install 'electroloc-gym[train]'): {exc}") from exc


def build_policy(export: PolicyExport, device: str = "cpu") -> Any:
    """Rebuild the torch policy of ``export`` and load its weights (strict: every tensor, every shape).

    Raises:
        PolicyFormatError: missing/altered weights file (SHA-256 mismatch), unreadable tensors, or
            tensors that do not fit the architecture.
    """
    import torch
    from safetensors import SafetensorError
    from safetensors.torch import load as load_tensors

    meta = export.meta
    wpath = export.folder / WEIGHTS_FILE
    if not wpath.is_file():
        raise PolicyFormatError(f"{export.folder} has {POLICY_JSON} but no {WEIGHTS_FILE}")
    blob = wpath.read_bytes()
    if hashlib.sha256(blob).hexdigest() != meta["weights"]["sha256"]:
        raise PolicyFormatError(f"{wpath} does not match the sha256 recorded in {POLICY_JSON} (altered or mixed files)")
    try:
        tensors = load_tensors(blob)
    except (SafetensorError, ValueError, RuntimeError) as exc:
        raise PolicyFormatError(f"{wpath} is not a readable safetensors file: {exc}") from exc
    arch = meta["architecture"]
    cls = _import(POLICY_CLASSES[arch["policy_class"]])
    kwargs = dict(arch["policy_kwargs"])
    if "activation_fn" in kwargs:
        kwargs["activation_fn"] = getattr(torch.nn, ACTIVATIONS[kwargs["activation_fn"]])
    obs_space = space_from_json(meta["observation"]["space"])
    act_space = space_from_json(meta["action"]["space"])
    try:
        policy = cls(obs_space, act_space, lambda _: 0.0, **kwargs)
        policy.load_state_dict(tensors, strict=True)
    except (TypeError, ValueError, RuntimeError, KeyError) as exc:
        raise PolicyFormatError(f"{export.folder}: the weights do not fit the architecture in {POLICY_JSON}: "
                                f"{type(exc).__name__}: {exc}") from exc
    policy.set_training_mode(False)
    return policy.to(device)
