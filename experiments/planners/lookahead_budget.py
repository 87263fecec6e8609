"""lookahead budget/benefit: median steps, successes and decision time for four planner budgets vs min-var.

Runs every agent on the same seeded trials (the benchmark's per-(condition, trial) seeds,
:func:`electroloc_gym.bench.config.trial_seeds`, root seed ``--seed``) of ``--trials`` trials per
ElectroLoc-v0 condition (``--conditions``, default all eight presets) and ``--global-trials`` trials of
ElectroLocGlobal-v0 (§6.5's map, the Table-2 layout), with the benchmark's env settings (calibrated
sensor model, default signal, 2500 particles, 35-observation cap). So with ``--seed 0 --trials 50
--global-trials 50`` the trials are exactly those of ``electroloc bench`` (seed 0). Prints, per env and
agent: trials, successes, median steps (observations fused, the first reading included, as the paper
counts; capped trials count as the cap; the median over all trials of the env, not Table 4's median of
per-condition medians), mean steps and the median decision time; saves a figure of median and mean
steps against median decision time, and its numbers beside it (``FILE.json``; ``--replot FILE.json``
redraws the figure from them).

The budgets are the planner's own defaults with more or less search: greedy (``depth=1``), the default
(depth 2, open loop over the eight compass continuations, 8 futures), depth 2 closed loop (the second
move chosen after the first reading, 16 × 8 futures) and depth 3 open loop over all 64 compass
continuations with 16 futures. The default settings were chosen on validation seeds 101–104
(docs/baselines.md), not on the seeds of this sweep.

    python experiments/planners/lookahead_budget.py [--trials 8] [--global-trials 50] [--seed 0] [--conditions all]
        [--out FILE.png]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.bench.config import resolve_conditions, trial_seeds  # noqa: E402
from electroloc_gym.protocol import MAX_OBSERVATIONS, N_PARTICLES  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID, env_entry, task_entry  # noqa: E402

GLOBAL_ENV_ID = task_entry("global").env_id
GLOBAL_CONDITION = env_entry(GLOBAL_ENV_ID).map_condition
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import DEFAULT_SIGNAL, get_condition  # noqa: E402

#: min-var, then the planner at increasing budgets.
AGENTS = (
    MinVarianceAgent.name,
    f"{LookaheadAgent.name}[depth=1]",
    LookaheadAgent.name,
    f"{LookaheadAgent.name}[closed=True,branches=16]",
    f"{LookaheadAgent.name}[depth=3,continuations=64,branches=16]",
)


def run(
    env_id: str,
    conditions: tuple[str, ...],
    trials: int,
    seed: int,
    agents: tuple[str, ...],
    max_observations: int,
    n_particles: int,
) -> dict[str, dict[str, list[float]]]:
    """Per agent: steps, success flags and per-decision times (s) over every trial."""
    out = {a: {"steps": [], "success": [], "decision_s": []} for a in agents}
    built = {a: make_agent(a) for a in agents}
    total = len(conditions) * trials * len(agents)
    with tqdm(total=total, desc=env_id, unit="trial") as bar:
        for cond in conditions:
            kwargs = {"sensor_model": "calibrated", "n_particles": n_particles, "max_observations": max_observations}
            if env_entry(env_id).takes("condition"):
                kwargs["condition"] = get_condition(cond, DEFAULT_SIGNAL)
            env = gym.make(env_id, **kwargs)
            for k in range(trials):
                env_seed, agent_seed = trial_seeds(seed, cond, k)
                for a in agents:
                    ep = run_episode(env, built[a], env_seed, agent_seed=agent_seed)
                    out[a]["steps"].append(int(ep.info["n_observations"]))
                    out[a]["success"].append(bool(ep.terminated))
                    out[a]["decision_s"].extend(ep.decision_s)
                    bar.update(1)
            env.close()
    return out


def table(env_id: str, res: dict[str, dict[str, list[float]]]) -> list[str]:
    """Markdown rows of one env's results."""
    return markdown_table(
        ("env", "agent", "trials", "successes", "median steps", "mean steps", "median decision (ms)"),
        [
            (
                env_id,
                f"`{a}`",
                len(r["steps"]),
                sum(r["success"]),
                f"{np.median(r['steps']):.1f}",
                f"{np.mean(r['steps']):.2f}",
                f"{1000 * np.median(r['decision_s']):.1f}",
            )
            for a, r in res.items()
        ],
        align="llrrrrr",
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("--trials", type=int, default=8, help="trials per ElectroLoc-v0 condition (default 8; 0: skip)")
    p.add_argument("--global-trials", type=int, default=50, help="ElectroLocGlobal-v0 trials (default 50; 0: skip)")
    p.add_argument("--seed", type=int, default=0, help="root seed of the trial seeds (default 0, the benchmark's)")
    p.add_argument("--conditions", default="all", help="'all' or comma-separated ElectroLoc-v0 presets")
    p.add_argument("--n-particles", type=int, default=N_PARTICLES)
    p.add_argument("--max-observations", type=int, default=MAX_OBSERVATIONS)
    p.add_argument("--out", default="lookahead_budget.png", help="figure path (default lookahead_budget.png)")
    p.add_argument("--replot", metavar="JSON", help="only redraw the figure from a run's saved numbers")
    args = p.parse_args()
    numbers = None if args.replot else os.path.splitext(args.out)[0] + ".json"
    check_output_options(p, files={"--out": args.out, "--out (its .json)": numbers})
    if args.replot:
        with open(args.replot, encoding="utf-8") as f:
            plot(json.load(f), args.out)
        print(f"wrote: {args.out}", file=sys.stderr)
        return
    if args.trials < 0 or args.global_trials < 0 or args.trials + args.global_trials == 0:
        p.error("--trials and --global-trials must be ≥ 0, and one of them ≥ 1")
    try:
        conditions = tuple(resolve_conditions(args.conditions))
    except ValueError as exc:
        p.error(f"--conditions: {exc}")
    t0 = time.perf_counter()
    results = {}
    if args.global_trials:
        results[GLOBAL_ENV_ID] = run(
            GLOBAL_ENV_ID,
            (GLOBAL_CONDITION,),
            args.global_trials,
            args.seed,
            AGENTS,
            args.max_observations,
            args.n_particles,
        )
    if args.trials:
        results[PAPER_ENV_ID] = run(
            PAPER_ENV_ID, conditions, args.trials, args.seed, AGENTS, args.max_observations, args.n_particles
        )
    print(
        f"\nseed {args.seed}; {PAPER_ENV_ID}: {len(conditions)} conditions × {args.trials} trials; "
        f"{GLOBAL_ENV_ID}: {args.global_trials} trials; "
        f"{args.n_particles} particles, cap {args.max_observations}; {time.perf_counter() - t0:.0f} s\n"
    )
    lines = []
    for env_id, res in results.items():
        lines += table(env_id, res)[(0 if not lines else 2) :]
    print("\n".join(lines))

    summary = {
        "title": f"lookahead budgets, seed {args.seed}: {PAPER_ENV_ID} {len(conditions)} conditions × "
        f"{args.trials} trials, {GLOBAL_ENV_ID} {args.global_trials} trials",
        "envs": {env_id: summarise(res) for env_id, res in results.items()},
    }
    write_json(os.path.splitext(args.out)[0] + ".json", summary)
    plot(summary, args.out)
    print(f"wrote: {os.path.splitext(args.out)[0]}.json\nwrote: {args.out}", file=sys.stderr)


def summarise(res: dict[str, dict[str, list[float]]]) -> dict[str, dict[str, float]]:
    """Per agent: trials, successes, median and mean steps, median decision time (ms)."""
    return {
        a: {
            "trials": len(r["steps"]),
            "successes": int(sum(r["success"])),
            "median_steps": float(np.median(r["steps"])),
            "mean_steps": float(np.mean(r["steps"])),
            "decision_ms": float(1000 * np.median(r["decision_s"])),
        }
        for a, r in res.items()
    }


def write_json(path: str, obj: Any) -> None:
    """Write ``obj`` as JSON, temp-then-rename."""
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=1, ensure_ascii=False)
    os.replace(tmp, path)


