"""The datasets' seed protocol and reference scores: which episodes a dataset holds, and what 0 and 1 mean.

**Seeds.** The benchmark evaluates on the trial seeds of root seed 0
(:func:`electroloc_gym.bench.config.trial_seeds`: ``SeedSequence(0, spawn_key=(condition index, trial))``,
condition indices 0–7 the presets, 8 the global map). Training and validation use other seeds (the
learned suite's training seeds 1–5, the training callback's reset seeds 100000+, the tuning scripts'
validation seeds 101, 102). Dataset episode ``k`` of root seed ``s`` gets
``SeedSequence(s, spawn_key=(DATASET_STREAM, k))``: a stream index no benchmark trial uses, and a root
seed other than the evaluation seed 0 (refused), so no dataset episode is a benchmark trial;
:func:`evaluation_overlap` checks it against the evaluation seeds themselves.

**Reference scores.** Minari's normalised score is ``(return − ref_min_score) / (ref_max_score −
ref_min_score)``: 0 at rnd-wlk and 1 at the best non-learned planner on the benchmark's trials of the same env
(the learned suite's committed baseline run, ``<results>/<env-id>/_baselines/bench``), an agent's score the mean
over conditions of its per-condition means of the env task's declared score (``Task.metrics.score``, which the
reference block's ``score`` names; the learned table averages per-condition ratios instead). The task puts that
score on the return's scale (``Score.reference``; by default negated where lower is better). For the readings
R the learned table counts (a failure counted as the cap) it is ``1 − R``, an episode's return (reward −1 per
reading after the reset's first one), so ``ref_min_score = 1 − R_rnd`` and ``ref_max_score = 1 − R_best``.
For an error, e.g. the moving target's tracking error in mm, where every episode reads its cap and the readings
say nothing, they are ``−E_rnd`` and ``−E_best``, and an episode's score is −(the mean of its per-step
``error_mm`` info over the scored second half, ``n_observations`` above half the cap): the episode's value of
the declared score, not the return, which sums the error over every reading.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable
from typing import Any

import numpy as np

from electroloc_gym.baselines.agent import PLANNER_AGENTS, RANDOM_AGENT
from electroloc_gym.registry import PAPER_ENV_ID
from electroloc_gym.utils.fileio import user_path
from electroloc_gym.world.conditions import PRESET_NAMES

__all__ = [
    "DATASET_STREAM",
    "DEFAULT_DATASET_SEED",
    "EVALUATION_SEED",
    "episode_seeds",
    "evaluation_overlap",
    "reference_scores",
    "RND_AGENT",
    "PLANNERS",
]

#: The benchmark's evaluation root seed (``electroloc bench --seed 0``): never a dataset's.
EVALUATION_SEED = 0
#: The default root seed of dataset episodes (a training seed).
DEFAULT_DATASET_SEED = 1
#: The spawn-key stream of dataset episodes: after the presets (0–7) and the global map (8).
DATASET_STREAM = len(PRESET_NAMES) + 1
#: The agent that scores 0 (the registry's chance level).
RND_AGENT = RANDOM_AGENT
#: The non-learned planners whose best scores 1 (those a baseline run holds).
PLANNERS = PLANNER_AGENTS
#: Evaluation trials per condition checked for overlap (the bench's default is 50).
_CHECKED_TRIALS = 1000


def episode_seeds(root_seed: int, episode: int) -> tuple[int, int]:
    """(env reset seed, agent seed) of dataset episode ``episode`` under ``root_seed``."""
    ss = np.random.SeedSequence(int(root_seed), spawn_key=(DATASET_STREAM, int(episode)))
    env_seed, agent_seed = (int(v) for v in ss.generate_state(2, dtype=np.uint32))
    return env_seed, agent_seed


def evaluation_overlap(env_seeds: Iterable[int]) -> list[int]:
    """The seeds of ``env_seeds`` that are reset seeds of the benchmark's evaluation trials (root seed 0,
    every condition and the global map, the first 1000 trials of each) or of the training callback's
    validation episodes (100000–100063); empty for a valid dataset.
    """
    return sorted(set(int(s) for s in env_seeds) & _evaluation_seeds())


@functools.cache
def _evaluation_seeds() -> frozenset[int]:
    """The reset seeds :func:`evaluation_overlap` checks against (computed once per process)."""
    from electroloc_gym.bench.config import MAP_CONDITIONS, trial_seeds

    trials = {
        trial_seeds(EVALUATION_SEED, c, k)[0] for c in (*PRESET_NAMES, *MAP_CONDITIONS) for k in range(_CHECKED_TRIALS)
    }
    return frozenset(trials | set(range(100_000, 100_064)))


def _mean_over_conditions(rows: list[dict[str, Any]], value: Any) -> float:
    """Mean over conditions of the per-condition mean of ``value(record)``."""
    conditions = sorted({r["condition"] for r in rows})
    per = [np.mean([value(r) for r in rows if r["condition"] == c]) for c in conditions]
    return float(np.mean(per))


def reference_scores(bench_dir: str | os.PathLike[str], env_id: str) -> dict[str, Any]:
    """``{"ref_min_score", "ref_max_score", "score": KEY, "rnd_KEY", "best_planner", "best_KEY", "source"}`` from
    a benchmark run's ``trials.jsonl`` holding rnd-wlk and at least one planner on ``env_id``: KEY the env task's
    declared score (``Task.metrics.score``), the reference scores that score on its declared
    reference scale (``Score.on_reference_scale``; module docstring).

    Raises:
        ValueError: no such file, another env, rnd-wlk or every planner missing, or rnd-wlk not worse than the
            best planner by the env's score — one line.
    """
    from electroloc_gym.bench.records import TRIALS_FILE, read_trials, stored_trials
    from electroloc_gym.registry import env_entry

    path = user_path(bench_dir)
    path = stored_trials(path / TRIALS_FILE if path.is_dir() else path)  # a kept run's .gz where it is absent
    if not path.is_file():
        raise ValueError(
            f"reference must be a benchmark folder or trials.jsonl with rnd-wlk and a planner on "
            f"{env_id}; {str(path)!r} does not exist"
        )
    rows = [r for r in read_trials(path) if r.get("env_id", PAPER_ENV_ID) == env_id]  # records before env_id: its env
    agents = {r["agent"] for r in rows}
    planners = [p for p in PLANNERS if p in agents]
    if RND_AGENT not in agents or not planners:
        raise ValueError(
            f"reference {str(path)!r} must hold {RND_AGENT} and one of {list(PLANNERS)} on {env_id}; "
            f"it holds {sorted(agents)}"
        )
    declared = env_entry(env_id).task_class.metrics.score  # what ranks agents on the env, and its reference scale
    key, direction = declared.key, declared.better
    score = functools.partial(_mean_over_conditions, value=declared.of_record)
    rnd = score([r for r in rows if r["agent"] == RND_AGENT])
    scores = {p: score([r for r in rows if r["agent"] == p]) for p in planners}
    best = max(scores, key=lambda p: declared.on_reference_scale(scores[p]))
    if declared.on_reference_scale(scores[best]) <= declared.on_reference_scale(rnd):
        raise ValueError(
            f"reference {str(path)!r}: rnd-wlk is not worse than the best planner by the env's own score, the "
            f"mean {key} ({RND_AGENT} {rnd:.4g}, {best} {scores[best]:.4g}; {direction} is better); no score scale"
        )
    return {
        "ref_min_score": declared.on_reference_scale(rnd),
        "ref_max_score": declared.on_reference_scale(scores[best]),
        "score": key,
        f"rnd_{key}": rnd,
        "best_planner": best,
        f"best_{key}": scores[best],
        "source": str(path),
    }
