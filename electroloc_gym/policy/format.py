"""The pickle-free policy format: weights in safetensors, everything else in JSON.

A policy folder holds::

    policy.json          architecture, observation layout and normalisation, action space, provenance
    policy.safetensors   the policy network's tensors (torch ``state_dict`` names and dtypes)

``policy.json`` (``format`` = ``"electroloc-gym-policy"``, ``format_version`` 1):

* ``weights``: ``{"file": "policy.safetensors", "sha256": hex, "tensors": n}`` — a weights file that
  does not belong to the JSON is refused.
* ``algo`` (``"ppo"``, ``"sac"``, …) and ``architecture``: ``{"policy_class": one of POLICY_CLASSES,
  "policy_kwargs": {net_arch, activation_fn (a name in ACTIVATIONS), …}, "recurrent": null |
  {lstm_hidden_size, n_lstm_layers, shared_lstm, enable_critic_lstm}}``.
* ``observation``: ``{"env_id", "mode" ("belief"/"raw"), "frame_stack", "frame_dim", "shape" (network
  input), "space"}``; ``action``: ``{"action_type" ("continuous"/"discrete"), "space"}``.
* ``normalization``: null or VecNormalize's frozen statistics (``norm_obs``, ``obs_mean``, ``obs_var``,
  ``clip_obs``, ``epsilon``, …). Statistics of ``frame_dim`` values normalise each frame before
  stacking (rl-zoo3's order: ``VecNormalize`` inside ``VecFrameStack``); statistics of the stacked
  vector normalise after stacking (files written before the rl-zoo3 path).
* ``env_kwargs`` (training env kwargs, for reference), ``provenance`` and ``evaluation`` (plain data).

Every field is read with its JSON type checked (:func:`read_export`): a number where a number goes (finite,
never a boolean), a boolean where a flag goes (``"norm_obs": "yes"`` is refused, not read as true),
integers ≥ 1 for sizes, ``policy_kwargs`` only with the keys :data:`POLICY_KWARGS` lists (they are passed to
SB3's policy class for stochastic actions), ``recurrent`` exactly for the recurrent policy class, and the
``action_type`` the action space's type (:data:`ACTION_SPACE_TYPES`).

Reading never unpickles or executes anything: JSON is parsed, spaces are rebuilt from plain values,
and the safetensors file is read and written by the reference library's numpy interface
(``safetensors.numpy``: no torch needed). What this module adds is what the format does not say:
the SHA-256 that ties the weights to their JSON, finite weights, and one :class:`PolicyFormatError`
naming the file for any damage.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.utils.fileio import atomic_write_bytes, write_json_atomic

__all__ = [
    "ACTION_SPACE_TYPES",
    "ACTIVATIONS",
    "POLICY_KWARGS",
    "FORMAT",
    "FORMAT_VERSION",
    "POLICY_CLASSES",
    "POLICY_JSON",
    "WEIGHTS_FILE",
    "ObsNormalization",
    "PolicyExport",
    "PolicyFormatError",
    "read_export",
    "read_weights",
    "space_from_json",
    "space_to_json",
    "write_export",
]

FORMAT = "electroloc-gym-policy"
FORMAT_VERSION = 1
POLICY_JSON = "policy.json"
WEIGHTS_FILE = "policy.safetensors"

#: Policy class name in policy.json → "module:attribute" of the SB3 class (for stochastic actions).
POLICY_CLASSES: dict[str, str] = {
    "ActorCriticPolicy": "stable_baselines3.common.policies:ActorCriticPolicy",
    "RecurrentActorCriticPolicy": "sb3_contrib.common.recurrent.policies:RecurrentActorCriticPolicy",
    "SACPolicy": "stable_baselines3.sac.policies:SACPolicy",
    "DQNPolicy": "stable_baselines3.dqn.policies:DQNPolicy",
    "QRDQNPolicy": "sb3_contrib.qrdqn.policies:QRDQNPolicy",
}

#: Activation name (as written in policy.json) → ``torch.nn`` class name.
ACTIVATIONS: dict[str, str] = {
    "tanh": "Tanh",
    "relu": "ReLU",
    "elu": "ELU",
    "leaky_relu": "LeakyReLU",
    "gelu": "GELU",
    "silu": "SiLU",
}


#: ``policy_kwargs`` keys a policy file may hold, by the JSON value each takes: ``"arch"`` a network layout
#: (a list of layer sizes, or ``{"pi": [...], "vf" | "qf": [...]}``), ``"activation"`` a name of
#: :data:`ACTIVATIONS`, ``"flag"`` a boolean, ``"count"`` an integer ≥ 1, ``"number"`` a finite number.
POLICY_KWARGS: dict[str, str] = {
    "net_arch": "arch",
    "activation_fn": "activation",
    "log_std_init": "number",
    "ortho_init": "flag",
    "share_features_extractor": "flag",
    "use_sde": "flag",
    "squash_output": "flag",
    "full_std": "flag",
    "use_expln": "flag",
    "normalize_images": "flag",
    "n_quantiles": "count",
    "n_critics": "count",
    "lstm_hidden_size": "count",
    "n_lstm_layers": "count",
    "shared_lstm": "flag",
    "enable_critic_lstm": "flag",
}
#: ``architecture.recurrent``'s keys (the recurrent policy class's LSTM), by kind as above.
RECURRENT_KEYS: dict[str, str] = {
    "lstm_hidden_size": "count",
    "n_lstm_layers": "count",
    "shared_lstm": "flag",
    "enable_critic_lstm": "flag",
}
#: The policy class whose file holds ``recurrent`` (null for every other class).
RECURRENT_CLASS = "RecurrentActorCriticPolicy"
#: ``action.action_type`` → the type of ``action.space`` it needs.
ACTION_SPACE_TYPES: dict[str, str] = {"continuous": "Box", "discrete": "Discrete"}
#: ``normalization``'s keys by kind (``"stats"``: a list of numbers or null; the others as above, ``"number?"``
#: a number or null). Keys beyond these are VecNormalize's and unused.
NORMALIZATION_KEYS: dict[str, str] = {
    "norm_obs": "flag",
    "norm_reward": "flag",
    "clip_obs": "number",
    "clip_reward": "number",
    "epsilon": "number",
    "gamma": "number",
    "obs_mean": "stats",
    "obs_var": "stats",
    "obs_count": "number?",
    "return_mean": "number?",
    "return_var": "number?",
    "return_count": "number?",
}


class PolicyFormatError(ValueError):
    """A policy folder or file is missing, malformed, or does not describe a loadable policy."""


def one_line(exc: BaseException, limit: int = 200) -> str:
    """``exc`` as ``Type: first line``, cut to ``limit`` characters (a library's message may be a page)."""
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    return f"{type(exc).__name__}: {first[:limit]}{'…' if len(first) > limit or len(text) > 1 else ''}"


@dataclass(frozen=True)
class ObsNormalization:
    """Frozen observation statistics: ``clip((x − mean) / sqrt(var + epsilon), −clip_obs, clip_obs)``.

    Attributes:
        mean: per-feature mean, shape (d,).
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
            raise PolicyFormatError(
                f"normalisation mean and var must be equal-length 1-D arrays, got shapes {mean.shape} and {var.shape}"
            )
        big = float(np.finfo(np.float32).max)  # the observations are float32: statistics beyond it describe none
        if not (
            np.isfinite(mean).all()
            and np.isfinite(var).all()
            and (var >= 0).all()
            and (np.abs(mean) <= big).all()
            and (var <= big).all()
        ):
            raise PolicyFormatError(f"normalisation mean/var must be finite, within ±{big:.3g} and var ≥ 0")
        for name in ("clip_obs", "epsilon"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise PolicyFormatError(f"normalisation {name} must be a finite number > 0, got {v!r}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "var", var)

    def apply(self, x: NDArray[np.floating[Any]]) -> NDArray[np.float64]:
        """Normalise rows of ``x`` exactly as SB3's ``VecNormalize.normalize_obs`` does.

        A quotient that overflows (a tiny variance under a far mean) is ±inf before the clip, which gives
        exactly ±``clip_obs``: the overflow is expected and silenced.
        """
        with np.errstate(over="ignore"):
            return np.clip((x - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs)


@dataclass(frozen=True)
class PolicyExport:
    """A parsed, validated ``policy.json`` plus its folder."""

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


# ------------------------------------------------------------------------------------ spaces, JSON
def floats_to_json(a: Any) -> list[Any]:
    """Numbers as a flat JSON list; ±inf as the strings "inf", "-inf" (NaN is refused)."""
    out = []
    for v in np.asarray(a, dtype=np.float64).reshape(-1).tolist():
        if math.isnan(v):
            raise PolicyFormatError("cannot write NaN into a policy file")
        out.append(v if math.isfinite(v) else ("inf" if v > 0 else "-inf"))
    return out


def floats_from_json(values: Any, where: str) -> np.ndarray:
    """Inverse of :func:`floats_to_json` (``where`` names the field in errors)."""
    if not isinstance(values, list):
        raise PolicyFormatError(f"{where} must be a list of numbers")
    out = []
    for v in values:
        if isinstance(v, str) and v in ("inf", "-inf"):
            out.append(float(v))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out.append(float(v))
        else:
            raise PolicyFormatError(f"{where} must hold numbers, got {v!r}")
    return np.asarray(out, dtype=np.float64)


def space_to_json(space: Any) -> dict[str, Any]:
    """A Gymnasium ``Box`` or ``Discrete`` as plain JSON."""
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "dtype": str(space.dtype),
            "low": floats_to_json(space.low),
            "high": floats_to_json(space.high),
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    raise PolicyFormatError(f"cannot export a {type(space).__name__} space (only Box and Discrete)")


def space_from_json(d: Any, where: str = "space") -> Any:
    """Inverse of :func:`space_to_json`."""
    from gymnasium import spaces

    if not isinstance(d, dict) or d.get("type") not in ("Box", "Discrete"):
        raise PolicyFormatError(f"{where} must be an object with type 'Box' or 'Discrete', got {d!r}")
    if d["type"] == "Discrete":
        n, start = d.get("n"), d.get("start", 0)
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1 and isinstance(start, int)):
            raise PolicyFormatError(f"{where}: Discrete needs an integer n ≥ 1 and an integer start")
        return spaces.Discrete(n, start=start)
    shape = d.get("shape")
    if not (isinstance(shape, list) and shape and all(isinstance(s, int) and s >= 1 for s in shape)):
        raise PolicyFormatError(f"{where}: Box shape must be a list of positive integers, got {shape!r}")
    if d.get("dtype") not in ("float32", "float64"):
        raise PolicyFormatError(f"{where}: Box dtype must be float32 or float64, got {d.get('dtype')!r}")
    low, high = floats_from_json(d.get("low"), f"{where}.low"), floats_from_json(d.get("high"), f"{where}.high")
    size = int(np.prod(shape))
    if low.size != size or high.size != size:
        raise PolicyFormatError(f"{where}: low/high must have {size} values for shape {shape}")
    if not (low <= high).all():
        raise PolicyFormatError(f"{where}: Box low must not exceed high")
    dtype = np.float32 if d["dtype"] == "float32" else np.float64
    return spaces.Box(low.reshape(shape).astype(dtype), high.reshape(shape).astype(dtype), dtype=dtype)


def json_value(value: Any, where: str) -> Any:
    """``value`` as plain JSON data (tuples → lists, numpy scalars → numbers); classes and NaN are refused."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int, str, type(None))):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise PolicyFormatError(f"cannot export {where} = {value!r} (not finite)")
        return value
    if isinstance(value, (list, tuple)):
        return [json_value(v, where) for v in value]
    if isinstance(value, Mapping):
        return {str(k): json_value(v, f"{where}.{k}") for k, v in value.items()}
    raise PolicyFormatError(f"cannot export {where} = {value!r} (not plain data)")


# ------------------------------------------------------------------------------------- weights
def _safetensors_bytes(tensors: Mapping[str, np.ndarray]) -> bytes:
    import safetensors.numpy as st

    try:
        return st.save({name: np.ascontiguousarray(a) for name, a in tensors.items()}, metadata={"format": FORMAT})
    except Exception as exc:  # the library raises its own error types for dtypes it cannot hold
        raise PolicyFormatError(f"cannot write the policy tensors: {one_line(exc)}") from exc


def read_weights(export: PolicyExport) -> dict[str, np.ndarray]:
    """The tensors of ``policy.safetensors`` as numpy arrays, after checking the SHA-256 in ``policy.json``.

    Raises:
        PolicyFormatError: a missing or altered file, one that is not a safetensors file, or weights that
            are not all finite (a NaN or infinite weight makes every action NaN).
    """
    import safetensors.numpy as st

    path = export.folder / WEIGHTS_FILE
    if not path.is_file():
        raise PolicyFormatError(f"{export.folder} has {POLICY_JSON} but no {WEIGHTS_FILE}")
    blob = path.read_bytes()
    if hashlib.sha256(blob).hexdigest() != export.meta["weights"]["sha256"]:
        raise PolicyFormatError(f"{path} does not match the sha256 recorded in {POLICY_JSON} (altered or mixed files)")
    try:
        out = {name: np.array(a) for name, a in st.load(blob).items()}
    except Exception as exc:  # safetensors raises SafetensorError (not a ValueError) on a damaged header
        raise PolicyFormatError(f"{path} is not a readable safetensors file: {one_line(exc)}") from exc
    for name, a in out.items():
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise PolicyFormatError(f"{path}: tensor {name!r} holds non-finite weights (NaN or infinity)")
    return out


def write_export(folder: str | Path, meta: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> Path:
    """Write ``policy.safetensors`` then ``policy.json`` (both atomically); ``meta`` without ``weights``.

    The JSON is written last and names the SHA-256 of the weights, so a reader never pairs a new
    JSON with old weights.
    """
    d = Path(folder)
    blob = _safetensors_bytes(tensors)
    full = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "weights": {"file": WEIGHTS_FILE, "sha256": hashlib.sha256(blob).hexdigest(), "tensors": len(tensors)},
        **json_value(dict(meta), "policy"),
    }
    atomic_write_bytes(d / WEIGHTS_FILE, blob)
    write_json_atomic(d / POLICY_JSON, full)
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


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _is_count(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 1


def _is_layers(v: Any) -> bool:
    return isinstance(v, list) and all(_is_count(x) for x in v)


def _is_arch(v: Any) -> bool:
    """A list of layer sizes, or the actor's and critic's: ``{"pi": [...], "vf" | "qf": [...]}``."""
    if isinstance(v, dict):
        return bool(v) and set(v) <= {"pi", "vf", "qf"} and all(_is_layers(x) for x in v.values())
    return _is_layers(v)


_KINDS: dict[str, tuple[Any, str]] = {
    "flag": (lambda v: isinstance(v, bool), "true or false"),
    "number": (_is_number, "a finite number"),
    "number?": (lambda v: v is None or _is_number(v), "a finite number or null"),
    "count": (_is_count, "an integer ≥ 1"),
    "stats": (lambda v: v is None or isinstance(v, list), "a list of numbers or null"),
    "activation": (lambda v: isinstance(v, str) and v in ACTIVATIONS, f"one of {list(ACTIVATIONS)}"),
    "arch": (_is_arch, 'a list of layer sizes (integers ≥ 1) or {"pi": [...], "vf"/"qf": [...]}'),
}


def _check_fields(d: Mapping[str, Any], kinds: Mapping[str, str], where: str, *, closed: bool) -> None:
    """Each key of ``d`` listed in ``kinds`` holds a value of its kind; with ``closed`` no other key is allowed."""
    if closed:
        unknown = sorted(str(k) for k in d if k not in kinds)
        if unknown:
            raise PolicyFormatError(f"{where} has unknown key(s) {unknown}; allowed: {sorted(kinds)}")
    for key, kind in kinds.items():
        if key in d:
            ok, what = _KINDS[kind]
            if not ok(d[key]):
                raise PolicyFormatError(f"{where}.{key} must be {what}, got {d[key]!r}")


def normalization_from_json(norm: Any, obs: Mapping[str, Any], where: str) -> ObsNormalization | None:
    """The validated observation statistics of a ``normalization`` entry (None: no normalisation).

    Every key of :data:`NORMALIZATION_KEYS` present must be of its type (``norm_obs`` a boolean, not ``"yes"``).
    """
    if norm is None:
        return None
    if not isinstance(norm, dict):
        raise PolicyFormatError(f"{where}: normalization must be null or an object")
    _check_fields(norm, NORMALIZATION_KEYS, f"{where}: normalization", closed=False)
    if not norm.get("norm_obs", False):
        return None
    if norm.get("obs_mean") is None or norm.get("obs_var") is None:
        raise PolicyFormatError(
            f"{where}: normalization.norm_obs is true but the observation statistics "
            f"(obs_mean, obs_var) are missing — refusing to run on raw observations"
        )
    stats = ObsNormalization(
        floats_from_json(norm["obs_mean"], f"{where} obs_mean"),
        floats_from_json(norm["obs_var"], f"{where} obs_var"),
        clip_obs=norm.get("clip_obs", 10.0),
        epsilon=norm.get("epsilon", 1e-8),
    )
    if stats.mean.shape[0] not in (obs["shape"][0], obs["frame_dim"]):
        raise PolicyFormatError(
            f"{where}: normalisation statistics have {stats.mean.shape[0]} features, the "
            f"observation has {obs['frame_dim']} per frame and {obs['shape'][0]} stacked"
        )
    return stats


def read_export(folder: str | Path) -> PolicyExport:
    """Parse and validate ``folder/policy.json`` (the weights are checked by :func:`read_weights`).

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
    except RecursionError as exc:
        raise PolicyFormatError(f"{path} is nested too deeply to be a policy file") from exc
    where = str(path)
    try:
        return _validated(d, meta, where)
    except PolicyFormatError as exc:
        if where in str(exc):
            raise
        raise PolicyFormatError(f"{where}: {exc}") from exc
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, RecursionError) as exc:
        # a field of a legal JSON type in a place no check above foresaw (e.g. a list where a name goes)
        raise PolicyFormatError(f"{where} does not describe a loadable policy: {one_line(exc)}") from exc


def _validated(d: Path, meta: Any, where: str) -> PolicyExport:
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise PolicyFormatError(f"{where} is not an {FORMAT} file")
    version = meta.get("format_version")
    if not (isinstance(version, int) and not isinstance(version, bool) and version == FORMAT_VERSION):
        raise PolicyFormatError(
            f"{where}: format_version {version!r} is not supported (this version reads {FORMAT_VERSION})"
        )
    weights = _need(meta, "weights", dict, where)
    if weights.get("file") != WEIGHTS_FILE or not isinstance(weights.get("sha256"), str):
        raise PolicyFormatError(f"{where}: weights must name {WEIGHTS_FILE!r} and its sha256")
    if not re.fullmatch(r"[0-9a-f]{64}", weights["sha256"]):
        raise PolicyFormatError(f"{where}: weights.sha256 must be 64 lowercase hex digits, got {weights['sha256']!r}")
    tensors = weights.get("tensors", 0)
    if not (isinstance(tensors, int) and not isinstance(tensors, bool) and tensors >= 0):
        raise PolicyFormatError(f"{where}: weights.tensors must be an integer ≥ 0, got {tensors!r}")
    if not _need(meta, "algo", str, where):
        raise PolicyFormatError(f"{where}: algo must be a non-empty string")
    arch = _need(meta, "architecture", dict, where)
    if not isinstance(arch.get("policy_class"), str) or arch["policy_class"] not in POLICY_CLASSES:
        raise PolicyFormatError(
            f"{where}: architecture.policy_class must be one of {sorted(POLICY_CLASSES)}, "
            f"got {arch.get('policy_class')!r}"
        )
    pk = _need(arch, "policy_kwargs", dict, f"{where} architecture")
    if "activation_fn" in pk and (not isinstance(pk["activation_fn"], str) or pk["activation_fn"] not in ACTIVATIONS):
        raise PolicyFormatError(
            f"{where}: activation_fn must be one of {list(ACTIVATIONS)}, got {pk['activation_fn']!r}"
        )
    _check_fields(pk, POLICY_KWARGS, f"{where}: architecture.policy_kwargs", closed=True)
    recurrent = arch.get("recurrent")
    if arch["policy_class"] == RECURRENT_CLASS:
        if not isinstance(recurrent, dict) or set(recurrent) != set(RECURRENT_KEYS):
            raise PolicyFormatError(
                f"{where}: architecture.recurrent of a {RECURRENT_CLASS} must be an object with exactly "
                f"{sorted(RECURRENT_KEYS)}, got {recurrent!r}"
            )
        _check_fields(recurrent, RECURRENT_KEYS, f"{where}: architecture.recurrent", closed=True)
    elif recurrent is not None:
        raise PolicyFormatError(f"{where}: architecture.recurrent must be null for a {arch['policy_class']}")
    obs = _need(meta, "observation", dict, where)
    for key, types in (("env_id", str), ("mode", str), ("frame_stack", int), ("frame_dim", int), ("shape", list)):
        _need(obs, key, types, f"{where} observation")
    for key in ("env_id", "mode"):
        if not obs[key]:
            raise PolicyFormatError(f"{where}: observation.{key} must be a non-empty string")
    if obs["frame_dim"] < 1:
        raise PolicyFormatError(f"{where}: observation.frame_dim must be an integer ≥ 1, got {obs['frame_dim']!r}")
    space = space_from_json(obs.get("space"), f"{where} observation.space")
    if (
        list(space.shape) != obs["shape"]
        or obs["frame_stack"] < 1
        or obs["frame_dim"] * obs["frame_stack"] != obs["shape"][0]
    ):
        raise PolicyFormatError(
            f"{where}: observation shape {obs['shape']} does not match its space, frame_stack "
            f"{obs['frame_stack']} and frame_dim {obs['frame_dim']}"
        )
    act = _need(meta, "action", dict, where)
    action_type = _need(act, "action_type", str, f"{where} action")
    action_space = space_from_json(act.get("space"), f"{where} action.space")
    if ACTION_SPACE_TYPES.get(action_type) != type(action_space).__name__:
        raise PolicyFormatError(
            f"{where}: action.action_type must be one of {list(ACTION_SPACE_TYPES)} and match the action space "
            f"({ACTION_SPACE_TYPES}), got {action_type!r} with a {type(action_space).__name__}"
        )
    for key, allow_null in (("env_kwargs", False), ("provenance", False), ("evaluation", True)):
        if key in meta and not (isinstance(meta[key], dict) or (allow_null and meta[key] is None)):
            kind = "an object or null" if allow_null else "an object"
            raise PolicyFormatError(f"{where}: {key} must be {kind}, got {type(meta[key]).__name__}")
    return PolicyExport(
        folder=d, meta=meta, normalization=normalization_from_json(meta.get("normalization"), obs, where)
    )
