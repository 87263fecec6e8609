"""The pickle-free policy format: weights in safetensors, everything else in JSON.

A policy folder holds ``policy.json`` (architecture, observation layout and normalisation, action space,
provenance) and ``policy.safetensors`` (the policy network's tensors: torch ``state_dict`` names and dtypes).

``policy.json`` is decoded by msgspec into :class:`PolicyFile`, one ``Struct`` per object declaring each key's
JSON type and range (no key the format does not define; ``normalization`` may keep VecNormalize's other keys);
each refusal is msgspec's one line with the field's path. What no type says is checked after
(:func:`_cross_checks`): each name one of its table's keys, the algo's class, ``recurrent`` exactly for the
recurrent class, ``net_arch`` of the form the class builds, an action type the class acts in and the space fits.

``normalization`` is ``null`` (raw observations: said explicitly, never by leaving the key out) or VecNormalize's
frozen statistics. Statistics of ``frame_dim`` values normalise each frame before stacking (rl-zoo3's order:
``VecNormalize`` inside ``VecFrameStack``); statistics of the stacked vector normalise after stacking.

At load the tensors must be those the declared architecture holds (:mod:`electroloc_gym.policy.tensors`), finite,
and tied to the JSON by its SHA-256: a folder whose parts disagree is one :class:`PolicyFormatError` naming the
file and the field, never half-read. Nothing is unpickled or executed: the safetensors file is read and written
by the library's numpy interface (no torch).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec
import numpy as np
from msgspec import UNSET, Meta, Struct, UnsetType
from numpy.typing import NDArray

from electroloc_gym.contract.observation import OBSERVATION_MODES
from electroloc_gym.policy.errors import PolicyFormatError
from electroloc_gym.policy.tensors import ALGOS, WEIGHTS_FILE, check_tensors, expected_tensors, integer_tensor
from electroloc_gym.utils.fileio import atomic_write_bytes, write_json_atomic

__all__ = [
    "ACTION_SPACE_TYPES",
    "ACTIVATIONS",
    "ALGOS",
    "CLASS_ACTION_TYPES",
    "POLICY_KWARGS",
    "FORMAT",
    "FORMAT_VERSION",
    "POLICY_CLASSES",
    "POLICY_JSON",
    "WEIGHTS_FILE",
    "ObsNormalization",
    "PolicyExport",
    "PolicyFormatError",
    "expected_tensors",
    "integer_tensor",
    "policy_folder",
    "read_export",
    "read_weights",
    "space_from_json",
    "space_to_json",
    "write_export",
]

FORMAT = "electroloc-gym-policy"
FORMAT_VERSION = 1
POLICY_JSON = "policy.json"

#: Policy class name in policy.json → "module:attribute" of the SB3 class (for stochastic actions).
POLICY_CLASSES: dict[str, str] = {
    "ActorCriticPolicy": "stable_baselines3.common.policies:ActorCriticPolicy",
    "RecurrentActorCriticPolicy": "sb3_contrib.common.recurrent.policies:RecurrentActorCriticPolicy",
    "SACPolicy": "stable_baselines3.sac.policies:SACPolicy",
    "DQNPolicy": "stable_baselines3.dqn.policies:DQNPolicy",
    "QRDQNPolicy": "sb3_contrib.qrdqn.policies:QRDQNPolicy",
    "CrossQPolicy": "sb3_contrib.crossq.policies:CrossQPolicy",
}

#: The action type a policy class acts in (a class not listed acts in either).
CLASS_ACTION_TYPES: dict[str, str] = {
    "SACPolicy": "continuous",
    "CrossQPolicy": "continuous",
    "DQNPolicy": "discrete",
    "QRDQNPolicy": "discrete",
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

#: The policy class whose file holds ``recurrent`` (null for every other class).
RECURRENT_CLASS = "RecurrentActorCriticPolicy"
#: ``action.action_type`` → the type of ``action.space`` it needs.
ACTION_SPACE_TYPES: dict[str, str] = {"continuous": "Box", "discrete": "Discrete"}
#: The ``normalization`` keys a file with ``norm_obs`` true must hold.
NORMALIZATION_NEEDED = ("obs_mean", "obs_var", "clip_obs", "epsilon")


def one_line(exc: BaseException, limit: int = 200) -> str:
    """``exc`` as ``Type: first line``, cut to ``limit`` characters (a library's message may be a page)."""
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    return f"{type(exc).__name__}: {first[:limit]}{'…' if len(first) > limit or len(text) > 1 else ''}"


@dataclass(frozen=True)
class ObsNormalization:
    """Frozen observation statistics: ``clip((x − mean) / sqrt(var + epsilon), −clip_obs, clip_obs)``.

    ``mean`` and ``var`` are per feature, shape (d,).
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
        if not ((np.abs(mean) <= big).all() and ((var >= 0) & (var <= big)).all()):  # NaN compares false
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
    """Inverse of :func:`space_to_json`: ``d`` decoded as :class:`BoxSpace` or :class:`DiscreteSpace`."""
    from gymnasium import spaces

    try:
        space = msgspec.convert(d, BoxSpace | DiscreteSpace)
    except msgspec.ValidationError as exc:
        raise PolicyFormatError(f"{where}: {exc}") from None
    if isinstance(space, DiscreteSpace):
        return spaces.Discrete(space.n, start=space.start)
    shape, dtype = space.shape, np.float32 if space.dtype == "float32" else np.float64
    low, high = np.asarray(space.low, dtype=np.float64), np.asarray(space.high, dtype=np.float64)
    size = math.prod(shape)
    if low.size != size or high.size != size:
        raise PolicyFormatError(f"{where}: low/high must have {size} values for shape {shape}")
    if not (low <= high).all():
        raise PolicyFormatError(f"{where}: Box low must not exceed high")
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
        # np.asarray(order="C"), not np.ascontiguousarray: that one makes a 0-d tensor (a counter) 1-d
        return st.save({name: np.asarray(a, order="C") for name, a in tensors.items()}, metadata={"format": FORMAT})
    except Exception as exc:  # the library raises its own error types for dtypes it cannot hold
        raise PolicyFormatError(f"cannot write the policy tensors: {one_line(exc)}") from exc


def read_weights(export: PolicyExport) -> dict[str, np.ndarray]:
    """The tensors of ``policy.safetensors`` as numpy arrays, after checking the SHA-256 in ``policy.json``.

    Raises:
        PolicyFormatError: a missing or altered file, one that is not a safetensors file, weights that
            are not all finite (a NaN or infinite weight makes every action NaN), or tensors that are not
            those the declared architecture builds (:func:`check_tensors`).
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
    check_tensors(export.meta, out, str(export.folder / POLICY_JSON))
    return out


def write_export(folder: str | Path, meta: Mapping[str, Any], tensors: Mapping[str, np.ndarray]) -> Path:
    """Write ``policy.safetensors`` then ``policy.json`` (both atomically); ``meta`` without ``weights``.

    The JSON is written last and names the SHA-256 of the weights, so a reader never pairs a new
    JSON with old weights. Both are checked as :func:`read_export` and :func:`read_weights` check them
    before anything is written: no writer leaves a policy that does not load.

    Raises:
        PolicyFormatError: ``meta`` or ``tensors`` are not a policy of the format (nothing is written).
    """
    d = Path(folder)
    blob = _safetensors_bytes(tensors)
    full = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "weights": {"file": WEIGHTS_FILE, "sha256": hashlib.sha256(blob).hexdigest(), "tensors": len(tensors)},
        **json_value(dict(meta), "policy"),
    }
    where = str(d / POLICY_JSON)
    try:
        _checked(d, full, where)
        check_tensors(full, {name: np.asarray(a) for name, a in tensors.items()}, where)
    except PolicyFormatError as exc:
        raise PolicyFormatError(f"refusing to write a policy that would not load: {exc}") from None
    atomic_write_bytes(d / WEIGHTS_FILE, blob)
    write_json_atomic(d / POLICY_JSON, full)
    return d


