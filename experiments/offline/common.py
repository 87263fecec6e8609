"""What the offline trainers share: Minari datasets as transition arrays, the actor, its export, validation.

* :func:`prepare` checks a trainer's settings and datasets before anything is trained or written (one
  :class:`ArgumentError` naming the option and what it allows): every option in its range, ``--env-id`` an
  env of the table, ``--out`` a folder that can be written, and every dataset an id of Minari's form, present,
  complete, collected on ``--env-id`` (its ``electroloc`` block's ``env_id``; datasets of different envs are
  not mixed), with the validation env's observation and action spaces, holding finite transitions.
* :func:`load_transitions` reads local Minari datasets (``minari.load_dataset``) into flat arrays
  (observations, actions, rewards, next observations, terminals), episodes in id order.
* :class:`Normalizer` is the observation standardisation the actor trains with; it is written into the
  policy file as its ``normalization`` block (mean, variance, clip, epsilon), which the benchmark's
  loader applies exactly as here.
* :class:`Actor` is a deterministic tanh actor with the layer names of SB3's ``SACPolicy`` actor
  (``actor.latent_pi.{0,2}``, ``actor.mu``), so :func:`export_actor` writes it in the project's pickle-free
  policy format (:mod:`electroloc_gym.policy.format`) and ``electroloc bench`` runs it with numpy like any
  shipped policy; :func:`export_actor` checks the numpy actions against torch's (to 1e-4: float64 against float32).
* :func:`finish` loads the chosen checkpoint, writes the curve and exports it with its provenance;
  :func:`main_of` is the trainers' command line (every field of their config an option).
* :func:`validate` runs the torch actor on validation episodes (reset seeds 100000+, the training
  callback's, never the benchmark's seed 0) through the benchmark's rollout loop: mean readings (a failure
  counted as the cap) and success rate, and the task's own score and rate where it declares its own
  (``Task.metrics``: on the moving target the mean tracking error, mm, and the capture rate), read from each
  episode's final info as the benchmark's records read them — the learning curve.
* The checkpoint is chosen by the env's own score (:func:`checkpoint_score`: its task's declared
  ``metrics.score``; :func:`improves`): the fewest mean validation readings, and on the moving target, where
  every episode runs all its readings, the lowest mean tracking error; of equal scores the first is kept.

The trainers are written by hand in the single-file style of CORL (Tarasov et al., 2022): the maintained
offline-RL libraries pin gymnasium or SB3 versions this package cannot install beside it (imitation 1.0.1:
gymnasium~=0.29; d3rlpy 2.8.1: gymnasium==1.0.0).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, fields
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
#: Each option's allowed values: (low, high, low allowed). Integers are counts ≥ 1 unless listed; every
#: float is finite. The learning rate is a step size in (0, 1].
RANGES: dict[str, tuple[float, float, bool]] = {
    "seed": (0, 2**32 - 1, True),  # numpy's global seed
    "steps": (1, 10**9, True),
    "batch_size": (1, 10**6, True),
    "eval_every": (1, 10**9, True),
    "eval_episodes": (1, 10**5, True),
    "policy_freq": (1, 10**6, True),
    "lr": (0.0, 1.0, False),
    "discount": (0.0, 1.0, True),
    "tau": (0.0, 1.0, False),
    "policy_noise": (0.0, 1.0, True),
    "noise_clip": (0.0, 1.0, True),
    "alpha": (0.0, 1000.0, False),
}


class ArgumentError(ValueError):
    """A trainer's option or dataset that cannot be used: one line naming it and what is allowed."""


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def check_settings(config: Any) -> None:
    """Every number of ``config`` in its :data:`RANGES` range, ``env_id`` an env of the table and ``out`` a
    folder that can be written (checked without creating anything).

    Raises:
        ArgumentError: the first option out of range, named as its command-line flag.
    """
    from electroloc_gym.registry import ENV_IDS

    for f in fields(config):
        value = getattr(config, f.name)
        if f.name not in RANGES:
            continue
        low, high, closed = RANGES[f.name]
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        if isinstance(f.default, int) and not isinstance(value, int):
            ok = False
        if not ok or not ((value >= low if closed else value > low) and value <= high):
            integer = isinstance(f.default, int)
            what = "an integer" if integer else "a finite number"
            lo, hi = (f"{int(low)}", f"{int(high)}") if integer else (f"{low:g}", f"{high:g}")
            rng = f"in [{lo}, {hi}]" if closed else f"in ({lo}, {hi}]"
            raise ArgumentError(f"{_flag(f.name)} must be {what} {rng}, got {value!r}")
    if config.env_id not in ENV_IDS:
        raise ArgumentError(f"--env-id must be one of {list(ENV_IDS)}, got {config.env_id!r}")
    check_out(config.out)


