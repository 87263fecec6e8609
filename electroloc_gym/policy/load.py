"""A trained policy as an agent the benchmark runs beside the paper's controllers.

:class:`LearnedAgent` implements the agent protocol (:class:`electroloc_gym.baselines.base.Agent`) on raw env
observations: it applies what training put between the env and the network, the frozen normalisation statistics
and the frame stack (in the order the statistics say, :mod:`electroloc_gym.policy.format`). A recurrent policy
keeps its LSTM state across ``predict`` calls; ``reset(env)`` clears it.

:func:`load_policy` reads the pickle-free format only, every field and tensor checked when the folder is read,
so a damaged folder is one ``PolicyFormatError`` at load, never a policy that acts otherwise. Deterministic
actions need numpy alone (:mod:`electroloc_gym.policy.networks`); stochastic ones rebuild the SB3 policy (the
``train`` extra). SB3's own zip and ``vecnormalize.pkl`` contain pickles, which run code when loaded: they are
read only with ``trust_pickle=True``, with a logged warning.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.models import shipped_models
from electroloc_gym.policy.format import (
    POLICY_JSON,
    ObsNormalization,
    PolicyExport,
    PolicyFormatError,
    normalization_from_json,
    one_line,
    policy_folder,
    read_export,
    read_weights,
)
from electroloc_gym.policy.networks import build_actor
from electroloc_gym.policy.tensors import ALGOS
from electroloc_gym.utils.agentspec import path_agent_name

__all__ = ["LearnedAgent", "load_policy", "ShippedPolicy", "shipped_policies"]

logger = logging.getLogger(__name__)

TRAIN_EXTRA = "pip install 'electroloc-gym[train]'"


def _agent_own(env_id: Any, env_kwargs: Mapping[str, Any] | None) -> dict[str, Any]:
    """The training env kwargs that are the agent's own on ``env_id`` (options its task declares so, e.g. the
    moving target's ``motion_model``: the policy keeps the belief it was trained with); none for an env that is
    not registered here.
    """
    from electroloc_gym.registry import ENV_IDS, env_entry

    if env_id not in ENV_IDS or env_kwargs is None:
        return {}
    own = env_entry(env_id).agent_arguments
    return {k: v for k, v in env_kwargs.items() if k in own}


class LearnedAgent:
    """An exported policy + its frozen observation pre-processing, behind the benchmark's agent protocol.

    ``meta`` is a validated ``policy.json``'s content, ``weights`` its tensors by ``state_dict`` name; ``name``
    labels tables.
    """

    def __init__(
        self,
        meta: Mapping[str, Any],
        weights: Mapping[str, NDArray[Any]],
        normalization: ObsNormalization | None,
        name: str = "learned",
    ) -> None:
        self.meta = dict(meta)
        self.weights = dict(weights)
        self.name = name
        obs = meta["observation"]
        self.frame_stack, self.obs_dim = int(obs["frame_stack"]), int(obs["frame_dim"])
        self.env_kwargs: dict[str, Any] = {
            "observation": obs["mode"],
            "action_type": meta["action"]["action_type"],
            **_agent_own(obs.get("env_id"), meta.get("env_kwargs")),
        }
        self.normalization = normalization
        self.normalize_frames = (
            normalization is not None and normalization.mean.shape[0] == self.obs_dim and self.frame_stack > 1
        )
        self.actor = build_actor(meta, weights)
        self.recurrent = self.actor.recurrent
        self._stack: NDArray[np.float32] | None = None
        self._state: Any = None
        self._fresh = True
        self._sb3_policy: Any = None

    def __repr__(self) -> str:
        return (
            f"LearnedAgent({self.meta['architecture']['policy_class']}, name={self.name!r}, "
            f"frame_stack={self.frame_stack}, normalised={self.normalization is not None}, "
            f"env_kwargs={self.env_kwargs})"
        )

    def reset(self, env: Any = None) -> None:
        """Start of a trial: clear the frame stack and the recurrent state (``env`` is not used)."""
        self._stack, self._state, self._fresh = None, None, True

    def preprocess(
        self, observation: NDArray[np.floating[Any]], episode_start: NDArray[Any] | None = None
    ) -> NDArray[np.float32]:
        """Raw env observation(s) (d,) or (n, d) → the network's input (n, k·d), updating the frame stack.

        ``episode_start`` (n,) of any dtype is read as bool: the envs whose frame stack restarts.
        """
        obs = np.asarray(observation, dtype=np.float32)
        obs = obs[None] if obs.ndim == 1 else obs
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"observation must have shape ({self.obs_dim},) or (n, {self.obs_dim}), got {obs.shape}")
        norm = self.normalization
        if self.normalize_frames and norm is not None:  # normalize_frames implies statistics
            obs = norm.apply(obs).astype(np.float32)
        n: int = obs.shape[0]
        stack = self._stack  # zeros at a trial start or a new batch size
        if stack is None or stack.shape[0] != n:
            stack = np.zeros((n, self.frame_stack, self.obs_dim), dtype=np.float32)
        if episode_start is not None:
            stack[np.reshape(np.asarray(episode_start, dtype=bool), n)] = 0.0
        stack = np.roll(stack, -1, axis=1)
        stack[:, -1] = obs
        self._stack = stack
        x = np.reshape(stack, (n, -1))  # a view of the stack: both returns below are new arrays
        if norm is not None and not self.normalize_frames:
            return norm.apply(x).astype(np.float32)
        return x.astype(np.float32)

    def predict(
        self,
        observation: NDArray[np.floating[Any]],
        state: Any = None,
        episode_start: NDArray[Any] | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[Any], Any]:
        """SB3-style decision for one observation (d,) or a batch (n, d).

        Returns:
            (action, state): the action (batch dim removed for one observation) and the recurrent state.
        """
        single = np.ndim(observation) == 1
        x = self.preprocess(observation, episode_start)
        if self.recurrent and episode_start is None:
            n: int = x.shape[0]
            episode_start = np.full(n, self._fresh, dtype=bool)
        st = self._state if state is None else state
        if deterministic:
            action, st = self.actor(x, st, episode_start)
        else:
            action, st = self._stochastic(x, st, episode_start)
        self._state = st if self.recurrent else None
        self._fresh = False
        return (action[0] if single else action), st

    def _stochastic(
        self, x: NDArray[np.float32], state: Any, episode_start: NDArray[Any] | None
    ) -> tuple[NDArray[Any], Any]:
        algo = str(self.meta.get("algo"))
        if ALGOS.get(algo, ("", "policy"))[1] == "actor":
            raise ValueError(
                f"a {algo} policy file holds the deterministic actor alone: it has no stochastic actions "
                f"(use deterministic=True)"
            )
        if self._sb3_policy is None:
            try:
                from electroloc_gym.policy.sb3 import sb3_policy

                self._sb3_policy = sb3_policy(self.meta, self.weights)
            except ImportError as exc:
                raise ValueError(
                    f"stochastic actions of a learned policy need torch and SB3 ({TRAIN_EXTRA}): {exc}"
                ) from exc
        if self.recurrent:
            start = np.zeros(x.shape[0], dtype=bool) if episode_start is None else np.asarray(episode_start, bool)
            return self._sb3_policy.predict(x, state=state, episode_start=start, deterministic=False)
        return self._sb3_policy.predict(x, deterministic=False)[0], None


def agent_from_export(export: PolicyExport, name: str | None = None) -> LearnedAgent:
    """The :class:`LearnedAgent` of a validated export (its weights checked against the SHA-256).

    Raises:
        PolicyFormatError: the weights or the architecture do not make a network (one error naming the
            folder, whatever the damage).
    """
    weights = read_weights(export)
    try:
        return LearnedAgent(export.meta, weights, export.normalization, name or export.folder.name)
    except PolicyFormatError:
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, RecursionError) as exc:
        raise PolicyFormatError(
            f"{export.folder / POLICY_JSON}: its architecture and weights do not make a network: {one_line(exc)}"
        ) from exc


@dataclass(frozen=True)
class ShippedPolicy:
    """One shipped learned policy and the env it was trained for.

    Attributes:
        name: its name (``load_policy(name)``, ``make_agent(name)``, ``electroloc bench --agents NAME``).
        folder: its folder in the installed package.
        env_id: the env id it was trained on.
        env_kwargs: the training env's keyword arguments (the benchmark runs it where they hold).
        algo: the training algorithm (``"ppo"``, ...).
    """

    name: str
    folder: Path
    env_id: str
    env_kwargs: Mapping[str, Any]
    algo: str


def shipped_policies() -> dict[str, ShippedPolicy]:
    """Every shipped policy by name, with the env it was trained for (read from its checked ``policy.json``)."""
    out: dict[str, ShippedPolicy] = {}
    for name, folder in shipped_models().items():
        meta = read_export(folder).meta
        out[name] = ShippedPolicy(
            name=name,
            folder=folder,
            env_id=str(meta["observation"]["env_id"]),
            env_kwargs=dict(meta.get("env_kwargs") or {}),
            algo=str(meta["algo"]),
        )
    return out


def load_policy(path: str | Path, trust_pickle: bool = False) -> LearnedAgent:
    """Load a trained policy as a :class:`LearnedAgent`: a shipped policy by name, or a file or folder.

    By default only the pickle-free format is read: a folder holding ``policy.json`` and
    ``policy.safetensors`` (or the ``policy.json`` file). Nothing is unpickled. An SB3 ``.zip`` (e.g.
    an rl-zoo3 run's ``best_model.zip``) needs ``trust_pickle=True`` and SB3; it is then converted in
    memory (:func:`electroloc_gym.policy.sb3.model_from_sb3_zip`) and a warning is logged.

    Args:
        path: the name of a shipped policy (:func:`shipped_policies`, e.g. ``"ppo-belief"``: always the shipped
            one, as ``electroloc bench --agents`` and ``make_agent`` read it; a folder of that name in the working
            directory is ``"./ppo-belief"``), a policy folder, its ``policy.json``, an rl-zoo3 run folder of this
            path (its ``best/``), or (with ``trust_pickle``) an SB3 ``.zip``.
        trust_pickle: allow SB3's pickle-based files (only for files you trust: loading runs their code).

    Raises:
        ValueError: a missing path, a pickle-based model without ``trust_pickle``, or a malformed
            ``policy.json`` or weights file (the message names the file).
    """
    shipped = shipped_models()
    p = shipped[path.strip()] if isinstance(path, str) and path.strip() in shipped else Path(path)
    folder = policy_folder(p)
    if folder.is_dir() and (folder / POLICY_JSON).is_file():  # an rl-zoo3 run folder's best/: named by its run
        return agent_from_export(read_export(folder), p.name if folder == p / "best" else None)
    if not p.exists():
        raise ValueError(
            f"policy path {str(path)!r} does not exist (expected a folder with {POLICY_JSON}, or the name of a "
            f"shipped policy: {sorted(shipped)})"
        )
    if not trust_pickle:
        raise ValueError(
            f"refusing to load {str(path)!r}: it has no {POLICY_JSON} (the pickle-free policy format). "
            f"SB3's .zip and vecnormalize.pkl contain pickles, which run code when loaded; read them "
            f"only with trust_pickle=True (--trust-pickle) for files you trust, or export a run you "
            f"trust with `python -m electroloc_gym.train.export`"
        )
    try:
        from electroloc_gym.policy.sb3 import model_from_sb3_zip
    except ImportError as exc:
        raise ValueError(f"loading an SB3 zip needs SB3 ({TRAIN_EXTRA}): {exc}") from exc
    logger.warning(
        "loading %s with pickle (trust_pickle=True): a pickle-based model runs code from the file; "
        "load only files you trust",
        p,
    )
    model, meta = model_from_sb3_zip(p)
    return agent_from_model(model, meta, path_agent_name(p))


def agent_from_model(model: Any, meta: Mapping[str, Any], name: str = "learned") -> LearnedAgent:
    """The benchmark's agent for a live SB3 model (what its export would load), from
    :func:`electroloc_gym.policy.sb3.export_meta`'s dict (needs torch and SB3).
    """
    from electroloc_gym.policy.sb3 import model_weights

    norm = normalization_from_json(meta["normalization"], meta["observation"], "model")
    return LearnedAgent(meta, model_weights(model), norm, name)
