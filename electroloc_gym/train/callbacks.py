"""The evaluation callback of every rl-zoo3 run: the benchmark's metrics on validation episodes.

rl-zoo3's own ``EvalCallback`` scores a checkpoint by its mean return. :class:`BenchEvalCallback`
(named under ``callback:`` in every file of ``electroloc_gym/train/hyperparams/``) also runs the *current* policy
the way the benchmark runs a policy — exported in memory to the pickle-free format, loaded as the
benchmark's agent (:mod:`electroloc_gym.policy`), one seeded episode per validation seed through
:func:`electroloc_gym.baselines.rollout.run_episode` — and records what the benchmark reports:
successes, readings to localise (``info["n_observations"]``; a failure counts as the cap) and the
final error, plus the task's own (unshaped) return and the task's own metrics (the columns its
``Task.metrics.eval_columns`` declares). It also switches on the reward
shaping of the training env (:func:`electroloc_gym.train.wrappers.activate_shaping`).

In the run folder rl-zoo3 made (``logs/<algo>/<env>_<n>/``, found from the training monitor's file)
it writes, each atomically: ``eval.csv`` (one row per evaluation: :data:`EVAL_FIELDS`, then the task's
own columns), ``best/`` (the pickle-free export of the checkpoint with the best mean validation score —
the task's declared score, ``Task.metrics.score``: the fewest mean readings, the lowest mean tracking error
on the moving target — the checkpoint the export ships) and ``summary.json`` (wall time, fps, the chosen
row). The run folder is locked while
the run writes, and a folder that already holds another run's ``eval.csv`` is refused.

Why not SB3's ``EvalCallback`` (with ``callback_after_eval``): it scores a policy by the mean return of
``evaluate_policy`` on a vector env it resets once, so its episodes are not the seeded, one-reset-per-seed
episodes of the benchmark, and it counts ``eval_freq`` in callback calls (env steps / n_envs), not env
steps; its best model is a pickled SB3 zip chosen by return. What this callback needs — the exported
policy run through :func:`~electroloc_gym.baselines.rollout.run_episode` as the benchmark runs it, chosen by
readings — is none of that, so it is a ``BaseCallback``. Its metrics go through SB3's logger
(``bench_eval/*``, so rl-zoo3's stdout, CSV and TensorBoard outputs carry them); ``eval.csv`` is the
per-evaluation table the learned report and ``--resume`` read, written atomically.
"""

from __future__ import annotations

import csv
import io
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper, VecFrameStack, VecMonitor

from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.policy.format import write_export
from electroloc_gym.policy.load import agent_from_model
from electroloc_gym.policy.sb3 import export_meta, model_weights
from electroloc_gym.train.native_vec import NativeVecEnv
from electroloc_gym.train.summary import TrainSummary, Validation, write_summary
from electroloc_gym.train.wrappers import activate_shaping
from electroloc_gym.utils.fileio import FolderLock, atomic_write_text

__all__ = ["BenchEvalCallback", "EVAL_FIELDS", "evaluate_agent", "eval_fields", "score_column"]

EVAL_FIELDS = (
    "timesteps",
    "wall_time_s",
    "episodes",
    "success_rate",
    "mean_readings",
    "median_readings",
    "median_error_mm",
    "mean_error_mm",
    "mean_return",
)


def _metrics(env_id: str) -> Any:
    from electroloc_gym.registry import env_entry

    return env_entry(env_id).task_class.metrics


def eval_fields(env_id: str) -> tuple[str, ...]:
    """The columns of ``env_id``'s ``eval.csv``: :data:`EVAL_FIELDS`, then its task's own (``eval_columns``)."""
    return EVAL_FIELDS + tuple(k for k in _metrics(env_id).eval_columns if k not in EVAL_FIELDS)


def score_column(env_id: str) -> tuple[str, bool]:
    """(column, smaller is better) of ``env_id``'s validation score: ``mean_<key>`` of its task's declared score
    (``Task.metrics.score``; ``mean_readings`` by default).
    """
    score = _metrics(env_id).score
    return f"mean_{score.key}", score.better == "lower"