# ------------------------------------------------------------------------------------- reading
#: The schema of ``policy.json`` (what no type says is in :func:`_cross_checks`).
Count = Annotated[int, Meta(ge=1)]
Layers = list[Count]
Name = Annotated[str, Meta(min_length=1)]
Floats = list[float | Literal["inf", "-inf"]]


class _Strict(Struct, forbid_unknown_fields=True, omit_defaults=True):
    """An object of the format: no key it does not define."""


class SplitArch(_Strict):
    """The actor's and the critic's layers: ``{"pi": [...], "vf" | "qf": [...]}``."""

    pi: Layers | UnsetType = UNSET
    vf: Layers | UnsetType = UNSET
    qf: Layers | UnsetType = UNSET


class PolicyKwargs(_Strict):
    """``architecture.policy_kwargs``: the keys passed to SB3's policy class (:data:`POLICY_KWARGS`)."""

    net_arch: Layers | SplitArch | UnsetType = UNSET
    activation_fn: Name | UnsetType = UNSET  # a key of ACTIVATIONS
    log_std_init: float | UnsetType = UNSET
    ortho_init: bool | UnsetType = UNSET
    share_features_extractor: bool | UnsetType = UNSET
    use_sde: bool | UnsetType = UNSET
    squash_output: bool | UnsetType = UNSET
    full_std: bool | UnsetType = UNSET
    use_expln: bool | UnsetType = UNSET
    normalize_images: bool | UnsetType = UNSET
    n_quantiles: Count | UnsetType = UNSET
    n_critics: Count | UnsetType = UNSET
    lstm_hidden_size: Count | UnsetType = UNSET
    n_lstm_layers: Count | UnsetType = UNSET
    shared_lstm: bool | UnsetType = UNSET
    enable_critic_lstm: bool | UnsetType = UNSET
    batch_norm: bool | UnsetType = UNSET
    batch_norm_momentum: float | UnsetType = UNSET
    batch_norm_eps: float | UnsetType = UNSET
    renorm_warmup_steps: float | UnsetType = UNSET
    clip_mean: float | UnsetType = UNSET


