"""A trained policy as an agent the benchmark can run beside the paper's controllers.

The agent protocol (shared with the baseline controllers in ``electroloc_gym.baselines.agent``)::

    agent.env_kwargs                       # kwargs the policy needs in gym.make (observation, action_type)
    agent.reset(env)                       # after env.reset(), at each trial start
    action, state = agent.predict(obs, state=None, episode_start=None, deterministic=True)

The benchmark passes raw env observations, so the agent applies what training put between the env
and the network itself: the flat frame stack and the frozen observation-normalisation statistics.
A recurrent policy keeps its LSTM state across ``predict`` calls; ``reset(env)`` clears it.

:func:`load_policy` reads the project's pickle-free format (``policy.json`` + ``policy.safetensors``,
:mod:`electroloc_gym.train.policy_format`): nothing in the model directory is unpickled or executed.
SB3's own ``model.zip`` (and ``vecnormalize.pkl``) contain pickles — loading a file made by someone
else runs their code — so they are read only with ``trust_pickle=True``, with a logged warning.
"""

from __future__ import annotations

import json
import logging
import pickle
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from electroloc_gym.train.policy_format import (
    POLICY_JSON,
    ObsNormalization,
    PolicyFormatError,
    build_policy,
    read_export,
)
from electroloc_gym.train.wrappers import FrameStacker

__all__ = ["SB3Agent", "load_policy", "resolve_model_path", "read_run_config", "AGENT_ENV_KWARGS"]

logger = logging.getLogger(__name__)

#: Env kwargs a policy depends on (the benchmark sets everything else: condition, target, seeds).
AGENT_ENV_KWARGS = ("observation", "action_type")


class SB3Agent:
    """An SB3 policy + its frozen observation pre-processing, behind the benchmark's agent protocol.

    Args:
        model: an SB3 / sb3-contrib algorithm, or its policy network (``model.policy``) alone.
        normalization: frozen observation statistics, or None (raw observations).
        obs_rms: alternatively, VecNormalize's ``RunningMeanStd`` (``mean``, ``var``) …
        clip_obs: … with VecNormalize's clip on normalised observations …
        epsilon: … and its epsilon.
        frame_stack: number of stacked observations the network expects (1 = none).
        env_kwargs: env kwargs the policy needs (observation mode, action type).
        name: a label for tables.
    """

    def __init__(
        self,
        model: Any,
        *,
        normalization: ObsNormalization | None = None,
        obs_rms: Any | None = None,
        clip_obs: float = 10.0,
        epsilon: float = 1e-8,
        frame_stack: int = 1,
        env_kwargs: Mapping[str, Any] | None = None,
        name: str = "learned",
    ) -> None:
        if isinstance(frame_stack, bool) or not isinstance(frame_stack, int) or frame_stack < 1:
            raise ValueError(f"frame_stack must be an integer ≥ 1, got {frame_stack!r}")
        if normalization is None and obs_rms is not None:
            normalization = ObsNormalization(np.asarray(obs_rms.mean), np.asarray(obs_rms.var),
                                             clip_obs=float(clip_obs), epsilon=float(epsilon))
        self.policy = getattr(model, "policy", model)
        self.name = name
        self.env_kwargs: dict[str, Any] = dict(env_kwargs or {})
        self.frame_stack = frame_stack
        self.normalization = normalization
        self.recurrent = any(c.__name__ == "RecurrentActorCriticPolicy" for c in type(self.policy).__mro__)
        shape = self.policy.observation_space.shape
        if len(shape) != 1 or shape[0] % frame_stack:
            raise ValueError(f"model observation shape {shape} does not fit frame_stack={frame_stack}")
        if normalization is not None and normalization.mean.shape != tuple(shape):
            raise ValueError(f"normalisation statistics of shape {normalization.mean.shape} do not fit the "
                             f"policy's observation shape {tuple(shape)}")
        self.obs_dim = shape[0] // frame_stack
        self._stacker: FrameStacker | None = None  # one row per observation of a batch
        self._state: Any = None
        self._fresh = True
        self._numpy_actor = None if self.recurrent else _numpy_actor(self.policy)

    @property
    def model(self) -> Any:
        """The policy network (kept under this name for code written against SB3 models)."""
        return self.policy

    def __repr__(self) -> str:
        return (f"SB3Agent({type(self.policy).__name__}, name={self.name!r}, frame_stack={self.frame_stack}, "
                f"normalised={self.normalization is not None}, env_kwargs={self.env_kwargs})")

    def reset(self, env: Any = None) -> None:
        """Start of a trial: clear the frame stack and the recurrent state (``env`` is not used)."""
        self._stacker = None
        self._state = None
        self._fresh = True

    def preprocess(self, observation: NDArray, episode_start: NDArray | None = None) -> NDArray[np.float32]:
        """Raw env observation(s) (d,) or (n, d) → the network's input (n, k·d), updating the stack."""
        obs = np.asarray(observation, dtype=np.float32)
        if obs.ndim == 1:
            obs = obs[None]
        if obs.ndim != 2 or obs.shape[1] != self.obs_dim:
            raise ValueError(f"observation must have shape ({self.obs_dim},) or (n, {self.obs_dim}), got {obs.shape}")
        n = obs.shape[0]
        if self._stacker is None or self._stacker.n_envs != n:
            self._stacker = FrameStacker(self.frame_stack, self.obs_dim, n)
        if episode_start is not None:
            self._stacker.reset(episode_start)
        x = self._stacker.push(obs)
        if self.normalization is not None:
            x = self.normalization.apply(x)
        return x.astype(np.float32)

    def predict(
        self,
        observation: NDArray,
        state: Any = None,
        episode_start: NDArray | None = None,
        deterministic: bool = True,
    ) -> tuple[NDArray, Any]:
        """SB3-style decision for one observation (d,) or a batch (n, d).

        The frame stack and the recurrent state live in the agent; pass ``episode_start`` (bool per row)
        to clear them for some rows, or call :meth:`reset` at each trial start.

        Returns:
            (action, state): the action (batch dim removed for a single observation) and the recurrent
            state (None for a feed-forward policy).
        """
        single = np.ndim(observation) == 1
        x = self.preprocess(observation, episode_start)
        n = x.shape[0]
        if self.recurrent:
            if episode_start is None:
                episode_start = np.full(n, self._fresh, dtype=bool)
            st = self._state if state is None else state
            action, st = self.policy.predict(x, state=st, episode_start=np.asarray(episode_start, dtype=bool),
                                             deterministic=deterministic)
            self._state = st
        elif deterministic and self._numpy_actor is not None:
            action, st = self._numpy_actor(x), None
        else:
            action, st = self.policy.predict(x, deterministic=deterministic)
        self._fresh = False
        return (action[0] if single else action), st