#: First reset seed of the validation episodes (the benchmark's trials are drawn from seed 0's stream).
VALIDATION_SEED = 100_000


def evaluate_agent(agent: Any, env_id: str, env_kwargs: Mapping[str, Any], seeds: Sequence[int]) -> dict[str, float]:
    """One deterministic benchmark episode per seed; the aggregate row (readings = ``n_observations``), then the
    task's own columns (``Task.metrics.eval_columns``, from the episodes' final infos).
    """
    env = gym.wrappers.RecordEpisodeStatistics(gym.make(env_id, **{**dict(env_kwargs), **agent.env_kwargs}))
    readings, errors, success, returns, infos = [], [], [], [], []
    try:
        for s in seeds:
            ep = run_episode(env, agent, int(s), deterministic=True)
            infos.append(ep.info)
            readings.append(int(ep.info["n_observations"]))
            errors.append(float(ep.info["error_mm"]))
            success.append(bool(ep.info["success"]))
            returns.append(float(ep.info["episode"]["r"]))
    finally:
        env.close()
    r, e = np.asarray(readings, float), np.asarray(errors, float)
    return {
        "episodes": len(r),
        "success_rate": float(np.mean(success)),
        "mean_readings": float(r.mean()),
        "median_readings": float(np.median(r)),
        "median_error_mm": float(np.median(e)),
        "mean_error_mm": float(e.mean()),
        "mean_return": float(np.mean(returns)),
        **{k: float(f(infos)) for k, f in _metrics(env_id).eval_columns.items()},
    }


def _zoo_argv() -> list[str]:
    """This process's ``rl_zoo3.train`` arguments as run from a shell (``-m rl_zoo3.train …``)."""
    return ["-m", "rl_zoo3.train", *sys.argv[1:]]


def _chain(venv: VecEnv) -> list[VecEnv]:
    out = [venv]
    while isinstance(out[-1], VecEnvWrapper):
        out.append(out[-1].venv)
    return out


def env_of(venv: VecEnv) -> tuple[str, dict[str, Any], int, Path | None]:
    """(env id, env kwargs, frames stacked, run folder) of an rl-zoo3 training env."""
    chain = _chain(venv)
    stack = next((w.stacked_obs.n_stack for w in chain if isinstance(w, VecFrameStack)), 1)
    base = chain[-1]
    monitor_file = None
    mon = next((w for w in chain if isinstance(w, VecMonitor)), None)
    if isinstance(base, NativeVecEnv):
        if base.env_id is None:
            raise ValueError("BenchEvalCallback needs a NativeVecEnv built by make_native_vec_env (it has no env id)")
        env_id, kwargs = base.env_id, dict(base.env_kwargs)
        writer = getattr(mon, "results_writer", None)
    elif isinstance(base, DummyVecEnv):
        spec = base.envs[0].unwrapped.spec
        if spec is None:
            raise ValueError("BenchEvalCallback needs envs made with gym.make (the DummyVecEnv's env has no spec)")
        env_id, kwargs = spec.id, dict(spec.kwargs)
        m = base.envs[0]
        while not isinstance(m, Monitor) and isinstance(m, gym.Wrapper):
            m = m.env
        writer = getattr(m, "results_writer", None)
    else:
        raise ValueError(f"BenchEvalCallback needs a NativeVecEnv or DummyVecEnv, got {type(base).__name__}")
    if writer is not None:
        monitor_file = writer.file_handler.name
    kwargs.pop("render_mode", None)
    return env_id, kwargs, int(stack), None if monitor_file is None else Path(monitor_file).parent