class Recurrent(_Strict):
    """``architecture.recurrent``: the recurrent policy class's LSTM (:data:`RECURRENT_KEYS`)."""

    lstm_hidden_size: Count
    n_lstm_layers: Count
    shared_lstm: bool
    enable_critic_lstm: bool


class Architecture(_Strict):
    policy_class: Name  # a key of POLICY_CLASSES
    policy_kwargs: PolicyKwargs
    recurrent: Recurrent | None


class Weights(_Strict):
    file: Literal["policy.safetensors"]
    sha256: Annotated[str, Meta(pattern="^[0-9a-f]{64}$")]
    tensors: Count


class BoxSpace(_Strict, tag="Box", tag_field="type"):
    shape: Annotated[list[Count], Meta(min_length=1)]
    dtype: Literal["float32", "float64"]
    low: Floats
    high: Floats


class DiscreteSpace(_Strict, tag="Discrete", tag_field="type"):
    n: Count
    start: int = 0


class Observation(_Strict):
    env_id: Name
    mode: Name  # one of OBSERVATION_MODES
    frame_stack: Count
    frame_dim: Count
    shape: Annotated[list[Count], Meta(min_length=1, max_length=1)]  # the network input: frame_stack · frame_dim
    space: BoxSpace | DiscreteSpace


class Action(_Strict):
    action_type: Name  # a key of ACTION_SPACE_TYPES
    space: BoxSpace | DiscreteSpace


class Normalization(Struct, omit_defaults=True):
    """VecNormalize's frozen statistics (its other keys kept and unused); ``norm_obs`` false: none."""

    norm_obs: bool
    norm_reward: bool | UnsetType = UNSET
    clip_obs: float | UnsetType = UNSET
    clip_reward: float | UnsetType = UNSET
    epsilon: float | UnsetType = UNSET
    gamma: float | UnsetType = UNSET
    obs_mean: Floats | None | UnsetType = UNSET
    obs_var: Floats | None | UnsetType = UNSET
    obs_count: float | None | UnsetType = UNSET
    return_mean: float | None | UnsetType = UNSET
    return_var: float | None | UnsetType = UNSET
    return_count: float | None | UnsetType = UNSET


class PolicyFile(_Strict):
    """``policy.json``; ``env_kwargs`` (the training env's), ``provenance`` and ``evaluation`` are plain data."""

    format: Literal["electroloc-gym-policy"]
    format_version: Literal[1]
    weights: Weights
    algo: Name  # a key of ALGOS
    architecture: Architecture
    observation: Observation
    action: Action
    normalization: Normalization | None
    env_kwargs: dict[str, Any] | UnsetType = UNSET
    provenance: dict[str, Any] | UnsetType = UNSET
    evaluation: dict[str, Any] | None | UnsetType = UNSET


