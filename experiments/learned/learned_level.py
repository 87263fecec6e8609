"""Env steps and wall time until a learned run first reaches min-var's level on its validation episodes.

Every rl-zoo3 run of the suite evaluates its policy on the same validation episodes (reset seeds 100000 and up,
``BenchEvalCallback``) and logs each evaluation in ``eval.csv``: env steps, the run's wall time at that
evaluation (``wall_time_s``, evaluations included) and the task's declared score (``mean_readings``; on the moving
target ``mean_tracking_error_mm``). Min-var is run once on the same episodes through the same evaluation function
(:func:`electroloc_gym.train.callbacks.evaluate_agent`), so its score is the level on the same footing; it is cached
in ``RESULTS/<env-id>/_baselines/validation/min-var.json`` (one entry per validation setting: env kwargs, first
seed, episodes), because on the moving target its 64 episodes of 70 readings take minutes.

Min-var's episodes use the run's validation env kwargs without ``observation`` and ``action_type``: they say
what a learned policy sees and does, while min-var reads the belief through the env's agent view and moves
continuously. A run that never scores at least as well as min-var is "not within the budget" (its last
evaluation's env steps); a log written before the task's score column existed has no entry ("no score column").
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the scores beside this script

from learned_scores import BASELINES_DIR, ReportError  # noqa: E402

LEVEL_AGENT = "min-var"
#: Where the level's evaluations are cached, under ``RESULTS/<env-id>/_baselines/``.
CACHE = Path("validation") / f"{LEVEL_AGENT}.json"
#: Env kwargs that describe the learned agent's interface, not the episodes (left out of min-var's).
AGENT_KWARGS = ("observation", "action_type")
NOT_REACHED = "not within the budget"


def first_reach(
    cols: Mapping[str, Sequence[float]], key: str, level: float, smaller_is_better: bool
) -> tuple[int, float | None] | None:
    """(env steps, wall time s or None when the log has no ``wall_time_s``) of the first evaluation whose ``key``
    is at least as good as ``level``; None when none is.
    """
    wall = cols.get("wall_time_s")
    for i, v in enumerate(cols[key]):
        if (v <= level) if smaller_is_better else (v >= level):
            return int(cols["timesteps"][i]), (None if wall is None else float(wall[i]))
    return None


def validation_settings(run: Path) -> tuple[str, dict[str, Any], int, int]:
    """(env id, min-var's env kwargs, first seed, episodes) of an rl-zoo3 run folder's validation episodes: its
    ``summary.json`` (written by the callback) and rl-zoo3's ``config.yml``/``args.yml`` (the env kwargs the run
    trained with: the command line's replace the file's, rl-zoo3's rule).

    Raises:
        ValueError: one line naming the file that is missing or unreadable.
    """
    from electroloc_gym.policy.sb3 import read_zoo_yaml
    from electroloc_gym.train.summary import read_summary

    summary = read_summary(run / "summary.json")  # one line naming the file and the field
    env_id, val = summary.env_id, summary.validation
    first, episodes, val_kwargs = val.first_seed, val.episodes, dict(val.env_kwargs)
    zoo = [d for d in run.iterdir() if d.is_dir() and (d / "config.yml").is_file()]
    if not zoo:
        raise ValueError(f"{run}: no rl-zoo3 config.yml (the run's env kwargs)")
    cfg = read_zoo_yaml(zoo[0] / "config.yml")
    args = read_zoo_yaml(zoo[0] / "args.yml") if (zoo[0] / "args.yml").is_file() else {}
    kwargs = {**dict(args.get("env_kwargs") or cfg.get("env_kwargs") or {}), **val_kwargs}
    return env_id, {k: v for k, v in kwargs.items() if k not in AGENT_KWARGS}, first, episodes


def level(
    baselines: Path,
    env_id: str,
    env_kwargs: Mapping[str, Any],
    first_seed: int,
    episodes: int,
    progress: Callable[[str], None] | None = None,
    compute: bool = True,
) -> dict[str, Any] | None:
    """Min-var's evaluation row on these validation episodes: from the cache in ``baselines`` (the env's
    ``_baselines`` folder), else (``compute``) run once through ``evaluate_agent`` and added to it (atomically),
    else None.
    """
    from electroloc_gym.utils.fileio import write_json_atomic

    path = baselines / CACHE
    key = {"env_id": env_id, "env_kwargs": json.loads(json.dumps(dict(env_kwargs))), "first_seed": first_seed}
    key["episodes"] = episodes
    entries: list[dict[str, Any]] = []
    if path.is_file():
        try:
            entries = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(entries, list):
                raise ValueError("not a list")
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            raise ValueError(f"{path}: not a readable cache of {LEVEL_AGENT}'s validation scores ({exc})") from None
    for e in entries:
        if isinstance(e, dict) and all(e.get(k) == v for k, v in key.items()) and isinstance(e.get("row"), dict):
            return e["row"]
    if not compute:
        return None
    from electroloc_gym.bench.agents import make_bench_agent
    from electroloc_gym.train.callbacks import evaluate_agent

    if progress is not None:
        progress(f"{env_id}: {LEVEL_AGENT} on {episodes} validation episodes (seeds {first_seed}…), once; cached")
    t = time.perf_counter()
    row = evaluate_agent(make_bench_agent(LEVEL_AGENT), env_id, env_kwargs, range(first_seed, first_seed + episodes))
    entries.append({**key, "agent": LEVEL_AGENT, "row": row, "wall_time_s": round(time.perf_counter() - t, 1)})
    write_json_atomic(path, entries)
    return row


def reach(
    results: Path, env_id: str, progress: Callable[[str], None] | None = None, compute: bool = True
) -> list[dict[str, Any]]:
    """Per learned label of ``results/<env-id>/`` (finished, benchmarked seeds, as the learning curves): min-var's
    validation score and, per seed, the env steps and wall time of the first evaluation at its level.

    Returns:
        ``[{"label", "score", "smaller_is_better", "level": {seed settings → min-var's score}, "seeds": [{"seed",
        "reached": bool | None, "note" (why None: the log has no score column, the run folder no validation
        settings, or min-var's level is not cached and not ``compute``d), "timesteps", "wall_time_s", "budget"}]}]``.

    Raises:
        ReportError: an unreadable eval.csv or training summary (one line naming the file).
    """
    from electroloc_gym.train.callbacks import score_column
    from electroloc_gym.train.curves import read_eval_csv

    key, smaller = score_column(env_id)
    out = []
    env_dir = results / env_id
    for label_dir in sorted(p for p in env_dir.iterdir() if p.is_dir() and p.name != BASELINES_DIR):
        seeds = []
        levels: list[float] = []
        for seed_dir in sorted(label_dir.glob("seed-*"), key=lambda p: (len(p.name), p.name)):
            found = sorted(seed_dir.glob("zoo/*/*/eval.csv"))
            if not found or not (seed_dir / "bench" / "summary.json").is_file():
                continue
            run = found[-1].parent
            try:
                cols = read_eval_csv(found[-1])
            except ValueError as exc:
                raise ReportError(str(exc)) from None
            entry: dict[str, Any] = {"seed": seed_dir.name.removeprefix("seed-"), "budget": int(cols["timesteps"][-1])}
            unknown = {**entry, "reached": None, "timesteps": None, "wall_time_s": None}
            if key not in cols:
                seeds.append({**unknown, "note": "no score column"})
                continue
            if not (run / "summary.json").is_file():
                seeds.append({**unknown, "note": "no summary.json (its validation settings)"})
                continue
            try:
                _, kwargs, first, episodes = validation_settings(run)
            except ValueError as exc:
                raise ReportError(str(exc)) from None
            row = level(env_dir / BASELINES_DIR, env_id, kwargs, first, episodes, progress, compute)
            if row is None:
                seeds.append({**unknown, "note": f"{LEVEL_AGENT}'s level not computed (--min-var-level)"})
                continue
            lv = float(row[key])
            levels.append(lv)
            hit = first_reach(cols, key, lv, smaller)
            seeds.append(
                {
                    **entry,
                    "reached": hit is not None,
                    "timesteps": None if hit is None else hit[0],
                    "wall_time_s": None if hit is None else hit[1],
                }
            )
        if seeds:
            out.append(
                {"label": label_dir.name, "score": key, "smaller_is_better": smaller, "levels": levels, "seeds": seeds}
            )
    return out


def reach_table(rows_by_env: Mapping[str, Sequence[Mapping[str, Any]]]) -> str:
    """The markdown section: per (env, label), min-var's validation score and each seed's steps and wall time to
    reach it (``NOT_REACHED`` where it never did).
    """
    from electroloc_gym.utils.markdown import markdown_table

    lines = []
    for env_id, rows in rows_by_env.items():
        for r in rows:
            levels = sorted(set(round(v, 3) for v in r["levels"]))
            steps, walls = [], []
            for s in r["seeds"]:
                if s["reached"] is None:
                    steps.append(f"seed {s['seed']}: {s['note']}")
                    walls.append(f"seed {s['seed']}: –")
                elif not s["reached"]:
                    steps.append(f"seed {s['seed']}: {NOT_REACHED} ({s['budget']:,})".replace(",", " "))
                    walls.append(f"seed {s['seed']}: {NOT_REACHED}")
                else:
                    steps.append(f"seed {s['seed']}: {s['timesteps']:,}".replace(",", " "))
                    w = s["wall_time_s"]
                    walls.append(f"seed {s['seed']}: " + ("–" if w is None else f"{w:.0f}"))
            reached = sum(1 for s in r["seeds"] if s["reached"])
            lines.append(
                (
                    env_id,
                    r["label"],
                    f"{r['score']} " + (" / ".join(f"{v:g}" for v in levels) if levels else "–"),
                    f"{reached} of {len(r['seeds'])}",
                    "; ".join(steps),
                    "; ".join(walls),
                )
            )
    if not lines:
        return ""
    head = (
        "env",
        "algorithm",
        f"{LEVEL_AGENT}'s validation score",
        "seeds reaching it",
        "env steps to reach it",
        "training wall time to reach it, s",
    )
    intro = (
        f"\nEnv steps and wall time until a run's validation score (its eval.csv, the checkpoint selection's "
        f"episodes) first equals or beats {LEVEL_AGENT}'s on the same episodes:\n"
    )
    return intro + "\n".join(["", *markdown_table(head, lines)]) + "\n"
