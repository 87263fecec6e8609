"""The deterministic action of an exported SB3 policy, computed in numpy from its weights.

Each supported policy class (:data:`electroloc_gym.policy.format.POLICY_CLASSES`) is the same
arithmetic as SB3's ``policy.predict(obs, deterministic=True)``, read off the ``state_dict`` names:

* ``ActorCriticPolicy`` (PPO, A2C): ``mlp_extractor.policy_net`` → ``action_net``; a Box action is the
  Gaussian mean clipped to the bounds, a Discrete one the arg-max of the logits.
* ``RecurrentActorCriticPolicy`` (RecurrentPPO): the actor LSTM (``lstm_actor``, torch's gate order
  i, f, g, o; the state is zeroed where an episode starts) before the same head.
* ``SACPolicy``: ``actor.latent_pi`` → ``actor.mu`` → tanh, rescaled to the Box.
* ``CrossQPolicy`` (sb3-contrib): the same, its ``latent_pi`` with a Batch Renorm layer before each linear layer
  and after the last hidden one, applied as in evaluation mode (the running statistics:
  ``scale · (x − ra_mean) / sqrt(ra_var + eps) + bias``, ``eps`` = ``batch_norm_eps``).
* ``DQNPolicy``: arg-max of ``q_net.q_net``; ``QRDQNPolicy``: arg-max of the quantile mean.

Written by hand (no torch, no SB3) so that the benchmark runs a shipped policy with the core
dependencies only, and a decision costs tens of microseconds instead of torch's ~0.3 ms per call.
Computed in float64. Stochastic actions need the SB3 policy itself (:mod:`electroloc_gym.policy.load`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.policy.format import PolicyFormatError

__all__ = ["Actor", "build_actor"]

#: A float64 array (the numpy forward pass computes in float64).
_F64 = NDArray[np.float64]

_ACT: dict[str, Callable[[_F64], _F64]] = {
    "tanh": np.tanh,
    "relu": lambda h: np.maximum(h, 0.0),
    "elu": lambda h: np.where(h > 0, h, np.expm1(np.minimum(h, 0.0))),
    "leaky_relu": lambda h: np.where(h > 0, h, 0.01 * h),
    "silu": lambda h: h / (1.0 + np.exp(-h)),
}

#: The policy classes whose SB3 default activation is tanh (the others': ReLU).
_TANH_DEFAULT = ("ActorCriticPolicy", "RecurrentActorCriticPolicy")


def _sigmoid(x: _F64) -> _F64:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


class _Mlp:
    """The modules ``prefix.<i>`` in index order: each an ``nn.Linear`` and the activation (not after the last one
    with ``last_linear``), or, in CrossQ's ``latent_pi``, a Batch Renorm layer in evaluation mode (it has
    ``ra_mean``) of epsilon ``eps``.
    """

    def __init__(
        self, w: Mapping[str, NDArray[Any]], prefix: str, act: str, last_linear: bool, eps: float = 0.0
    ) -> None:
        pat = re.compile(re.escape(prefix) + r"\.(\d+)\.(weight|ra_mean)$")
        self.act, self.last_linear = _ACT[act], last_linear
        self.steps: list[tuple[bool, _F64, _F64]] = []
        for i, kind in sorted((int(m.group(1)), m.group(2)) for k in w if (m := pat.match(k))):
            p = f"{prefix}.{i}"
            if kind == "weight":
                self.steps.append((True, w[f"{p}.weight"].astype(np.float64).T, w[f"{p}.bias"].astype(np.float64)))
            else:  # (x − mean) / sqrt(var + eps) · scale + bias  ==  x · a + b
                inv = 1.0 / np.sqrt(w[f"{p}.ra_var"].astype(np.float64) + eps)
                a = w[f"{p}.scale"].astype(np.float64) * inv
                self.steps.append((False, a, w[f"{p}.bias"].astype(np.float64) - w[f"{p}.ra_mean"] * a))

    def __call__(self, x: _F64) -> _F64:
        for j, (linear, a, b) in enumerate(self.steps):
            if not linear:
                x = x * a + b
            elif self.last_linear and j == len(self.steps) - 1:
                x = x @ a + b
            else:
                x = self.act(x @ a + b)
        return x


def _linear(w: Mapping[str, NDArray[Any]], name: str) -> Callable[[_F64], _F64]:
    wt, b = w[f"{name}.weight"].astype(np.float64).T, w[f"{name}.bias"].astype(np.float64)
    return lambda x: x @ wt + b


class Actor:
    """Deterministic actions of one exported policy: ``actor(x, state, episode_start) → (action, state)``.

    ``x`` is the network input (n, d) (normalised, stacked); ``state`` the recurrent (h, c) pair of
    arrays (n_layers, n, hidden) or None.
    """

    def __init__(self, meta: Mapping[str, Any], w: Mapping[str, NDArray[Any]]) -> None:
        from electroloc_gym.policy.format import space_from_json

        arch = meta["architecture"]
        self.kind = arch["policy_class"]
        act = arch["policy_kwargs"].get("activation_fn") or ("tanh" if self.kind in _TANH_DEFAULT else "relu")
        if act not in _ACT:
            raise PolicyFormatError(f"activation {act!r} has no numpy forward pass; supported: {sorted(_ACT)}")
        space = space_from_json(meta["action"]["space"])
        self.low = getattr(space, "low", None)
        self.high = getattr(space, "high", None)
        self.n_actions = getattr(space, "n", None)
        self.recurrent = self.kind == "RecurrentActorCriticPolicy"
        try:
            if self.kind in ("ActorCriticPolicy", "RecurrentActorCriticPolicy"):
                body, head = _Mlp(w, "mlp_extractor.policy_net", act, False), _linear(w, "action_net")
                self._net = lambda x: head(body(x))
            elif self.kind in ("SACPolicy", "CrossQPolicy"):  # CrossQ's eps: its Batch Renorm layers'
                eps = float(arch["policy_kwargs"].get("batch_norm_eps", 0.001))
                body, head = _Mlp(w, "actor.latent_pi", act, False, eps), _linear(w, "actor.mu")
                self._net = lambda x: np.tanh(head(body(x)))
            elif self.kind == "DQNPolicy":
                self._net = _Mlp(w, "q_net.q_net", act, True)
            else:  # QRDQNPolicy: (n, n_quantiles · n_actions) viewed as (n, n_quantiles, n_actions)
                q = _Mlp(w, "quantile_net.quantile_net", act, True)
                n_actions = self.n_actions
                if n_actions is None:
                    raise PolicyFormatError(f"a {self.kind} needs a Discrete action space, got {space}")
                self._net = lambda x: q(x).reshape(x.shape[0], -1, n_actions).mean(axis=1)
            if self.recurrent:
                rec = arch["recurrent"]
                self.n_layers, self.hidden = int(rec["n_lstm_layers"]), int(rec["lstm_hidden_size"])
                self._lstm = [
                    (
                        w[f"lstm_actor.weight_ih_l{k}"].astype(np.float64).T,
                        w[f"lstm_actor.weight_hh_l{k}"].astype(np.float64).T,
                        (w[f"lstm_actor.bias_ih_l{k}"] + w[f"lstm_actor.bias_hh_l{k}"]).astype(np.float64),
                    )
                    for k in range(self.n_layers)
                ]
        except (KeyError, TypeError) as exc:
            raise PolicyFormatError(f"the weights do not fit a {self.kind}: missing {exc}") from exc

    def initial_state(self, n: int) -> tuple[_F64, _F64]:
        z = np.zeros((self.n_layers, n, self.hidden))
        return z, z.copy()

    def __call__(
        self, x: NDArray[Any], state: Any = None, episode_start: NDArray[Any] | None = None
    ) -> tuple[NDArray[Any], Any]:
        h = np.asarray(x, dtype=np.float64)
        if self.recurrent:
            hs, cs = self.initial_state(h.shape[0]) if state is None else (np.array(state[0]), np.array(state[1]))
            if episode_start is not None:
                keep = 1.0 - np.asarray(episode_start, dtype=np.float64).reshape(1, -1, 1)
                hs, cs = hs * keep, cs * keep
            for k, (wi, wh, b) in enumerate(self._lstm):
                g = h @ wi + hs[k] @ wh + b
                i, f, gg, o = np.split(g, 4, axis=1)
                cs[k] = _sigmoid(f) * cs[k] + _sigmoid(i) * np.tanh(gg)
                hs[k] = _sigmoid(o) * np.tanh(cs[k])
                h = hs[k]
            state = (hs, cs)
        out = self._net(h)
        if self.n_actions is not None:
            return np.argmax(out, axis=-1), state
        low, high = self.low, self.high
        if low is None or high is None:
            raise PolicyFormatError(f"a {self.kind} with continuous actions needs a Box action space")
        if self.kind in ("SACPolicy", "CrossQPolicy"):  # SB3 unscale_action of the tanh-squashed mean
            return (low + 0.5 * (out + 1.0) * (high - low)).astype(np.float32), state
        return np.clip(out, low, high).astype(np.float32), state


def build_actor(meta: Mapping[str, Any], weights: Mapping[str, NDArray[Any]]) -> Actor:
    """The numpy :class:`Actor` of a validated ``policy.json`` and its tensors."""
    return Actor(meta, weights)