#: ``policy_kwargs`` keys a policy file may hold (passed to SB3's policy class for stochastic actions).
POLICY_KWARGS: tuple[str, ...] = PolicyKwargs.__struct_fields__
#: ``architecture.recurrent``'s keys (the recurrent policy class's LSTM).
RECURRENT_KEYS: tuple[str, ...] = Recurrent.__struct_fields__
#: Where a name of the format must be one of a table's keys (checked after decoding: the tables are the
#: declaration).
_NAMED: tuple[tuple[str, Any], ...] = (
    ("algo", ALGOS),
    ("architecture.policy_class", POLICY_CLASSES),
    ("architecture.policy_kwargs.activation_fn", ACTIVATIONS),
    ("observation.mode", OBSERVATION_MODES),
    ("action.action_type", ACTION_SPACE_TYPES),
)


def normalization_from_json(norm: Any, obs: Mapping[str, Any], where: str) -> ObsNormalization | None:
    """The validated observation statistics of a ``normalization`` entry (None: no normalisation).

    ``null`` and ``{"norm_obs": false, …}`` say "no normalisation"; with ``norm_obs`` true every key of
    :data:`NORMALIZATION_NEEDED` is needed and the statistics fit the observation (per frame or stacked).
    """
    if norm is None:
        return None
    try:
        n = msgspec.convert(norm, Normalization)
    except msgspec.ValidationError as exc:
        raise PolicyFormatError(f"{where}: normalization: {exc}") from None
    if not n.norm_obs:
        return None
    missing = [k for k in NORMALIZATION_NEEDED if getattr(n, k) in (UNSET, None)]
    if missing:
        raise PolicyFormatError(
            f"{where}: normalization.norm_obs is true but {missing} are missing — refusing to run on raw observations"
        )
    # every one set (checked above); ObsNormalization makes the statistics float64 arrays
    stats = ObsNormalization(n.obs_mean, n.obs_var, clip_obs=n.clip_obs, epsilon=n.epsilon)  # type: ignore[arg-type]
    if stats.mean.shape[0] not in (obs["shape"][0], obs["frame_dim"]):
        raise PolicyFormatError(
            f"{where}: normalisation statistics have {stats.mean.shape[0]} features, the "
            f"observation has {obs['frame_dim']} per frame and {obs['shape'][0]} stacked"
        )
    return stats


def policy_folder(path: str | Path) -> Path:
    """The folder whose ``policy.json`` a policy path names: the folder, the ``policy.json`` file's folder, or an
    rl-zoo3 run folder's chosen checkpoint ``best/``; ``path`` itself where none holds one (e.g. an SB3 ``.zip``).
    The one resolution of a policy path: loading a policy and checking it against a run's env both read it.
    """
    p = Path(path)
    if p.is_file() and p.name == POLICY_JSON:
        p = p.parent
    if p.is_dir() and not (p / POLICY_JSON).is_file() and (p / "best" / POLICY_JSON).is_file():
        p = p / "best"
    return p


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
        meta = msgspec.json.decode(path.read_bytes())
    except msgspec.DecodeError as exc:
        raise PolicyFormatError(f"{path} is not valid JSON: {exc}") from None
    except RecursionError:
        raise PolicyFormatError(f"{path} is nested too deeply to be a policy file") from None
    return _checked(d, meta, str(path))


def _checked(d: Path, meta: Any, where: str) -> PolicyExport:
    """``meta`` decoded into :class:`PolicyFile` and cross-checked: one :class:`PolicyFormatError` naming ``where``."""
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise PolicyFormatError(f"{where} is not an {FORMAT} file")
    try:
        spec = msgspec.convert(meta, PolicyFile)
    except msgspec.ValidationError as exc:
        raise PolicyFormatError(f"{where}: {exc}") from None
    try:
        _cross_checks(spec)
        spaces = space_from_json(meta["observation"]["space"]), space_from_json(meta["action"]["space"])
        normalization = normalization_from_json(meta["normalization"], meta["observation"], where)
    except PolicyFormatError as exc:
        raise PolicyFormatError(str(exc) if str(exc).startswith(where) else f"{where}: {exc}") from None
    obs, act = spec.observation, spec.action
    if list(spaces[0].shape) != obs.shape or obs.frame_dim * obs.frame_stack != obs.shape[0]:
        raise PolicyFormatError(
            f"{where}: observation shape {obs.shape} does not match its space, frame_stack "
            f"{obs.frame_stack} and frame_dim {obs.frame_dim} (a flat vector of frame_stack frames)"
        )
    if ACTION_SPACE_TYPES[act.action_type] != type(spaces[1]).__name__:
        raise PolicyFormatError(
            f"{where}: action.action_type must match the action space ({ACTION_SPACE_TYPES}), got "
            f"{act.action_type!r} with a {type(spaces[1]).__name__}"
        )
    return PolicyExport(folder=d, meta=meta, normalization=normalization)