def check_folder(flag: str, folder: Any) -> Path:
    """``folder`` (the value of option ``flag``) names a folder that can be created or written into, checked
    without creating anything.

    Raises:
        ArgumentError: empty, a file, under a file, or no write permission where it would be created.
    """
    if not isinstance(folder, (str, os.PathLike)) or not str(folder).strip():
        raise ArgumentError(f"{flag} must name a folder, got {folder!r}")
    path = Path(folder).expanduser()
    if path.exists() and not path.is_dir():
        raise ArgumentError(f"{flag} {str(folder)!r} is a file, not a folder")
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise ArgumentError(f"{flag} {str(folder)!r} is under {str(parent)!r}, which is a file")
            break
    existing = next(p for p in (path.absolute(), *path.absolute().parents) if p.exists())
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ArgumentError(f"{flag} {str(folder)!r}: {str(existing)!r} is not writable")
    return path


def check_out(out: str) -> None:
    """``--out`` names a folder this trainer can create or write into (``curve.json`` and ``policy/``).

    Raises:
        ArgumentError: what :func:`check_folder` refuses, or a folder holding ``curve.json`` or ``policy``
            of the other kind (a folder, a file).
    """
    path = check_folder("--out", out)
    for name, want_dir in (("curve.json", False), ("policy", True)):
        p = path / name
        if p.exists() and p.is_dir() != want_dir:
            kind = "a folder" if p.is_dir() else "a file"
            raise ArgumentError(f"--out {out!r} holds {name!r} as {kind}; the trainer writes it as the other")


def dataset_ids(text: str) -> list[str]:
    """The comma-separated ids of ``--datasets``, each of Minari's form ``NAMESPACE/NAME-vN``, none twice.

    Raises:
        ArgumentError: no id, a malformed id or one named twice.
    """
    from minari.dataset.minari_dataset import DATASET_ID_RE

    ids = [t.strip() for t in str(text).split(",")]
    if not any(ids):
        raise ArgumentError(f"--datasets names no dataset (comma-separated Minari ids), got {text!r}")
    for ds_id in ids:
        match = DATASET_ID_RE.fullmatch(ds_id)
        if not ds_id or match is None or match["version"] is None:
            raise ArgumentError(f"--datasets: {ds_id!r} is not a Minari dataset id NAMESPACE/NAME-vN")
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise ArgumentError(f"--datasets names {twice} more than once")
    return ids


def dataset_env_id(ds: Any, ds_id: str) -> str:
    """The env a dataset was collected on: its ``electroloc`` block's ``env_id`` (``electroloc dataset``'s).

    Raises:
        ArgumentError: a dataset without that block (not made by ``electroloc dataset``) or not complete.
    """
    block = ds.storage.metadata.get("electroloc")
    if not isinstance(block, dict) or not isinstance(block.get("env_id"), str):
        raise ArgumentError(
            f"--datasets: {ds_id!r} was not made by `electroloc dataset` (its metadata has no electroloc env_id)"
        )
    if block.get("complete") is not True:
        raise ArgumentError(
            f"--datasets: {ds_id!r} is not complete (its collection did not finish): continue it with "
            f"`electroloc dataset ... --resume`"
        )
    return block["env_id"]