def short_label(spec: str) -> str:
    """``lookahead[depth=3,continuations=64,branches=16]`` → ``depth 3, 64 cont., 16 futures``."""
    opts = spec.partition("[")[2].rstrip("]")
    if not opts:
        return "default"
    names = {"depth": "depth {}", "continuations": "{} cont.", "branches": "{} futures", "closed": "closed loop"}
    parts = []
    for item in opts.split(","):
        key, _, val = item.partition("=")
        parts.append(names.get(key, f"{key}={{}}").format(val) if key != "closed" else names["closed"])
    return ", ".join(parts)


def plot(summary: dict[str, Any], out: str) -> None:
    """Median and mean steps against median decision time, one line per env (min-var as a square)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharex=True)
    for ax, key, label in ((axes[0], "median_steps", "median"), (axes[1], "mean_steps", "mean")):
        for (env_id, res), colour in zip(summary["envs"].items(), ("C0", "C1")):
            agents = list(res)
            xs = [res[a]["decision_ms"] for a in agents]
            ys = [res[a][key] for a in agents]
            ax.plot(xs[1:], ys[1:], "o-", color=colour, label=f"lookahead, {env_id}")
            ax.plot(xs[:1], ys[:1], "s", ms=9, color=colour, mfc="none", label=f"min-var, {env_id}")
            for x, y, a in zip(xs[1:], ys[1:], agents[1:]):
                ax.annotate(
                    short_label(a),
                    (x, y),
                    fontsize=6.5,
                    rotation=20,
                    color=colour,
                    xytext=(4, 4 if colour == "C1" else -10),
                    textcoords="offset points",
                )
        ax.set_xscale("log")
        times = [r["decision_ms"] for res in summary["envs"].values() for r in res.values()]
        ax.set_xlim(min(times) / 2, max(times) * 8)  # room for the labels
        ax.set_xlabel("median decision time (ms, one core)")
        ax.set_ylabel(f"{label} readings to localise (first included)")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle(summary["title"], fontsize=9)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    tmp = out + ".tmp.png"
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, out)


if __name__ == "__main__":
    main()
