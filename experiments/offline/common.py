"""What the offline trainers share: Minari datasets as transition arrays, the actor, its export, validation.

* :func:`load_transitions` reads local Minari datasets (``minari.load_dataset``) into flat arrays
  (observations, actions, rewards, next observations, terminals), episodes in id order.
* :class:`Normalizer` is the observation standardisation the actor trains with; it is written into the
  policy file as its ``normalization`` block (mean, variance, clip, epsilon), which the benchmark's
  loader applies exactly as here.
* :class:`Actor` is a deterministic tanh actor with the layer names of SB3's ``SACPolicy`` actor
  (``actor.latent_pi.{0,2}``, ``actor.mu``), so :func:`export_actor` writes it in the project's pickle-free
  policy format (:mod:`electroloc_gym.policy.format`) and ``electroloc bench`` runs it with numpy like any
  shipped policy; :func:`export_actor` checks the numpy actions against torch's (to 1e-4: float64 against float32).
* :func:`finish` keeps the checkpoint with the fewest validation readings, writes the curve and exports it
  with its provenance; :func:`main_of` is the trainers' command line (every field of their config an option).
* :func:`validate` runs the torch actor on validation episodes (reset seeds 100000+, the training
  callback's, never the benchmark's seed 0) through the benchmark's rollout loop: mean readings (a failure
  counted as the cap) and success rate — the learning curve and the checkpoint choice.

The trainers are written by hand in the single-file style of CORL (Tarasov et al., 2022): the maintained
offline-RL libraries pin gymnasium or SB3 versions this package cannot install beside it (imitation 1.0.1:
gymnasium~=0.29; d3rlpy 2.8.1: gymnasium==1.0.0).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

#: First reset seed of the validation episodes (the training callback's, disjoint from evaluation).
VALIDATION_SEED = 100_000
#: Clip of the standardised observation (VecNormalize's default).
CLIP_OBS = 10.0
#: Added to the variance before the square root.
EPSILON = 1e-6


def load_transitions(dataset_ids: Sequence[str]) -> dict[str, np.ndarray]:
    """Flat transition arrays of the datasets (``observations``, ``actions``, ``rewards``,
    ``next_observations``, ``terminals``, ``source`` — the index of the dataset in ``dataset_ids``).
    """
    import minari

    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ("observations", "actions", "rewards", "next_observations", "terminals", "source")
    }
    for j, ds_id in enumerate(dataset_ids):
        ds = minari.load_dataset(ds_id)
        for ep in ds.iterate_episodes():
            obs = np.asarray(ep.observations, dtype=np.float32)
            n = len(ep.actions)
            parts["observations"].append(obs[:-1])
            parts["next_observations"].append(obs[1:])
            parts["actions"].append(np.asarray(ep.actions, dtype=np.float32).reshape(n, -1))
            parts["rewards"].append(np.asarray(ep.rewards, dtype=np.float32))
            parts["terminals"].append(np.asarray(ep.terminations, dtype=np.float32))
            parts["source"].append(np.full(n, j, dtype=np.int64))
    return {k: np.concatenate(v) for k, v in parts.items()}


@dataclass(frozen=True)
class Normalizer:
    """``clip((x − mean) / sqrt(var + EPSILON), ±CLIP_OBS)``: the benchmark loader's ``ObsNormalization``."""

    mean: np.ndarray
    var: np.ndarray

    @classmethod
    def fit(cls, observations: np.ndarray) -> Normalizer:
        return cls(observations.mean(axis=0).astype(np.float64), observations.var(axis=0).astype(np.float64))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.clip((x - self.mean) / np.sqrt(self.var + EPSILON), -CLIP_OBS, CLIP_OBS).astype(np.float32)

    def to_json(self) -> dict[str, Any]:
        return {
            "norm_obs": True,
            "norm_reward": False,
            "clip_obs": CLIP_OBS,
            "epsilon": EPSILON,
            "obs_mean": self.mean.tolist(),
            "obs_var": self.var.tolist(),
        }


