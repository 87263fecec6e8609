"""lookahead budget/benefit: median steps, successes and decision time for a few planner budgets vs min-var.

Runs every agent on the same seeded trials (the benchmark's per-(condition, trial) seeds,
:func:`electroloc_gym.bench.config.trial_seeds`, root seed ``--seed``, a validation seed: never the
reporting seed 0) of ``--conditions`` in ElectroLoc-v0 and ``--global-trials`` trials of
ElectroLocGlobal-v0 (§6.5's map), with the benchmark's env settings (calibrated sensor model, default
signal, 2500 particles, 35-observation cap). Prints, per env and agent: trials, successes, median
steps (observations fused, the first reading included, as the paper counts; capped trials count as
the cap) and the median decision time; saves a figure of median steps vs median decision time.

This is a small-sample budget sweep, not the full benchmark protocol (8 conditions × 50 trials, seed 0,
``electroloc bench``).

    python benchmarks/lookahead_budget.py [--trials 8] [--global-trials 8] [--seed 101] [--out FILE.png]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.bench.config import GLOBAL_CONDITION, GLOBAL_ENV_ID, trial_seeds  # noqa: E402
from electroloc_gym.bench.rollout import run_episode  # noqa: E402
from electroloc_gym.conditions import DEFAULT_SIGNAL, get_condition  # noqa: E402

#: min-var, then the planner at increasing budgets.
AGENTS = (
    "min-var",
    "lookahead[depth=1,branches=8]",
    "lookahead[depth=2,continuations=4,branches=8]",
    "lookahead[depth=3,continuations=4,branches=8]",
    "lookahead[depth=3,continuations=8,branches=16,n_particles=500,rounds=2]",
)
CONDITIONS = ("fresh-steel-12.7", "fresh-delrin-12.7", "salt-steel-12.7", "salt-delrin-12.7")


def run(env_id: str, conditions: tuple[str, ...], trials: int, seed: int, agents: tuple[str, ...],
        max_observations: int, n_particles: int) -> dict[str, dict[str, list[float]]]:
    """Per agent: steps, success flags and per-decision times (s) over every trial."""
    out = {a: {"steps": [], "success": [], "decision_s": []} for a in agents}
    built = {a: make_agent(a) for a in agents}
    total = len(conditions) * trials * len(agents)
    with tqdm(total=total, desc=env_id, unit="trial") as bar:
        for cond in conditions:
            kwargs = {"sensor_model": "calibrated", "n_particles": n_particles, "max_observations": max_observations}
            if env_id != GLOBAL_ENV_ID:
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
    rows = ["| env | agent | trials | successes | median steps | median decision (ms) |",
            "|---|---|---:|---:|---:|---:|"]
    for a, r in res.items():
        rows.append(f"| {env_id} | `{a}` | {len(r['steps'])} | {sum(r['success'])} | "
                    f"{np.median(r['steps']):.1f} | {1000 * np.median(r['decision_s']):.1f} |")
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    p.add_argument("--trials", type=int, default=8, help="trials per ElectroLoc-v0 condition (default 8)")
    p.add_argument("--global-trials", type=int, default=8, help="ElectroLocGlobal-v0 trials (default 8; 0: skip)")
    p.add_argument("--seed", type=int, default=101, help="root seed of the trial seeds (default 101)")
    p.add_argument("--n-particles", type=int, default=2500)
    p.add_argument("--max-observations", type=int, default=35)
    p.add_argument("--out", default="lookahead_budget.png", help="figure path (default lookahead_budget.png)")
    args = p.parse_args()
    if args.trials < 1 or args.global_trials < 0:
        p.error("--trials must be ≥ 1 and --global-trials ≥ 0")
    t0 = time.perf_counter()
    results = {"ElectroLoc-v0": run("ElectroLoc-v0", CONDITIONS, args.trials, args.seed, AGENTS,
                                    args.max_observations, args.n_particles)}
    if args.global_trials:
        results[GLOBAL_ENV_ID] = run(GLOBAL_ENV_ID, (GLOBAL_CONDITION,), args.global_trials, args.seed, AGENTS,
                                     args.max_observations, args.n_particles)
    print(f"\nseed {args.seed}; ElectroLoc-v0: {len(CONDITIONS)} conditions × {args.trials} trials "
          f"({', '.join(CONDITIONS)}); {GLOBAL_ENV_ID}: {args.global_trials} trials; "
          f"{args.n_particles} particles, cap {args.max_observations}; {time.perf_counter() - t0:.0f} s\n")
    lines = []
    for env_id, res in results.items():
        lines += table(env_id, res)[(0 if not lines else 2):]
    print("\n".join(lines))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for env_id, res in results.items():
        xs = [1000 * np.median(r["decision_s"]) for r in res.values()]
        ys = [np.median(r["steps"]) for r in res.values()]
        ax.plot(xs[1:], ys[1:], "o-", label=f"lookahead, {env_id}")
        ax.plot(xs[:1], ys[:1], "s", ms=9, label=f"min-var, {env_id}")
    ax.set_xscale("log")
    ax.set_xlabel("median decision time (ms, one core)")
    ax.set_ylabel("median steps to localize")
    ax.set_title(f"lookahead budgets (seed {args.seed}, small sample)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    tmp = args.out + ".tmp.png"
    fig.savefig(tmp, dpi=120)
    os.replace(tmp, args.out)
    print(f"\nfigure: {args.out}")


if __name__ == "__main__":
    main()
