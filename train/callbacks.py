"""Training callbacks: seeded evaluation (success, median steps, median error), checkpoints, atomic saves.

The evaluation runs the *current* policy through :class:`electroloc_gym.train.policy.SB3Agent` — the very wrapper
the benchmark uses — on a fixed list of seeded episodes, so the numbers in ``eval.csv`` are
comparable across a run and with the benchmark's metric definitions (steps = ``info["n_observations"]``,
the observations fused, as the paper counts them).
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml
from stable_baselines3.common.callbacks import BaseCallback

from electroloc_gym.bench.rollout import run_episode
from electroloc_gym.fileio import atomic_write_bytes, atomic_write_text  # noqa: F401  (re-exported)
from electroloc_gym.train.policy import SB3Agent
from electroloc_gym.train.policy_format import export_policy, normalization_from_vecnormalize

__all__ = [
    "EvalResult",
    "SeededEvalCallback",
    "ModelDirCheckpoint",
    "atomic_write_bytes",
    "atomic_write_text",
    "evaluate_agent",
    "save_model_dir",
]

EVAL_CSV_FIELDS = ("timesteps", "wall_time_s", "episodes", "success_rate", "median_steps", "mean_steps",
                   "median_steps_success", "median_error_mm", "mean_error_mm")


def _observation_info(model: Any, config: Mapping[str, Any]) -> dict[str, Any]:
    """What ``policy.json`` records about the observation and action layout, from the run config."""
    env_kwargs = dict(config.get("env_kwargs") or {})
    frame_stack = int(config.get("frame_stack", 1) or 1)
    mode = env_kwargs.get("observation")
    if mode is None:  # the env's default; infer it from the network's input size
        from electroloc_gym.envs.observation import RAW_OBS_DIM

        mode = "raw" if model.observation_space.shape[0] == RAW_OBS_DIM * frame_stack else "belief"
    action_type = env_kwargs.get("action_type") or ("discrete" if hasattr(model.action_space, "n") else "continuous")
    return {"env_id": config.get("env_id", "ElectroLoc-v0"), "mode": mode, "action_type": action_type,
            "frame_stack": frame_stack, "env_kwargs": env_kwargs, "algo": config.get("algo")}


def save_model_dir(model: Any, folder: str | Path, config: Mapping[str, Any], *,
                   provenance: Mapping[str, Any] | None = None, evaluation: Mapping[str, Any] | None = None) -> Path:
    """Save a model directory atomically: ``policy.safetensors`` + ``policy.json``, ``model.zip``, ``config.yml``.

    The pickle-free pair is what this project loads (:mod:`electroloc_gym.train.policy_format`);
    ``model.zip`` is SB3's own (pickle-based) file for SB3 users. No ``vecnormalize.pkl`` is written:
    the observation statistics are in ``policy.json``.

    Returns:
        The folder.
    """
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    model.save(buf)
    atomic_write_bytes(d / "model.zip", buf.getvalue())
    atomic_write_text(d / "config.yml", yaml.safe_dump(dict(config), sort_keys=False))
    prov = {**dict(provenance or {}), "timesteps": int(model.num_timesteps),
            "saved_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    prov.setdefault("seed", config.get("seed"))
    export_policy(model, d, observation=_observation_info(model, config),
                  normalization=normalization_from_vecnormalize(model.get_vec_normalize_env()),
                  provenance=prov, evaluation=evaluation)  # last: policy.json names the weights it goes with
    return d


@dataclass(frozen=True)
class EvalResult:
    """Aggregate of a seeded evaluation. Steps are observations fused (``info["n_observations"]``)."""

    episodes: int
    success_rate: float
    median_steps: float
    mean_steps: float
    median_steps_success: float
    median_error_mm: float
    mean_error_mm: float


def evaluate_agent(agent: Any, env_id: str, env_kwargs: Mapping[str, Any], seeds: Sequence[int]) -> EvalResult:
    """Run one episode per seed with ``agent`` (deterministic) and aggregate.

    Each episode is the benchmark's (:func:`electroloc_gym.bench.rollout.run_episode`).

    Args:
        agent: anything with ``reset(env)``, ``predict(obs, ...)`` and ``env_kwargs``.
        env_id: Gymnasium id.
        env_kwargs: env kwargs (the agent's own ``env_kwargs`` are merged on top).
        seeds: one reset seed per episode.
    """
    import electroloc_gym  # noqa: F401  (registers the ids)

    env = gym.make(env_id, **{**dict(env_kwargs), **dict(getattr(agent, "env_kwargs", {}))})
    steps, errors, success = [], [], []
    try:
        for s in seeds:
            info = run_episode(env, agent, int(s), deterministic=True).info
            steps.append(int(info["n_observations"]))
            errors.append(float(info["error_mm"]))
            success.append(bool(info["success"]))
    finally:
        env.close()
    st, er, ok = np.asarray(steps, float), np.asarray(errors, float), np.asarray(success, bool)
    return EvalResult(
        episodes=len(st),
        success_rate=float(ok.mean()),
        median_steps=float(np.median(st)),
        mean_steps=float(st.mean()),
        median_steps_success=float(np.median(st[ok])) if ok.any() else float("nan"),
        median_error_mm=float(np.median(er)),
        mean_error_mm=float(er.mean()),
    )


def _agent_from_training(model: Any, frame_stack: int, env_kwargs: Mapping[str, Any]) -> SB3Agent:
    vn = model.get_vec_normalize_env()
    obs_rms = None
    if vn is not None and vn.norm_obs:
        obs_rms = vn.obs_rms.copy()  # frozen copy: evaluation must not move the statistics
    return SB3Agent(model, obs_rms=obs_rms, clip_obs=getattr(vn, "clip_obs", 10.0),
                    epsilon=getattr(vn, "epsilon", 1e-8), frame_stack=frame_stack, env_kwargs=env_kwargs)


class SeededEvalCallback(BaseCallback):
    """Every ``eval_freq`` env steps: evaluate on fixed seeds, log, keep the best model.

    Writes one row per evaluation to ``csv_path`` (always) and records ``eval/*`` in SB3's logger
    (TensorBoard when it is installed and enabled). The best model (lowest mean steps, failures
    counting as the observation cap — i.e. the highest return) is saved to ``best_dir``.

    Args:
        env_id: Gymnasium id.
        env_kwargs: evaluation env kwargs (include the agent's observation/action kwargs).
        seeds: reset seeds, one episode each (keep them disjoint from the benchmark's).
        eval_freq: env steps between evaluations.
        csv_path: where the rows go.
        best_dir: model directory for the best model (None: do not save).
        config: the resolved run config written beside saved models.
        frame_stack: the policy's frame stack.
        t0: wall-clock start of training (``time.time()``; a resumed run passes its start shifted back by
            the earlier segments' wall time, so that ``wall_time_s`` counts the whole run).
        best_mean_steps: the best score so far (a resumed run's, so that a worse model never replaces
            its ``best/``); ``inf`` for a new run.
        provenance: written into each saved model's ``policy.json``.
        on_evaluate: called with the number of timesteps after each evaluation (run records).
    """

    def __init__(self, env_id: str, env_kwargs: Mapping[str, Any], seeds: Sequence[int], eval_freq: int,
                 csv_path: str | Path, best_dir: str | Path | None, config: Mapping[str, Any],
                 frame_stack: int = 1, t0: float | None = None, verbose: int = 1, *,
                 best_mean_steps: float = float("inf"), provenance: Mapping[str, Any] | None = None,
                 on_evaluate: Callable[[int], None] | None = None) -> None:
        super().__init__(verbose)
        if eval_freq < 1:
            raise ValueError(f"eval_freq must be ≥ 1 env step, got {eval_freq}")
        self.env_id = env_id
        self.env_kwargs = dict(env_kwargs)
        self.seeds = [int(s) for s in seeds]
        self.eval_freq = int(eval_freq)
        self.csv_path = Path(csv_path)
        self.best_dir = None if best_dir is None else Path(best_dir)
        self.config = dict(config)
        self.frame_stack = frame_stack
        self.t0 = time.time() if t0 is None else t0
        self.best_mean_steps = float(best_mean_steps)
        self.best_timesteps: int | None = None
        self.provenance = dict(provenance or {})
        self.on_evaluate = on_evaluate
        self.history: list[dict[str, float]] = []
        self._last = -1

    def _on_training_start(self) -> None:
        self._last = self.num_timesteps
        if not self.csv_path.exists():
            self.csv_path.parent.mkdir(parents=True, exist_ok=True)
            with self.csv_path.open("w", newline="") as fh:
                csv.writer(fh).writerow(EVAL_CSV_FIELDS)
        if self.num_timesteps == 0:
            self.evaluate()

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.eval_freq:
            self._last = self.num_timesteps
            self.evaluate()
        return True

    def _on_training_end(self) -> None:
        if self.num_timesteps != self._last:
            self._last = self.num_timesteps
            self.evaluate()

    def evaluate(self) -> EvalResult:
        """Evaluate now, append a CSV row, log, and save the model if it is the best so far."""
        agent = _agent_from_training(self.model, self.frame_stack, {})
        res = evaluate_agent(agent, self.env_id, self.env_kwargs, self.seeds)
        row = {"timesteps": int(self.num_timesteps), "wall_time_s": round(time.time() - self.t0, 1), **asdict(res)}
        self.history.append(row)
        with self.csv_path.open("a", newline="") as fh:
            csv.writer(fh).writerow([row[k] for k in EVAL_CSV_FIELDS])
        for k in ("success_rate", "median_steps", "mean_steps", "median_error_mm"):
            self.logger.record(f"eval/{k}", row[k])
        if self.verbose:
            print(f"[eval] t={row['timesteps']:>8d}  success {res.success_rate:5.1%}  median steps "
                  f"{res.median_steps:4.1f}  mean steps {res.mean_steps:5.2f}  median error "
                  f"{res.median_error_mm:4.2f} mm  ({row['wall_time_s']:.0f} s)", flush=True)
        if self.best_dir is not None and res.mean_steps <= self.best_mean_steps:
            self.best_mean_steps = res.mean_steps
            self.best_timesteps = row["timesteps"]
            cfg = {**self.config, "eval": row}
            save_model_dir(self.model, self.best_dir, cfg, provenance=self.provenance, evaluation=row)
        if self.on_evaluate is not None:
            self.on_evaluate(int(self.num_timesteps))
        return res


class ModelDirCheckpoint(BaseCallback):
    """Every ``save_freq`` env steps save a model directory ``<folder>/step_<N>/`` (resumable)."""

    def __init__(self, save_freq: int, folder: str | Path, config: Mapping[str, Any], verbose: int = 0, *,
                 provenance: Mapping[str, Any] | None = None, on_save: Callable[[int], None] | None = None) -> None:
        super().__init__(verbose)
        if save_freq < 1:
            raise ValueError(f"checkpoint_freq must be ≥ 1 env step, got {save_freq}")
        self.save_freq = int(save_freq)
        self.folder = Path(folder)
        self.config = dict(config)
        self.provenance = dict(provenance or {})
        self.on_save = on_save
        self._last = 0

    def _on_training_start(self) -> None:
        self._last = self.num_timesteps

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.save_freq:
            self._last = self.num_timesteps
            d = save_model_dir(self.model, self.folder / f"step_{self.num_timesteps}", self.config,
                               provenance=self.provenance)
            if self.on_save is not None:
                self.on_save(int(self.num_timesteps))
            if self.verbose:
                print(f"[checkpoint] {d}", flush=True)
        return True