class _NumpyActor:
    """The deterministic action of a feed-forward SB3 actor-critic (PPO/A2C MlpPolicy), in numpy.

    The same arithmetic as ``policy._predict(obs, deterministic=True)`` (Gaussian mean clipped to the
    Box, or the arg-max of the logits) without torch's per-call overhead: a decision then costs tens of
    microseconds instead of ~0.3 ms, which is what makes the learned policy's decision cost small next
    to min-var's vote.
    """

    def __init__(self, layers: list[tuple[NDArray, NDArray, str]], low: NDArray | None, high: NDArray | None) -> None:
        self.layers = layers
        self.low, self.high = low, high

    def __call__(self, x: NDArray) -> NDArray:
        h = np.asarray(x, dtype=np.float64)
        for w, b, act in self.layers:
            h = h @ w + b
            if act == "tanh":
                h = np.tanh(h)
            elif act == "relu":
                h = np.maximum(h, 0.0)
        if self.low is None:  # Discrete: the most probable action
            return np.argmax(h, axis=-1)
        return np.clip(h, self.low, self.high).astype(np.float32)


def _numpy_actor(pol: Any) -> _NumpyActor | None:
    """A :class:`_NumpyActor` for a plain PPO/A2C MlpPolicy, or None when the policy is anything else."""
    try:
        import torch.nn as nn
        from gymnasium import spaces
        from stable_baselines3.common.policies import ActorCriticPolicy
        from stable_baselines3.common.torch_layers import FlattenExtractor
    except ImportError:  # pragma: no cover
        return None
    if type(pol) is not ActorCriticPolicy or pol.squash_output or getattr(pol, "use_sde", False):
        return None
    if not isinstance(pol.pi_features_extractor, FlattenExtractor):
        return None
    box = isinstance(pol.action_space, spaces.Box)
    if not (box or isinstance(pol.action_space, spaces.Discrete)):
        return None
    modules = [*pol.mlp_extractor.policy_net, pol.action_net]
    layers: list[tuple[NDArray, NDArray, str]] = []
    for m in modules:
        if isinstance(m, nn.Linear):
            layers.append((m.weight.detach().cpu().double().numpy().T.copy(),
                           m.bias.detach().cpu().double().numpy().copy(), "linear"))
        elif isinstance(m, (nn.Tanh, nn.ReLU)) and layers:
            w, b, _ = layers[-1]
            layers[-1] = (w, b, "tanh" if isinstance(m, nn.Tanh) else "relu")
        else:
            return None
    if box:
        return _NumpyActor(layers, pol.action_space.low.astype(np.float64), pol.action_space.high.astype(np.float64))
    return _NumpyActor(layers, None, None)