def load_datasets(ids: Sequence[str], env_id: str, env: Any) -> list[Any]:
    """The Minari datasets ``ids``, each checked against ``env_id`` and ``env``'s spaces.

    Raises:
        ArgumentError: a dataset that is missing or unreadable, not complete, collected on another env (or
            datasets of different envs mixed), or whose observation or action space is not ``env``'s.
    """
    import minari

    root = os.environ.get("MINARI_DATASETS_PATH") or "~/.minari/datasets (MINARI_DATASETS_PATH unset)"
    out, envs = [], {}
    for ds_id in ids:
        try:
            ds = minari.load_dataset(ds_id)
        except FileNotFoundError:
            raise ArgumentError(f"--datasets: no dataset {ds_id!r} in {root}") from None
        except Exception as exc:  # noqa: BLE001 - a damaged dataset: Minari's error in one line
            first = (str(exc).strip().splitlines() or [""])[0][:200]
            raise ArgumentError(f"--datasets: {ds_id!r} cannot be read: {type(exc).__name__}: {first}") from None
        envs[ds_id] = dataset_env_id(ds, ds_id)
        out.append(ds)
    if len(set(envs.values())) > 1:
        raise ArgumentError(f"--datasets mixes datasets of different envs: {envs}")
    for ds_id, ds in zip(ids, out):
        if envs[ds_id] != env_id:
            raise ArgumentError(f"--datasets: {ds_id!r} was collected on {envs[ds_id]}, not --env-id {env_id}")
        for what, got, want in (
            ("observation", ds.observation_space, env.observation_space),
            ("action", ds.action_space, env.action_space),
        ):
            if got != want:
                raise ArgumentError(
                    f"--datasets: {ds_id!r} has the {what} space {got}, the trainer's {env_id} env {want} "
                    f"(collected with other env arguments: {ds.storage.metadata['electroloc'].get('env_kwargs')})"
                )
        if ds.total_steps < 1:
            raise ArgumentError(f"--datasets: {ds_id!r} holds no transitions")
    return out


def validation_env(env_id: str) -> Any:
    """The env the actor is validated on (and the datasets checked against): ``env_id`` over the eight presets
    (``condition="random"``) where it takes a condition, its defaults otherwise.
    """
    import gymnasium as gym

    import electroloc_gym  # noqa: F401
    from electroloc_gym.registry import env_entry

    return gym.make(env_id, **({"condition": "random"} if env_entry(env_id).takes("condition") else {}))


def prepare(config: Any) -> tuple[list[str], dict[str, np.ndarray], Any]:
    """Everything a trainer checks before it trains (``ids``, the transitions, the validation env).

    Raises:
        ArgumentError: an option or a dataset that cannot be used (:func:`check_settings`,
            :func:`dataset_ids`, :func:`load_datasets`), or transitions that are not finite.
    """
    check_settings(config)
    ids = dataset_ids(config.datasets)
    env = validation_env(config.env_id)
    data = load_transitions(load_datasets(ids, config.env_id, env))
    for key in ("observations", "actions", "rewards"):
        bad = ~np.isfinite(data[key]).reshape(len(data[key]), -1).all(axis=1)
        if bad.any():
            ds_id = ids[int(data["source"][np.argmax(bad)])]
            raise ArgumentError(f"--datasets: {ds_id!r} holds non-finite {key} ({int(bad.sum())} transitions)")
    return ids, data, env


def load_transitions(datasets: Sequence[Any]) -> dict[str, np.ndarray]:
    """Flat transition arrays of the datasets (ids or loaded Minari datasets): ``observations``, ``actions``,
    ``rewards``, ``next_observations``, ``terminals``, ``source`` — the index of the dataset in ``datasets``.
    """
    import minari

    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ("observations", "actions", "rewards", "next_observations", "terminals", "source")
    }
    for j, dataset in enumerate(datasets):
        ds = minari.load_dataset(dataset) if isinstance(dataset, str) else dataset
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


def _metrics(env_id: str) -> Any:
    from electroloc_gym.registry import env_entry

    return env_entry(env_id).task_class.metrics


def checkpoint_score(env_id: str) -> tuple[str, str]:
    """``(key, direction)`` of the validation row that chooses the checkpoint on ``env_id``: its task's declared
    score (``Task.metrics.score``), ``("readings", "lower")`` by default, ``("tracking_error_mm", "lower")`` on
    the moving target.
    """
    score = _metrics(env_id).score
    return score.key, score.better


