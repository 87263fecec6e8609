"""The tensors each policy architecture holds: their names and shapes, and the check of a file's tensors.

A policy file's tensors must be exactly those the declared architecture builds (:func:`expected_tensors`), of
those shapes, as many as ``weights.tensors`` says, and floating-point (CrossQ's ``….steps`` counters: integers).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from electroloc_gym.policy.errors import PolicyFormatError

__all__ = ["ALGOS", "WEIGHTS_FILE", "check_tensors", "expected_tensors", "integer_tensor"]

WEIGHTS_FILE = "policy.safetensors"

#: ``algo`` → (the policy class its files hold, which tensors they hold: ``"policy"`` the class's whole
#: ``state_dict`` — what an export of an SB3 / sb3-contrib model or an RLlib PPO writes — or ``"actor"`` the
#: deterministic actor's alone: the offline trainers' files, which have no stochastic actions).
ALGOS: dict[str, tuple[str, str]] = {
    "ppo": ("ActorCriticPolicy", "policy"),
    "a2c": ("ActorCriticPolicy", "policy"),
    "trpo": ("ActorCriticPolicy", "policy"),
    "recurrentppo": ("RecurrentActorCriticPolicy", "policy"),
    "sac": ("SACPolicy", "policy"),
    "dqn": ("DQNPolicy", "policy"),
    "qrdqn": ("QRDQNPolicy", "policy"),
    "crossq": ("CrossQPolicy", "policy"),
    "bc": ("SACPolicy", "actor"),
    "td3_bc": ("SACPolicy", "actor"),
}


def _linear(name: str, n_in: int, n_out: int) -> dict[str, tuple[int, ...]]:
    return {f"{name}.weight": (n_out, n_in), f"{name}.bias": (n_out,)}


def _lstm(name: str, n_in: int, hidden: int, layers: int) -> dict[str, tuple[int, ...]]:
    shapes: dict[str, tuple[int, ...]] = {}
    for k in range(layers):
        shapes.update(
            {
                f"{name}.weight_ih_l{k}": (4 * hidden, n_in if k == 0 else hidden),
                f"{name}.weight_hh_l{k}": (4 * hidden, hidden),
                f"{name}.bias_ih_l{k}": (4 * hidden,),
                f"{name}.bias_hh_l{k}": (4 * hidden,),
            }
        )
    return shapes


#: The tensors of one Batch Renorm layer (sb3-contrib's ``BatchRenorm1d``, CrossQ): four of ``n`` features, and
#: ``steps``, the layer's update counter (a 0-d int64 tensor; the one integer tensor the format holds).
_RENORM = ("scale", "bias", "ra_mean", "ra_var")


def _renorm(name: str, n: int) -> dict[str, tuple[int, ...]]:
    return {**{f"{name}.{k}": (n,) for k in _RENORM}, f"{name}.steps": ()}


def _mlp(
    prefix: str, n_in: int, layers: list[int], n_out: int | None = None, renorm: bool = False
) -> tuple[dict[str, tuple[int, ...]], int]:
    """SB3's MLP ``prefix`` (``create_mlp``): per layer an ``nn.Linear`` and an activation (indices 0, 2, …), then
    one ``nn.Linear`` to ``n_out`` if given. Returns the shapes and the last width.

    ``renorm``: sb3-contrib's CrossQ MLP, a Batch Renorm layer before each ``nn.Linear``, and without ``n_out`` one
    after the last hidden layer (the actor's ``latent_pi``).
    """
    shapes: dict[str, tuple[int, ...]] = {}
    width, i = n_in, 0
    for size in layers if n_out is None else [*layers, n_out]:
        if renorm:
            shapes.update(_renorm(f"{prefix}.{i}", width))
            i += 1
        shapes.update(_linear(f"{prefix}.{i}", width, size))
        width, i = size, i + 2
    if renorm and n_out is None and layers:
        shapes.update(_renorm(f"{prefix}.{i}", width))
    return shapes, width


def integer_tensor(meta: Mapping[str, Any], name: str) -> bool:
    """Whether tensor ``name`` of a file is an integer one: a CrossQ Batch Renorm layer's ``steps`` counter."""
    return meta["architecture"]["policy_class"] == "CrossQPolicy" and name.endswith(".steps")


def _arch_parts(net_arch: Any, critic: str) -> tuple[list[int], list[int]]:
    """(actor layers, critic layers) of a ``net_arch``: one list for both, or ``{"pi": [...], critic: [...]}``."""
    if isinstance(net_arch, dict):
        return list(net_arch.get("pi", [])), list(net_arch.get(critic, []))
    return list(net_arch), list(net_arch)


def expected_tensors(meta: Mapping[str, Any]) -> dict[str, tuple[int, ...]]:
    """The tensor names and shapes the architecture of a validated ``policy.json`` builds.

    SB3's / sb3-contrib's ``state_dict`` of the policy class with its ``net_arch``, LSTM and activation, the
    observation size (``observation.shape``) and the action space (a Box's size, a Discrete's n); for an
    ``"actor"`` algo (:data:`ALGOS`) the deterministic actor's tensors alone (``actor.latent_pi``, ``actor.mu``).
    The flat features extractor has no tensors.
    """
    arch = meta["architecture"]
    kind, pk = arch["policy_class"], arch["policy_kwargs"]
    n_obs = int(np.prod(meta["observation"]["shape"]))
    space = meta["action"]["space"]
    n_act = int(space["n"]) if space["type"] == "Discrete" else int(np.prod(space["shape"]))
    out: dict[str, tuple[int, ...]] = {}
    if kind in ("ActorCriticPolicy", "RecurrentActorCriticPolicy"):
        pi, vf = _arch_parts(pk["net_arch"], "vf")
        features = n_obs
        if kind == "RecurrentActorCriticPolicy":
            rec = arch["recurrent"]
            hidden, layers = int(rec["lstm_hidden_size"]), int(rec["n_lstm_layers"])
            out.update(_lstm("lstm_actor", n_obs, hidden, layers))
            if rec["enable_critic_lstm"]:
                out.update(_lstm("lstm_critic", n_obs, hidden, layers))
            elif not rec["shared_lstm"]:
                out.update(_linear("critic", n_obs, hidden))
            features = hidden
        shapes, latent_pi = _mlp("mlp_extractor.policy_net", features, pi)
        out.update(shapes)
        shapes, latent_vf = _mlp("mlp_extractor.value_net", features, vf)
        out.update(shapes)
        out.update(_linear("action_net", latent_pi, n_act))
        if space["type"] == "Box":
            out["log_std"] = (n_act,)
        out.update(_linear("value_net", latent_vf, 1))
    elif kind in ("SACPolicy", "CrossQPolicy"):  # CrossQ: Batch Renorm layers in actor and critics, no target
        pi, qf = _arch_parts(pk["net_arch"], "qf")
        crossq = kind == "CrossQPolicy"
        renorm = crossq and bool(pk.get("batch_norm", True))
        shapes, latent = _mlp("actor.latent_pi", n_obs, pi, None, renorm)
        out.update(shapes)
        out.update(_linear("actor.mu", latent, n_act))
        if ALGOS[meta["algo"]][1] == "policy":
            out.update(_linear("actor.log_std", latent, n_act))
            for net in ("critic",) if crossq else ("critic", "critic_target"):
                for i in range(int(pk.get("n_critics", 2))):
                    out.update(_mlp(f"{net}.qf{i}", n_obs + n_act, qf, 1, renorm)[0])
    else:  # DQNPolicy; QRDQNPolicy: n_quantiles outputs per action
        net = "quantile_net" if kind == "QRDQNPolicy" else "q_net"
        n_out = n_act * int(pk["n_quantiles"]) if kind == "QRDQNPolicy" else n_act
        for prefix in (net, f"{net}_target"):
            out.update(_mlp(f"{prefix}.{net}", n_obs, list(pk["net_arch"]), n_out)[0])
    return out


def check_tensors(meta: Mapping[str, Any], tensors: Mapping[str, np.ndarray], where: str) -> None:
    """Refuse ``tensors`` unless they are exactly those :func:`expected_tensors` names, of those shapes,
    floating-point (:func:`integer_tensor`: integers), and as many as ``weights.tensors`` says.

    Raises:
        PolicyFormatError: one line starting with ``where``, naming the fields the tensors contradict.
    """
    declared = meta["weights"]["tensors"]
    if declared != len(tensors):
        raise PolicyFormatError(
            f"{where}: weights.tensors is {declared}, but {WEIGHTS_FILE} holds {len(tensors)} tensors"
        )
    want = expected_tensors(meta)
    problems = []
    for label, names in (("missing", set(want) - set(tensors)), ("not of this architecture", set(tensors) - set(want))):
        if names:
            problems.append(f"{label} {sorted(names)[:6]}{' …' if len(names) > 6 else ''}")
    for name in sorted(set(want) & set(tensors)):
        a = tensors[name]
        if tuple(a.shape) != want[name]:
            problems.append(f"{name!r} has shape {tuple(a.shape)}, the architecture's is {want[name]}")
        elif integer_tensor(meta, name) and a.dtype.kind not in "iu":
            problems.append(f"{name!r} is {a.dtype}, not an integer counter")
        elif not integer_tensor(meta, name) and a.dtype.kind != "f":
            problems.append(f"{name!r} is {a.dtype}, not floating-point")
    if problems:
        arch, obs, act = meta["architecture"], meta["observation"], meta["action"]["space"]
        declared_as = (
            f"algo {meta['algo']!r}, architecture.policy_class {arch['policy_class']!r}, "
            f"architecture.policy_kwargs.net_arch {arch['policy_kwargs']['net_arch']}"
            + (f", architecture.recurrent {arch['recurrent']}" if arch.get("recurrent") else "")
            + f", observation.shape {obs['shape']}, action.space "
            + (f"Discrete({act['n']})" if act["type"] == "Discrete" else f"Box{tuple(act['shape'])}")
        )
        shown = "; ".join(problems[:4]) + (f"; … ({len(problems) - 4} more)" if len(problems) > 4 else "")
        raise PolicyFormatError(f"{where}: the tensors of {WEIGHTS_FILE} do not fit {declared_as}: {shown}")