def _cross_checks(spec: PolicyFile) -> None:
    """What no key's type says: the algo's class, the class's ``net_arch`` form, its LSTM and action type."""
    for path, table in _NAMED:
        value: Any = spec
        for part in path.split("."):
            value = getattr(value, part)
        if value is not UNSET and value not in table:
            raise PolicyFormatError(f"{path} must be one of {list(table)}, got {value!r}")
    arch, kind = spec.architecture, spec.architecture.policy_class
    pk = arch.policy_kwargs
    if ALGOS[spec.algo][0] != kind:
        raise PolicyFormatError(
            f"algo {spec.algo!r} goes with architecture.policy_class {ALGOS[spec.algo][0]!r}, got {kind!r}"
        )
    for key in ("net_arch", "n_quantiles") if kind == "QRDQNPolicy" else ("net_arch",):
        if getattr(pk, key) is UNSET:
            raise PolicyFormatError(f"architecture.policy_kwargs.{key} is missing (a {kind} needs it)")
    _check_net_arch(kind, pk.net_arch)
    if pk.use_sde is True:
        raise PolicyFormatError("architecture.policy_kwargs.use_sde must be false (gSDE is not supported)")
    lstm = [k for k in RECURRENT_KEYS if getattr(pk, k) is not UNSET]
    if kind == RECURRENT_CLASS:
        if arch.recurrent is None:
            raise PolicyFormatError(
                f"architecture.recurrent of a {RECURRENT_CLASS} must be an object with exactly {sorted(RECURRENT_KEYS)}"
            )
        if arch.recurrent.shared_lstm and arch.recurrent.enable_critic_lstm:
            raise PolicyFormatError("architecture.recurrent: shared_lstm and enable_critic_lstm exclude each other")
        for key in lstm:
            if getattr(pk, key) != getattr(arch.recurrent, key):
                raise PolicyFormatError(
                    f"architecture.policy_kwargs.{key} is {getattr(pk, key)!r}, architecture.recurrent.{key} is "
                    f"{getattr(arch.recurrent, key)!r}"
                )
    elif arch.recurrent is not None:
        raise PolicyFormatError(f"architecture.recurrent must be null for a {kind}")
    elif lstm:
        raise PolicyFormatError(f"architecture.policy_kwargs holds LSTM keys {sorted(lstm)}, but a {kind} has no LSTM")
    if CLASS_ACTION_TYPES.get(kind, spec.action.action_type) != spec.action.action_type:
        raise PolicyFormatError(
            f"a {kind} acts in {CLASS_ACTION_TYPES[kind]} actions, action.action_type is {spec.action.action_type!r}"
        )


def _check_net_arch(kind: str, net_arch: Any) -> None:
    """``net_arch`` of the form ``kind`` builds: a list for the DQN classes, ``pi``/``vf`` or ``pi`` and ``qf``."""
    if not isinstance(net_arch, SplitArch):
        return
    allowed = {
        "ActorCriticPolicy": {"pi", "vf"},
        "RecurrentActorCriticPolicy": {"pi", "vf"},
        "SACPolicy": {"pi", "qf"},
        "CrossQPolicy": {"pi", "qf"},
    }
    given = {k for k in ("pi", "vf", "qf") if getattr(net_arch, k) is not UNSET}
    keys = allowed.get(kind)
    both = kind in ("SACPolicy", "CrossQPolicy")
    if keys is None or not given or not given <= keys or (both and given != keys):
        form = "a list of layer sizes" + (
            "" if keys is None else f" or {{{', '.join(repr(k) for k in sorted(keys))}: [...]}}"
        )
        shown = msgspec.to_builtins(net_arch)
        raise PolicyFormatError(f"architecture.policy_kwargs.net_arch of a {kind} must be {form}, got {shown!r}")