def improves(row: dict[str, Any], best: dict[str, Any] | None, score: tuple[str, str]) -> bool:
    """Whether validation ``row`` beats ``best`` (None: nothing yet) by ``score`` (:func:`checkpoint_score`);
    an equal score does not (the earlier checkpoint is kept).
    """
    if best is None:
        return True
    key, direction = score
    return row[key] < best[key] if direction == "lower" else row[key] > best[key]


def validate(actor: Actor, norm: Normalizer, env: Any, episodes: int) -> dict[str, float]:
    """Mean readings (a failure counted as the cap), success rate and ms per decision on validation episodes;
    where the task declares its own score and rate (``Task.metrics``), also their means over the episodes'
    final infos under the score's key and the rate's name (the moving target: ``tracking_error_mm``, mm, and
    ``capture``, the fraction of episodes ending captured).
    """
    from electroloc_gym.baselines.rollout import run_episode

    metrics = _metrics(env.spec.id)
    agent = _TorchAgent(actor, norm)
    readings, success, decision, scores, rates = [], [], [], [], []
    for k in range(episodes):
        ep = run_episode(env, agent, VALIDATION_SEED + k)
        ok = bool(ep.terminated and ep.info["success"])
        cap = int(env.unwrapped.params.max_observations)
        readings.append(int(ep.info["n_observations"]) if ok else cap)
        success.append(ok)
        decision += ep.decision_s
        scores.append(metrics.score.of_info(ep.info))  # the env's own, from the final info (as the records)
        rates.append(metrics.rate.of_info(ep.info))
    out = {
        "readings": float(np.mean(readings)),
        "success": float(np.mean(success)),
        "decision_ms": float(np.median(decision) * 1e3),
    }
    out.setdefault(metrics.score.key, float(np.mean(scores)))  # a task's own score and rate beside the shared
    out.setdefault(metrics.rate.name, float(np.mean(rates)))
    return out


def describe(row: dict[str, Any]) -> str:
    """A validation row in a few words for the trainers' progress lines (a task's own score and rate after the
    shared readings and success).
    """
    text = f"readings {row['readings']:.2f} success {row['success']:.2f}"
    for key, value in row.items():
        if key not in ("step", "readings", "success", "decision_ms"):
            text += f" {key} {value:.2f}"
    return text


def seed_everything(seed: int) -> None:
    """torch, numpy; one thread (the machine is shared)."""
    torch.manual_seed(seed)
    np.random.seed(seed)
    torch.set_num_threads(1)


def write_curve(path: Path, rows: list[dict[str, Any]]) -> None:
    """The learning curve as JSON (list of {step, readings, success, ...})."""
    from electroloc_gym.utils.fileio import write_json_atomic

    write_json_atomic(path, rows)


def timer() -> float:
    """Monotonic seconds."""
    return time.perf_counter()


def _chosen_by(env_id: str) -> str:
    """The provenance's words for the checkpoint choice (the task's declared score's)."""
    return f"{_metrics(env_id).score.best} on the validation episodes"


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
        "checkpoint_chosen_by": _chosen_by(config.env_id),
        "validation": {"episodes": config.eval_episodes, "first_seed": VALIDATION_SEED},
    }
    export_actor(actor, norm, out / "policy", algo=algo, env_id=config.env_id, provenance=provenance, evaluation=best)
    return {"best": best, "curve": curve}


def main_of(config_class: type, train: Any, doc: str) -> Any:
    """A trainer's command line: every field of ``config_class`` as an option (integers in ASCII digits).

    Whatever :func:`prepare` refuses — before anything is trained or written — is argparse's one-line
    ``prog: error: ...`` and exit status 2.
    """
    import argparse

    from electroloc_gym.bench.bench_command import ascii_int

    def main(argv: list[str] | None = None) -> int:
        parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
        for f in fields(config_class):
            kind = ascii_int if isinstance(f.default, int) else type(f.default)
            parser.add_argument(_flag(f.name), type=kind, default=f.default)
        config = config_class(**vars(parser.parse_args(argv)))
        try:
            train(config)
        except ArgumentError as exc:
            parser.error(str(exc))
        return 0

    return main