class Actor(nn.Module):
    """Deterministic ``tanh(mu(latent_pi(x)))`` in [−1, 1]: SB3's SACPolicy actor layout (ReLU MLP)."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256)) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        d = obs_dim
        for h in hidden:
            layers += [nn.Linear(d, h), nn.ReLU()]
            d = h
        self.latent_pi = nn.Sequential(*layers)
        self.mu = nn.Linear(d, act_dim)
        self.hidden = tuple(int(h) for h in hidden)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.mu(self.latent_pi(x)))

    @torch.no_grad()
    def act(self, x: np.ndarray) -> np.ndarray:
        return self(torch.as_tensor(np.asarray(x, dtype=np.float32)[None])).numpy()[0]


def export_actor(
    actor: Actor,
    norm: Normalizer,
    out: str | Path,
    *,
    algo: str,
    env_id: str,
    provenance: dict[str, Any],
    evaluation: dict[str, Any] | None = None,
) -> Path:
    """Write ``actor`` as a policy folder (policy.json + policy.safetensors) and check that the numpy
    loader's actions equal torch's on standardised random observations (to 1e-4).
    """
    import gymnasium as gym

    import electroloc_gym  # noqa: F401
    from electroloc_gym.policy.format import space_to_json, write_export
    from electroloc_gym.policy.load import load_policy

    env = gym.make(env_id)
    obs_space, act_space = env.observation_space, env.action_space
    env.close()
    tensors = {f"actor.{k}": v.detach().cpu().numpy().astype(np.float32) for k, v in actor.state_dict().items()}
    meta = {
        "algo": algo,
        "architecture": {
            "policy_class": "SACPolicy",
            "policy_kwargs": {"net_arch": list(actor.hidden), "activation_fn": "relu"},
            "recurrent": None,
        },
        "observation": {
            "env_id": env_id,
            "mode": "belief",
            "frame_stack": 1,
            "frame_dim": int(obs_space.shape[0]),
            "shape": [int(obs_space.shape[0])],
            "space": space_to_json(obs_space),
        },
        "action": {"action_type": "continuous", "space": space_to_json(act_space)},
        "normalization": norm.to_json(),
        "env_kwargs": {"observation": "belief"},
        "provenance": provenance,
        "evaluation": evaluation or {},
    }
    folder = write_export(out, meta, tensors)
    agent = load_policy(folder)
    x = np.random.default_rng(0).uniform(-1, 1, size=(64, obs_space.shape[0])).astype(np.float32)
    want = actor(torch.as_tensor(norm(x))).detach().numpy()
    got, _ = agent.predict(x)
    if not np.allclose(got, want, atol=1e-4):  # float64 numpy against float32 torch
        raise RuntimeError(f"the exported policy's actions differ from torch's by {np.abs(got - want).max():.2e}")
    return folder


class _TorchAgent:
    """A torch actor behind the benchmark's agent protocol (for validation during training)."""

    def __init__(self, actor: Actor, norm: Normalizer) -> None:
        self.actor, self.norm = actor, norm

    def reset(self, env: Any) -> None:
        pass

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, Any]:
        return self.actor.act(self.norm(np.asarray(observation, dtype=np.float32)[None])[0]), None


def validate(actor: Actor, norm: Normalizer, env: Any, episodes: int) -> dict[str, float]:
    """Mean readings (a failure counted as the cap), success rate and ms per decision on validation episodes."""
    from electroloc_gym.rollout import run_episode

    agent = _TorchAgent(actor, norm)
    readings, success, decision = [], [], []
    for k in range(episodes):
        ep = run_episode(env, agent, VALIDATION_SEED + k)
        ok = bool(ep.terminated and ep.info["success"])
        cap = int(env.unwrapped.params.max_observations)
        readings.append(int(ep.info["n_observations"]) if ok else cap)
        success.append(ok)
        decision += ep.decision_s
    return {
        "readings": float(np.mean(readings)),
        "success": float(np.mean(success)),
        "decision_ms": float(np.median(decision) * 1e3),
    }


def seed_everything(seed: int) -> None:
    """torch, numpy; one thread (the machine is shared)."""
    torch.manual_seed(seed)
    np.random.seed(seed)
    torch.set_num_threads(1)


def write_curve(path: Path, rows: list[dict[str, Any]]) -> None:
    """The learning curve as JSON (list of {step, readings, success, ...})."""
    from electroloc_gym.fileio import write_json_atomic

    write_json_atomic(path, rows)


def timer() -> float:
    """Monotonic seconds."""
    return time.perf_counter()


def read_json(path: Path) -> Any:
    """A JSON file's content."""
    return json.loads(Path(path).read_text(encoding="utf-8"))


def finish(
    actor: Actor,
    best_state: dict[str, Any],
    best: dict[str, Any],
    curve: list[dict[str, Any]],
    *,
    norm: Normalizer,
    config: Any,
    algo: str,
    trainer: str,
    datasets: Sequence[str],
    transitions: int,
    t0: float,
) -> dict[str, Any]:
    """Load the chosen checkpoint into ``actor``, write ``curve.json`` and export the policy to ``config.out``."""
    from dataclasses import asdict

    out = Path(config.out)
    actor.load_state_dict(best_state)
    write_curve(out / "curve.json", curve)
    provenance = {
        "trainer": trainer,
        "config": asdict(config),
        "datasets": list(datasets),
        "transitions": int(transitions),
        "wall_time_s": round(timer() - t0, 1),
        "checkpoint_chosen_by": "fewest mean readings (failures as the cap) on the validation episodes",
        "validation": {"episodes": config.eval_episodes, "first_seed": VALIDATION_SEED},
    }
    export_actor(actor, norm, out / "policy", algo=algo, env_id=config.env_id, provenance=provenance, evaluation=best)
    return {"best": best, "curve": curve}


def main_of(config_class: type, train: Any, doc: str, positive: Sequence[str]) -> Any:
    """A trainer's command line: every field of ``config_class`` as an option, ``positive`` ones ≥ 1."""
    import argparse
    from dataclasses import fields

    def main(argv: list[str] | None = None) -> int:
        parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
        for f in fields(config_class):
            parser.add_argument(f"--{f.name.replace('_', '-')}", type=type(f.default), default=f.default)
        config = config_class(**vars(parser.parse_args(argv)))
        for name in positive:
            if getattr(config, name) < 1:
                parser.error(f"--{name.replace('_', '-')} must be ≥ 1, got {getattr(config, name)}")
        train(config)
        return 0

    return main
