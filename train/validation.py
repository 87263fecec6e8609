"""Checks of hyper-parameter values, policy keywords and the env, run before any training starts.

Every value is checked against its documented range (``gamma`` in [0, 1], ``batch_size`` ≥ 1 …) and
otherwise against the type annotation of the algorithm's constructor; ``policy_kwargs`` keys against
the policy class's constructor; env kwargs against the env's constructor, then by building one env.
Each problem is one :class:`~electroloc_gym.train.config.ConfigError` naming the key, the place and
the allowed values — the run never starts and then fails inside SB3 or torch.
"""

from __future__ import annotations

import inspect
import math
import types
import typing
from collections.abc import Mapping
from typing import Any

from electroloc_gym.train.config import ConfigError, algo_class

__all__ = ["check_algo_values", "check_policy_kwargs", "check_env"]

# key → (kind, low, high): kind "int" (integers), "float" (numbers), "rate" (number or 'lin_x' schedule).
# low/high are inclusive bounds; None = unbounded. "prob" = a number in [0, 1].
_RANGES: dict[str, tuple[str, float | None, float | None]] = {
    "n_steps": ("int", 1, None), "batch_size": ("int", 1, None), "n_epochs": ("int", 1, None),
    "buffer_size": ("int", 1, None), "learning_starts": ("int", 0, None), "target_update_interval": ("int", 1, None),
    "stats_window_size": ("int", 1, None), "policy_delay": ("int", 1, None), "sde_sample_freq": ("int", -1, None),
    "gamma": ("float", 0.0, 1.0), "gae_lambda": ("float", 0.0, 1.0), "tau": ("float", 0.0, 1.0),
    "exploration_fraction": ("float", 0.0, 1.0), "exploration_initial_eps": ("float", 0.0, 1.0),
    "exploration_final_eps": ("float", 0.0, 1.0), "vf_coef": ("float", 0.0, None),
    "target_policy_noise": ("float", 0.0, None), "target_noise_clip": ("float", 0.0, None),
    "max_grad_norm": ("float", 0.0, None), "rms_prop_eps": ("float", 0.0, None),
    "learning_rate": ("rate", 0.0, None), "clip_range": ("rate", 0.0, None),
}
_POSITIVE = {"max_grad_norm", "rms_prop_eps", "learning_rate", "clip_range"}  # strictly > low
_OPTIONAL_POSITIVE = ("target_kl", "clip_range_vf")  # None or > 0
_POLICY_RESERVED = {"self", "observation_space", "action_space", "lr_schedule", "use_sde"}
_POLICY_UNSUPPORTED = ("features_extractor_class", "features_extractor_kwargs", "optimizer_class")


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _as_number(v: Any) -> Any:
    """YAML 1.1 reads ``3e-4`` (no dot) as a string; accept such a numeric string as the float it spells."""
    if isinstance(v, str) and not v.startswith("lin_"):
        try:
            f = float(v)
        except ValueError:
            return v
        return f if math.isfinite(f) else v
    return v


def _range_text(kind: str, low: float | None, high: float | None, strict_low: bool) -> str:
    noun = "an integer" if kind == "int" else "a number"
    if low is not None and high is not None:
        return f"{noun} in [{low:g}, {high:g}]"
    if low is not None:
        return f"{noun} {'>' if strict_low else '≥'} {low:g}"
    return noun


def _check_range(key: str, value: Any, where: str) -> Any:
    kind, low, high = _RANGES[key]
    strict = key in _POSITIVE
    if kind == "rate" and isinstance(value, str) and value.startswith("lin_"):
        return value  # schedules are parsed (and checked) by config._parse_schedule
    value = _as_number(value) if kind != "int" else value
    ok = _is_int(value) if kind == "int" else _is_number(value)
    if ok and low is not None:
        ok = value > low if strict else value >= low
    if ok and high is not None:
        ok = value <= high
    if not ok:
        extra = " or a schedule 'lin_<initial>'" if kind == "rate" else ""
        raise ConfigError(f"{where}: {key} must be {_range_text(kind, low, high, strict)}{extra}, got {value!r}")
    return value


def _matches(value: Any, ann: Any) -> bool | None:
    """Whether ``value`` fits the annotation ``ann`` (None when the annotation cannot be checked)."""
    if ann is inspect.Parameter.empty or ann is Any:
        return None
    if ann is bool:
        return isinstance(value, bool)
    if ann is int:
        return _is_int(value)
    if ann is float:
        return _is_number(value)
    if ann is str:
        return isinstance(value, str)
    if ann is type(None):
        return value is None
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        results = [_matches(value, a) for a in typing.get_args(ann)]
        return True if any(r is True for r in results) else (None if None in results else False)
    if origin in (dict, Mapping):
        return isinstance(value, dict)
    if origin is list:
        return isinstance(value, list)
    if origin is tuple:
        return isinstance(value, (list, tuple))
    return None


def _annotation_text(ann: Any) -> str:
    return getattr(ann, "__name__", None) or str(ann).replace("typing.", "")