def resolve_model_path(path: str | Path) -> Path:
    """``path`` (a model directory or a .zip) → SB3's model zip file.

    Raises:
        ValueError: no such file, or a directory without ``model.zip``.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "model.zip"
        if not p.is_file():
            raise ValueError(f"model path {str(path)!r} is a directory without model.zip")
        return p
    if not p.is_file():
        if p.suffix != ".zip" and Path(f"{p}.zip").is_file():
            return Path(f"{p}.zip")
        raise ValueError(f"model path {str(path)!r} does not exist (expected a .zip or a directory with model.zip)")
    return p


def read_run_config(folder: str | Path) -> dict[str, Any]:
    """``folder/config.yml`` as a mapping ({} when absent), read with ``yaml.safe_load``.

    Raises:
        ValueError: not valid YAML or not a mapping.
    """
    cfg_path = Path(folder) / "config.yml"
    if not cfg_path.is_file():
        return {}
    try:
        cfg = yaml.safe_load(cfg_path.read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"{cfg_path} is not valid YAML: {exc}") from exc
    if not isinstance(cfg, dict):
        raise ValueError(f"{cfg_path} must be a mapping, got {type(cfg).__name__}")
    return cfg


def _config_normalises(cfg: Mapping[str, Any]) -> bool:
    norm = cfg.get("normalize")
    if norm is None or norm is False:
        return False
    return not (isinstance(norm, Mapping) and norm.get("norm_obs", True) is False)


def _guess_algo(zip_path: Path) -> str:
    """The algorithm of a saved SB3 zip from the module of its stored policy class (plain JSON, no pickle)."""
    with zipfile.ZipFile(zip_path) as archive:
        data = json.loads(archive.read("data").decode())
    module = str(data.get("policy_class", {}).get("__module__", ""))
    for key, algo in (("recurrent", "recurrentppo"), ("sac", "sac"), ("td3", "td3"), ("dqn", "dqn"),
                      ("tqc", "tqc"), ("qrdqn", "qrdqn")):
        if key in module:
            return algo
    return "ppo"


def _set_threads(num_threads: int | None) -> None:
    if num_threads is not None:
        import torch

        torch.set_num_threads(num_threads)


def _pickle_refusal(path: Path, what: str) -> ValueError:
    return ValueError(
        f"{what}: {path} has no {POLICY_JSON} (the pickle-free policy format). SB3's model.zip and "
        f"vecnormalize.pkl contain pickles, which run code when loaded, so they are read only with "
        f"trust_pickle=True (--trust-pickle) for files you trust; or convert a model you trust with "
        f"`python -m electroloc_gym.train.export {path}`")


def load_policy(path: str | Path, *, trust_pickle: bool = False, device: str = "cpu",
                num_threads: int | None = 1) -> SB3Agent:
    """Load a trained policy as an :class:`SB3Agent`.

    By default only the pickle-free format is read: a model directory holding ``policy.json`` and
    ``policy.safetensors`` (or the ``policy.json`` file, or the directory's ``model.zip``, which then
    stands for its directory). Nothing is unpickled. A bare SB3 zip — and a directory with only
    ``model.zip`` — needs ``trust_pickle=True``; it is then loaded by SB3 (pickle) with its
    ``vecnormalize.pkl`` beside it, and a warning is logged.

    Args:
        path: a model directory, its ``policy.json``, or an SB3 ``.zip``.
        trust_pickle: allow SB3's pickle-based files (only for files you trust: loading runs their code).
        device: torch device for inference ("cpu" is fastest for these small networks).
        num_threads: if not None, ``torch.set_num_threads(num_threads)`` (one thread per process).

    Raises:
        ValueError: missing path; a pickle-based model without ``trust_pickle``; a malformed
            ``policy.json`` or weights file; or a model whose config says observations were
            normalised while the statistics are missing.
    """
    p = Path(path)
    if p.is_file() and p.name == POLICY_JSON:
        p = p.parent
    if not p.exists() and p.suffix != ".zip" and Path(f"{p}.zip").is_file():
        p = Path(f"{p}.zip")
    if not p.exists():
        raise ValueError(f"model path {str(path)!r} does not exist (expected a model directory with "
                         f"{POLICY_JSON}, or an SB3 .zip with trust_pickle=True)")
    if p.is_file() and p.name == "model.zip" and (p.parent / POLICY_JSON).is_file():
        p = p.parent  # our own model directory: its pickle-free files stand for the zip
    if p.is_dir() and (p / POLICY_JSON).is_file():
        return _load_export(p, device, num_threads)
    if not trust_pickle:
        raise _pickle_refusal(p, f"refusing to load {str(path)!r}")
    return _load_pickled(resolve_model_path(p), device, num_threads)


def _load_export(folder: Path, device: str, num_threads: int | None) -> SB3Agent:
    export = read_export(folder)
    cfg = read_run_config(folder)
    if export.normalization is None:
        if _config_normalises(cfg):
            raise PolicyFormatError(f"{folder}/config.yml says observations were normalised, but {POLICY_JSON} "
                                    f"has no normalisation statistics — refusing to run on raw observations")
        if (folder / "vecnormalize.pkl").exists():
            raise PolicyFormatError(f"{folder} has a vecnormalize.pkl (observations were normalised), but "
                                    f"{POLICY_JSON} has no normalisation statistics — refusing to run on raw "
                                    f"observations; re-export the model")
    _set_threads(num_threads)
    policy = build_policy(export, device)
    return SB3Agent(policy, normalization=export.normalization, frame_stack=export.frame_stack,
                    env_kwargs=export.env_kwargs, name=folder.name)


def _load_pickled(zip_path: Path, device: str, num_threads: int | None) -> SB3Agent:
    """SB3's own loader (cloudpickle) and ``vecnormalize.pkl`` (pickle): only for trusted files."""
    logger.warning("loading %s with pickle (trust_pickle=True): a pickle-based model runs code from the file; "
                   "load only files you trust", zip_path)
    folder = zip_path.parent
    cfg = read_run_config(folder) if zip_path.name == "model.zip" else {}
    try:
        algo = str(cfg.get("algo") or _guess_algo(zip_path))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"{zip_path} is not a saved SB3 model (corrupt or not a zip): {exc}") from exc
    _set_threads(num_threads)
    from electroloc_gym.train.config import algo_class

    cls = algo_class(algo)
    # Schedules are only needed to train further; replace them rather than unpickle them.
    custom = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
    try:
        model = cls.load(zip_path, device=device, custom_objects=custom)
    except Exception as exc:  # SB3 raises many kinds (BadZipFile, KeyError, RuntimeError, pickle errors)
        raise ValueError(f"cannot load {zip_path} as a {cls.__name__} model (corrupt file?): "
                         f"{type(exc).__name__}: {exc}") from exc
    normalization = None
    vn_path = folder / "vecnormalize.pkl"
    if vn_path.is_file():
        try:
            with vn_path.open("rb") as fh:
                vn = pickle.load(fh)  # noqa: S301 - trust_pickle=True was given
            if getattr(vn, "norm_obs", True):
                normalization = ObsNormalization(np.asarray(vn.obs_rms.mean), np.asarray(vn.obs_rms.var),
                                                 clip_obs=float(vn.clip_obs), epsilon=float(vn.epsilon))
        except Exception as exc:  # noqa: BLE001
            raise ValueError(f"cannot read the normalisation statistics {vn_path}: "
                             f"{type(exc).__name__}: {exc}") from exc
        if normalization is not None and normalization.mean.shape != model.observation_space.shape:
            raise ValueError(f"{vn_path} has statistics of shape {normalization.mean.shape}, "
                             f"the model expects {model.observation_space.shape}")
    elif _config_normalises(cfg):
        raise ValueError(f"{folder}/config.yml says observations were normalised, but {vn_path.name} is missing "
                         f"— refusing to run on raw observations")
    frame_stack = int(cfg.get("frame_stack", 1) or 1)
    env_kwargs = {k: v for k, v in (cfg.get("env_kwargs") or {}).items() if k in AGENT_ENV_KWARGS}
    if "observation" not in env_kwargs:  # a bare zip: infer from the network's input size
        from electroloc_gym.envs.observation import RAW_OBS_DIM

        env_kwargs["observation"] = "raw" if model.observation_space.shape[0] == RAW_OBS_DIM * frame_stack else "belief"
    if "action_type" not in env_kwargs:
        env_kwargs["action_type"] = "discrete" if hasattr(model.action_space, "n") else "continuous"
    name = folder.name if zip_path.name == "model.zip" else zip_path.stem
    return SB3Agent(model, normalization=normalization, frame_stack=frame_stack, env_kwargs=env_kwargs, name=name)