class BenchEvalCallback(BaseCallback):
    """Every ``eval_freq`` env steps: the benchmark's metrics on ``n_episodes`` validation episodes.

    Args:
        eval_freq: env steps between evaluations (≥ 1); also one at the start and one at the end.
        n_episodes: validation episodes (reset seeds ``seed``, ``seed + 1``, …; ≥ 1).
        seed: first validation reset seed (keep it away from the benchmark's seed-0 trials).
        env_kwargs: evaluation env kwargs on top of the training env's (e.g. ``randomize_target: false``).
        select: what makes a checkpoint the best: ``"score"`` (default: the task's declared score,
            ``Task.metrics.score``, e.g. the fewest mean readings to localise, the lowest mean tracking error
            on the moving target; :func:`score_column`), ``"mean_readings"`` or ``"mean_return"`` (highest
            validation return, unshaped). Ties: the later.
        verbose: 1 prints one line per evaluation.
    """

    #: The selection rules besides ``"score"`` (the task's): the row's key and whether a smaller value is better.
    SELECT: Mapping[str, bool] = {"score": True, "mean_readings": True, "mean_return": False}
    #: What each rule is, as the run's summary and the export's provenance say it (``"score"``: the task's words).
    CHOSEN_BY: Mapping[str, str] = {
        "mean_readings": "fewest mean readings to localise (failures count as the cap) on the validation episodes",
        "mean_return": "highest mean return (unshaped) on the validation episodes",
    }

    def __init__(
        self,
        eval_freq: int = 50_000,
        n_episodes: int = 64,
        seed: int = VALIDATION_SEED,
        env_kwargs: Mapping[str, Any] | None = None,
        select: str = "score",
        verbose: int = 1,
    ) -> None:
        super().__init__(verbose)
        if select not in self.SELECT:
            raise ValueError(f"BenchEvalCallback select must be one of {list(self.SELECT)}, got {select!r}")
        self.select = select
        for name, v in (("eval_freq", eval_freq), ("n_episodes", n_episodes)):
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"BenchEvalCallback {name} must be an integer ≥ 1, got {v!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"BenchEvalCallback seed must be an integer ≥ 0, got {seed!r}")
        self.eval_freq, self.n_episodes, self.seed = eval_freq, n_episodes, seed
        self.eval_env_kwargs = dict(env_kwargs or {})
        self.history: list[dict[str, float]] = []
        self.best: dict[str, float] | None = None
        self.run_dir: Path | None = None
        self._lock: FolderLock | None = None
        self._last = 0
        self._t0 = 0.0
        self._eval_s = 0.0

    # ---- SB3 hooks ----------------------------------------------------------------------------
    def _on_training_start(self) -> None:
        n = activate_shaping(self.training_env)
        self.env_id, self.env_kwargs, self.frame_stack, self.run_dir = env_of(self.training_env)
        self.fields = eval_fields(self.env_id)
        if self.select == "score":
            self.select_key, self.smaller = score_column(self.env_id)
            self.chosen_by = f"{_metrics(self.env_id).score.best} on the validation episodes"
        else:
            self.select_key, self.smaller = self.select, self.SELECT[self.select]
            self.chosen_by = self.CHOSEN_BY[self.select]
        if self.verbose:
            print(
                f"[bench-eval] {self.env_id}: reward shaping {'on' if n else 'absent'}; evaluating every "
                f"{self.eval_freq} steps on {self.n_episodes} validation episodes (seeds {self.seed}…)",
                flush=True,
            )
        if self.run_dir is not None:
            self._lock = FolderLock(
                self.run_dir, ".bench_eval.lock", f"another training run writes into {self.run_dir}"
            ).acquire()
            if (self.run_dir / "eval.csv").exists():
                self._lock.release()
                raise ValueError(
                    f"run folder {self.run_dir} already holds another run's eval.csv; "
                    f"rl-zoo3 gives every run a fresh folder — start a new run"
                )
        self._t0 = time.perf_counter()
        self._last = self.num_timesteps
        self.evaluate()

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.eval_freq:
            self._last = self.num_timesteps
            self.evaluate()
        return True

    def _on_training_end(self) -> None:
        try:
            if self.num_timesteps != self._last:
                self._last = self.num_timesteps
                self.evaluate()
            self._write_summary(finished=self.num_timesteps >= getattr(self.model, "_total_timesteps", 0))
        finally:
            if self._lock is not None:
                self._lock.release()

    # ---- evaluation ---------------------------------------------------------------------------
    def _meta(self, row: Mapping[str, Any] | None) -> dict[str, Any]:
        return export_meta(
            self.model,
            env_id=self.env_id,
            env_kwargs=self.env_kwargs,
            frame_stack=self.frame_stack,
            vecnormalize=self.model.get_vec_normalize_env(),
            evaluation=row,
            provenance={
                "command": shlex.join(["python", *_zoo_argv()]),
                "seed": self.model.seed,
                "timesteps": int(self.num_timesteps),
                "run": str(self.run_dir),
            },
        )

    def evaluate(self) -> dict[str, float]:
        """Evaluate the current policy now; log, write eval.csv, export it to ``best/`` if it is the best."""
        t = time.perf_counter()
        agent = agent_from_model(self.model, self._meta(None))
        seeds = range(self.seed, self.seed + self.n_episodes)
        res = evaluate_agent(agent, self.env_id, {**self.env_kwargs, **self.eval_env_kwargs}, seeds)
        self._eval_s += time.perf_counter() - t
        row = {"timesteps": int(self.num_timesteps), "wall_time_s": round(time.perf_counter() - self._t0, 1), **res}
        self.history.append(row)
        own = self.fields[len(EVAL_FIELDS) :]  # the task's own columns
        for k in ("success_rate", "mean_readings", "median_readings", "median_error_mm", "mean_return", *own):
            self.logger.record(f"bench_eval/{k}", row[k])
        if self.verbose:
            metrics = (
                "  ".join(f"{k} {res[k]:.4g}" for k in own)
                if own
                else f"success {res['success_rate']:6.1%}  readings mean {res['mean_readings']:5.2f} median "
                f"{res['median_readings']:4.1f}"
            )
            print(
                f"[bench-eval] t={row['timesteps']:>8d}  {metrics}  error median "
                f"{res['median_error_mm']:4.1f} mm  return {res['mean_return']:6.2f} (unshaped)  "
                f"({row['wall_time_s']:.0f} s)",
                flush=True,
            )
        key, smaller = self.select_key, self.smaller
        new_best = self.best is None or (  # ties: the later checkpoint
            res[key] <= self.best[key] if smaller else res[key] >= self.best[key]
        )
        if new_best:
            self.best = row
        if self.run_dir is not None:
            buf = io.StringIO()
            w = csv.writer(buf)
            w.writerow(self.fields)
            w.writerows([[r[k] for k in self.fields] for r in self.history])
            atomic_write_text(self.run_dir / "eval.csv", buf.getvalue())
            if new_best:
                write_export(self.run_dir / "best", self._meta(row), model_weights(self.model))
            self._write_summary(finished=False)
        return res

    def _write_summary(self, finished: bool) -> None:
        if self.run_dir is None:
            return
        wall = time.perf_counter() - self._t0
        steps = int(self.num_timesteps)
        write_summary(
            self.run_dir / "summary.json",
            TrainSummary(
                env_id=self.env_id,
                algo=type(self.model).__name__.lower(),
                seed=self.model.seed,
                command=shlex.join(["python", *_zoo_argv()]),
                argv=_zoo_argv(),
                finished=finished,
                timesteps=steps,
                wall_time_s=round(wall, 3),
                evaluation_time_s=round(self._eval_s, 3),
                fps_with_evaluation=round(steps / wall, 1) if wall > 0 else None,
                fps_training_only=round(steps / (wall - self._eval_s), 1) if wall > self._eval_s else None,
                validation=Validation(episodes=self.n_episodes, first_seed=self.seed, env_kwargs=self.eval_env_kwargs),
                chosen_by=self.chosen_by,
                best=self.best,
                evaluations=len(self.history),
            ),
        )
