r"""Why EEDI's exploration does not pay with distractors here: the belief locks before exploration can act.

Runs agents with D distractors on the paper's eight conditions with the success test switched off
(``success_spread_mm`` tiny, so every episode runs to ``--budget`` readings) and records, per reading, the
belief's spread and its estimate's error. From these it reports, per agent:

* *first tight*: the reading at which √trace Σ first fell to ≤ 10 mm (where the benchmark's episode ends)
  and whether the estimate was then far (> 15 mm off: a far success in the benchmark);
* *far at the budget*: the estimate's error after all ``--budget`` readings: does continued exploration
  (ergodic or greedy) pull a wrong lock back to the target?

    python experiments/distractors/distractor_budget.py --agents infotaxis,eedi,lookahead --distractors 2 --seed 101 \
        --trials 3 --budget 15

Validation seeds only (the benchmark's trial seeds of ``--seed``; 101 here, never 0). One process, one
thread.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.baselines.eedi import EEDIAgent  # noqa: E402
from electroloc_gym.baselines.infotaxis import InfotaxisAgent  # noqa: E402
from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.protocol import FAR_ERROR_MM, SUCCESS_SPREAD_MM  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition  # noqa: E402


def trace(agent_name: str, condition: str, d: int, seed: int, trial: int, budget: int) -> dict:
    """One episode to ``budget`` readings: per reading (spread mm, error mm)."""
    env = gym.make(
        PAPER_ENV_ID,
        condition=get_condition(condition),
        distractors=d,
        max_observations=budget,
        success_spread_mm=1e-6,
    )
    agent = make_agent(agent_name)
    env_seed, agent_seed = trial_seeds(seed, condition, trial)
    steps: list[tuple[float, float]] = []
    run_episode(
        env,
        agent,
        env_seed,
        agent_seed=agent_seed,
        on_step=lambda info: steps.append((float(info["spread_mm"]), float(info["error_mm"]))),
    )
    return {"agent": agent_name, "condition": condition, "trial": trial, "distractors": d, "steps": steps}


def summarize(traces: list[dict]) -> list[dict]:
    """Per agent: first-tight reading and far fraction there, and the far fraction at the budget."""
    out = []
    for a in dict.fromkeys(t["agent"] for t in traces):
        ts = [t for t in traces if t["agent"] == a]
        first, far_first, far_end, recovered = [], 0, 0, 0
        for t in ts:
            s = np.array(t["steps"])
            tight = np.flatnonzero(s[:, 0] <= SUCCESS_SPREAD_MM)
            end_far = s[-1, 1] > FAR_ERROR_MM
            far_end += bool(end_far)
            if tight.size:
                k = int(tight[0])
                first.append(k + 1)
                if s[k, 1] > FAR_ERROR_MM:
                    far_first += 1
                    recovered += not end_far
        out.append(
            {
                "agent": a,
                "trials": len(ts),
                "tight": len(first),
                "first_tight_reading_median": float(np.median(first)) if first else None,
                "far_at_first_tight": far_first,
                "recovered_by_budget": recovered,
                "far_at_budget": far_end,
                "error_median_at_budget_mm": float(np.median([t["steps"][-1][1] for t in ts])),
            }
        )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--agents", default=",".join((InfotaxisAgent.name, EEDIAgent.name, LookaheadAgent.name)))
    p.add_argument("--distractors", type=int, default=2)
    p.add_argument("--seed", type=int, default=101)
    p.add_argument("--trials", type=int, default=3)
    p.add_argument("--budget", type=int, default=15)
    p.add_argument("--out", default=None, help="JSON of the traces and the summary")
    a = p.parse_args()
    check_output_options(p, files={"--out": a.out})
    traces = []
    for k in range(a.trials):
        print(f"distractor_budget: trial {k + 1} of {a.trials} ({time.strftime('%H:%M:%S')})", file=sys.stderr)
        traces += [
            trace(agent, c, a.distractors, a.seed, k, a.budget) for c in PRESET_NAMES for agent in a.agents.split(",")
        ]
    rows = summarize(traces)
    for line in markdown_table(
        (
            "agent",
            "trials",
            "tight within budget",
            "first tight (median reading)",
            "far when first tight",
            "of those, back within 15 mm at the budget",
            "far at the budget",
            "median error at the budget (mm)",
        ),
        [
            (
                r["agent"],
                r["trials"],
                r["tight"],
                r["first_tight_reading_median"],
                r["far_at_first_tight"],
                r["recovered_by_budget"],
                r["far_at_budget"],
                f"{r['error_median_at_budget_mm']:.1f}",
            )
            for r in rows
        ],
    ):
        print(line)
    if a.out:
        with open(a.out, "w", encoding="utf-8") as fh:
            json.dump({"args": vars(a), "summary": rows, "traces": traces}, fh)
        print(f"wrote: {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
