r"""Compare agents (baselines and learned policies) on the same seeded trials of the 8 paper conditions.

A small stand-in for ``electroloc bench`` (which it does not replace): every agent runs the same
trials — condition ``c``, trial ``t`` resets the env with a seed drawn from
``SeedSequence(0, spawn_key=(c, t))`` — with the paper's fixed target, and the time of every
``predict`` call is recorded (the decision cost).

Usage::

    python -m train.evaluate --agents rnd-wlk,min-var,models/ppo-belief --trials 20 --workers 2 \
        --out /work/notes/eval_learned
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["trial_seed", "run_trials", "summarise", "main"]


def trial_seed(condition_index: int, trial: int, root: int = 0) -> int:
    """Reset seed of (condition, trial): ``SeedSequence(root, spawn_key=(c, t))`` → one 32-bit word."""
    return int(np.random.SeedSequence(root, spawn_key=(condition_index, trial)).generate_state(1)[0])


def run_trials(spec: str, condition: str, condition_index: int, trials: int, root: int = 0) -> list[dict[str, Any]]:
    """Run ``trials`` episodes of agent ``spec`` on ``condition``; one dict per trial."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import gymnasium as gym

    import electroloc_gym  # noqa: F401
    from baselines.agent import make_agent

    agent = make_agent(spec, seed=root)
    env = gym.make("ElectroLoc-v0", condition=condition, **getattr(agent, "env_kwargs", {}))
    rows = []
    for t in range(trials):
        seed = trial_seed(condition_index, t, root)
        if hasattr(agent, "seed"):
            agent.seed(seed)
        obs, info = env.reset(seed=seed)
        agent.reset(env)
        times: list[float] = []
        done = False
        while not done:
            t0 = time.perf_counter()
            action, _ = agent.predict(obs, deterministic=True)
            times.append(time.perf_counter() - t0)
            obs, _, term, trunc, info = env.step(action)
            done = term or trunc
        rows.append({"agent": spec, "condition": condition, "trial": t, "seed": seed,
                     "success": bool(info["success"]), "steps": int(info["n_observations"]),
                     "error_mm": float(info["error_mm"]), "decision_ms": 1e3 * float(np.median(times))})
    env.close()
    return rows


def summarise(rows: Sequence[dict[str, Any]]) -> dict[str, float]:
    """Successes, failures, error and steps (median over all trials and over successes), decision ms."""
    ok = np.array([r["success"] for r in rows], bool)
    steps = np.array([r["steps"] for r in rows], float)
    err = np.array([r["error_mm"] for r in rows], float)
    return {
        "trials": len(rows), "successes": int(ok.sum()), "failures": int((~ok).sum()),
        "median_error_mm": float(np.median(err)), "mean_error_mm": float(err.mean()),
        "median_steps": float(np.median(steps)), "mean_steps": float(steps.mean()),
        "median_steps_success": float(np.median(steps[ok])) if ok.any() else float("nan"),
        "mean_steps_success": float(steps[ok].mean()) if ok.any() else float("nan"),
        "decision_ms": float(np.median([r["decision_ms"] for r in rows])),
    }


def _table(rows: list[dict[str, Any]], agents: list[str], conditions: list[str]) -> str:
    hdr = ("| condition | agent | succ. | fail | median err mm | median steps (all) | median steps (succ.) "
           "| mean steps (succ.) | decision ms |")
    lines = [hdr, "|" + "---|" * 9]
    for cond in conditions + ["all"]:
        for a in agents:
            sel = [r for r in rows if r["agent"] == a and (cond == "all" or r["condition"] == cond)]
            s = summarise(sel)
            lines.append(f"| {cond} | {a} | {s['successes']} | {s['failures']} | {s['median_error_mm']:.2f} | "
                         f"{s['median_steps']:.1f} | {s['median_steps_success']:.1f} | "
                         f"{s['mean_steps_success']:.2f} | {s['decision_ms']:.3f} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point."""
    from electroloc_gym.conditions import PRESET_NAMES

    p = argparse.ArgumentParser(prog="python -m train.evaluate", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--agents", default="rnd-wlk,min-var", help="comma-separated agent specs / model paths")
    p.add_argument("--trials", type=int, default=20, help="trials per condition and agent")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--root-seed", type=int, default=0)
    p.add_argument("--out", default=None, help="folder for rows.json and table.md")
    a = p.parse_args(argv)
    if a.trials < 1 or a.workers < 1:
        print("error: --trials and --workers must be ≥ 1", file=sys.stderr)
        return 2
    agents = [s.strip() for s in a.agents.split(",") if s.strip()]
    conditions = list(PRESET_NAMES)
    jobs = [(s, c, i, a.trials, a.root_seed) for s in agents for i, c in enumerate(conditions)]
    rows: list[dict[str, Any]] = []
    from tqdm import tqdm

    with ProcessPoolExecutor(a.workers) as pool:
        futures = [pool.submit(run_trials, *j) for j in jobs]
        for f in tqdm(futures, desc="agent×condition", file=sys.stderr):
            rows.extend(f.result())
    table = _table(rows, agents, conditions)
    print(table)
    if a.out:
        from train.callbacks import atomic_write_text

        out = Path(a.out)
        atomic_write_text(out / "rows.json", json.dumps(rows, indent=1) + "\n")
        atomic_write_text(out / "table.md", table + "\n")
        atomic_write_text(out / "summary.json", json.dumps(
            {ag: summarise([r for r in rows if r["agent"] == ag]) for ag in agents}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