def check_algo_values(hp: Mapping[str, Any], algo: str, where: str) -> dict[str, Any]:
    """Check every constructor keyword in ``hp`` for ``algo``; returns ``hp`` with numeric strings as floats.

    Raises:
        ConfigError: a value outside its documented range, of the wrong type, or an unknown policy name.
    """
    cls = algo_class(algo)
    params = inspect.signature(cls.__init__).parameters
    out = dict(hp)
    for key, value in hp.items():
        if key == "policy":
            if value not in cls.policy_aliases:
                raise ConfigError(f"{where}: policy must be one of {sorted(cls.policy_aliases)} for --algo {algo}, "
                                  f"got {value!r}")
        elif key in _RANGES:
            out[key] = _check_range(key, value, where)
        elif key in _OPTIONAL_POSITIVE:
            if value is not None and not (isinstance(value, str) and value.startswith("lin_")):
                v = _as_number(value)
                if not (_is_number(v) and v > 0):
                    raise ConfigError(f"{where}: {key} must be null or a number > 0, got {value!r}")
                out[key] = v
        elif key == "gradient_steps":
            if not (_is_int(value) and (value >= 1 or value == -1)):
                raise ConfigError(f"{where}: gradient_steps must be an integer ≥ 1 or -1, got {value!r}")
        elif key == "train_freq":
            ok = (_is_int(value) and value >= 1) or (
                isinstance(value, list) and len(value) == 2 and _is_int(value[0]) and value[0] >= 1
                and value[1] in ("step", "episode"))
            if not ok:
                raise ConfigError(f"{where}: train_freq must be an integer ≥ 1 or [n, 'step'|'episode'], got {value!r}")
        elif key in ("ent_coef", "target_entropy") and isinstance(value, str) and value.startswith("auto"):
            continue
        elif key in ("ent_coef",):
            v = _as_number(value)
            if not (_is_number(v) and v >= 0):
                auto = " or 'auto'" if algo in ("sac", "tqc") else ""
                raise ConfigError(f"{where}: ent_coef must be a number ≥ 0{auto}, got {value!r}")
            out[key] = v
        elif key in params:
            ann = params[key].annotation
            if _matches(_as_number(value), ann) is False:
                raise ConfigError(f"{where}: {key} must be {_annotation_text(ann)}, got {value!r}")
    if algo in ("ppo", "recurrentppo") and out.get("normalize_advantage", True) and "batch_size" in out \
            and out["batch_size"] < 2:
        raise ConfigError(f"{where}: batch_size must be an integer ≥ 2 for {algo} (advantages are normalised over "
                          f"a minibatch), got {out['batch_size']!r}")
    return out


def _check_net_arch(value: Any, where: str) -> None:
    def layers(v: Any) -> bool:
        return isinstance(v, list) and all(_is_int(n) and n >= 1 for n in v)

    ok = layers(value) or (isinstance(value, dict) and value and set(value) <= {"pi", "vf", "qf"}
                           and all(layers(v) for v in value.values()))
    if not ok:
        raise ConfigError(f"{where}: policy_kwargs.net_arch must be a list of layer sizes ≥ 1 (e.g. [128, 128]) or "
                          f"a mapping {{pi: [...], vf: [...]}} (qf for off-policy critics), got {value!r}")


def check_policy_kwargs(pk: Mapping[str, Any], algo: str, policy: str, where: str) -> None:
    """Check ``policy_kwargs`` keys against the policy class's constructor, and their values.

    Raises:
        ConfigError: an unknown key (e.g. ``net_arc``), an unsupported one, or a bad value.
    """
    cls = algo_class(algo)
    pol_cls = cls.policy_aliases.get(policy)
    if pol_cls is None:
        raise ConfigError(f"{where}: policy must be one of {sorted(cls.policy_aliases)}, got {policy!r}")
    params = inspect.signature(pol_cls.__init__).parameters
    allowed = set(params) - _POLICY_RESERVED - set(_POLICY_UNSUPPORTED)
    unknown = sorted(set(pk) - allowed)
    if unknown:
        raise ConfigError(f"{where}: policy_kwargs has unknown key(s) {unknown} for {policy} ({pol_cls.__name__}); "
                          f"allowed: {sorted(allowed)}")
    for key, value in pk.items():
        if key == "net_arch":
            _check_net_arch(value, where)
        elif key == "activation_fn":
            continue  # checked by config against the names it can build
        elif key in ("lstm_hidden_size", "n_lstm_layers", "n_critics", "n_quantiles"):
            if not (_is_int(value) and value >= 1):
                raise ConfigError(f"{where}: policy_kwargs.{key} must be an integer ≥ 1, got {value!r}")
        elif _matches(value, params[key].annotation) is False:
            raise ConfigError(f"{where}: policy_kwargs.{key} must be {_annotation_text(params[key].annotation)}, "
                              f"got {value!r}")


def check_env(env_id: str, env_kwargs: Mapping[str, Any], flag: str = "env_kwargs") -> None:
    """The env id is registered, every kwarg is a parameter of its constructor, and one env builds.

    Raises:
        ConfigError: unknown id, unknown kwarg (with the allowed ones), or a value the env rejects.
    """
    import gymnasium as gym
    from gymnasium.envs.registration import load_env_creator

    import electroloc_gym  # noqa: F401  (registers the ids)

    try:
        spec = gym.spec(env_id)
    except gym.error.Error as exc:
        ours = sorted(i for i in gym.registry if i.startswith("ElectroLoc"))
        raise ConfigError(f"--env {env_id!r} is not a registered Gymnasium env ({exc}); electroloc-gym "
                          f"registers {ours}") from exc
    creator = load_env_creator(spec.entry_point) if isinstance(spec.entry_point, str) else spec.entry_point
    target = creator.__init__ if inspect.isclass(creator) else creator
    params = inspect.signature(target).parameters
    if not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        allowed = set(params) - {"self"}
        unknown = sorted(set(env_kwargs) - allowed)
        if unknown:
            raise ConfigError(f"{flag}: unknown env kwarg(s) {unknown} for {env_id}; allowed: {sorted(allowed)}")
    try:
        gym.make(env_id, **dict(env_kwargs)).close()
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{flag}: {env_id} rejects these kwargs: {exc}") from exc
