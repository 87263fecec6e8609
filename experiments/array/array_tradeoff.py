r"""The trade of motion for sensing (§7), measured: readings, motions and snapshots to localise against the array's K.

For every layout (K = 1 ``single``, K = 2 ``ring-2`` — pairs 1 and 6 of ``ring-8``, mirrored about the emitter
axis —, K = 4 ``grid-2x2`` — the paper's "four stationary sensor pairs" —, K = 8 ``ring-8``), every agent
(``rnd-wlk``, ``min-var``, ``lookahead``) on the moving carriage, and the **stationary** array
(``fixed_carriage=True``: the carriage stays at its start, every step one more snapshot of K readings), and any
learned policy named with ``--agents`` (a shipped model or a policy folder, run only on the layout it was trained
with: ``ppo-belief-grid-2x2``), on the paper's eight conditions: the trials of ``electroloc bench`` (its seeds,
:func:`electroloc_gym.bench.config.trial_seeds`; ElectroLoc-v0 with the calibrated model, 2500 particles, the
35-snapshot cap, the 10 mm success spread). Per
trial: success (√trace Σ ≤ 10 mm within the cap), error (mm), snapshots (``n_observations``: readings per
pair), readings (K × snapshots) and motions (steps in which the carriage moved).

``run`` appends one JSON line per trial to ``--out`` (trial-major: every cell gets trial t before any gets t + 1,
so a run stopped early still has the same trials in every cell; ``--resume`` skips the trials already there);
``report`` writes the table (markdown) and the figure of motions to localise against K.

    python experiments/array/array_tradeoff.py run --trials 50 --out array_tradeoff.jsonl
    python experiments/array/array_tradeoff.py run --trials 50 --layouts grid-2x2 --agents ppo-belief-grid-2x2 \
        --out array_tradeoff.jsonl --resume
    python experiments/array/array_tradeoff.py report array_tradeoff.jsonl --table docs/array_tradeoff.md \
        --figure docs/array_tradeoff.png
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

import electroloc_gym  # noqa: E402, F401
from electroloc_gym.baselines import make_agent  # noqa: E402
from electroloc_gym.baselines.agent import RANDOM_AGENT  # noqa: E402
from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.bench.agents import bench_env_kwargs, make_bench_agent  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition  # noqa: E402
from electroloc_gym.world.sensor_array import SensorLayout, named_layout  # noqa: E402

AGENTS = (RANDOM_AGENT, MinVarianceAgent.name, LookaheadAgent.name)
STATIONARY = "stationary"
LAYOUTS = ("single", "ring-2", "grid-2x2", "ring-8")


def layout_of(name: str) -> str | SensorLayout:
    """A layout argument of ElectroLoc-v0: a named layout, or ``"ring-2"`` (pairs 1 and 6 of ``ring-8``)."""
    if name == "ring-2":
        return SensorLayout(named_layout("ring-8").electrodes[[1, 6]], name="ring-2")
    return name


def run_trial(layout: str, agent_name: str, condition: str, trial: int, seed: int) -> dict:
    """One trial (module docstring) as a JSON-able record."""
    env_seed, agent_seed = trial_seeds(seed, condition, trial)
    fixed = agent_name == STATIONARY
    if fixed or agent_name in AGENTS:
        agent = make_agent(RANDOM_AGENT if fixed else agent_name, seed=agent_seed)
        kwargs = {}
    else:  # a learned policy: its own observation mode, the bench's settings (bench_env_kwargs)
        agent = make_bench_agent(agent_name, seed=agent_seed)
        kwargs = bench_env_kwargs(PAPER_ENV_ID, agent, None)
    env = gym.make(
        PAPER_ENV_ID,
        **kwargs,
        condition=get_condition(condition),
        sensor_layout=layout_of(layout),
        fixed_carriage=fixed,
    )
    positions: list[tuple[float, float]] = []
    t0 = time.perf_counter()
    ep = run_episode(
        env, agent, env_seed, agent_seed=agent_seed, on_step=lambda info: positions.append(tuple(info["position_mm"]))
    )
    k = env.unwrapped.sensor_layout.n_pairs
    moved = np.any(np.diff(np.asarray(positions), axis=0) != 0.0, axis=1)
    env.close()
    snapshots = int(ep.info["n_observations"])
    return {
        "layout": layout,
        "K": k,
        "agent": agent_name,
        "condition": condition,
        "trial": trial,
        "seed": env_seed,
        "success": bool(ep.terminated),
        "error_mm": float(ep.info["error_mm"]),
        "snapshots": snapshots,
        "readings": snapshots * k,
        "motions": int(moved.sum()),
        "wall_s": time.perf_counter() - t0,
    }


def run(args: argparse.Namespace) -> None:
    done = set()
    if args.resume and os.path.exists(args.out):
        with open(args.out, encoding="utf-8") as f:
            done = {(r["layout"], r["agent"], r["condition"], r["trial"]) for r in map(json.loads, f)}
    cells = [(lay, ag, c) for lay in args.layouts for ag in args.agents for c in PRESET_NAMES]
    with open(args.out, "a", encoding="utf-8") as f:
        for t in range(args.trials):
            for lay, ag, c in cells:
                if (lay, ag, c, t) in done:
                    continue
                rec = run_trial(lay, ag, c, t, args.seed)
                f.write(json.dumps(rec) + "\n")
                f.flush()
            print(f"trial {t} done ({time.strftime('%H:%M:%S')})", flush=True)
    print(f"wrote: {args.out}", file=sys.stderr)


def _load(path: str) -> list[dict]:
    with open(path, encoding="utf-8") as f:
        recs = [json.loads(line) for line in f if line.strip()]
    # only trials complete in every cell (a run stopped early)
    cells = {(r["layout"], r["agent"], r["condition"]) for r in recs}
    per_trial: dict[int, set] = {}
    for r in recs:
        per_trial.setdefault(r["trial"], set()).add((r["layout"], r["agent"], r["condition"]))
    full = {t for t, s in per_trial.items() if s == cells}
    return [r for r in recs if r["trial"] in full]


def _order(agent: str) -> int:
    """Table order: the controllers, the stationary array, then learned policies."""
    known = (*AGENTS, STATIONARY)
    return known.index(agent) if agent in known else len(known)


def summarise(recs: list[dict]) -> list[dict]:
    """Per layout and agent, pooled over the conditions: trials, success rate, errors, means to localise."""
    rows = []
    keys = sorted({(r["K"], r["layout"], r["agent"]) for r in recs}, key=lambda x: (x[0], _order(x[2]), x[2]))
    for k, lay, ag in keys:
        rs = [r for r in recs if r["layout"] == lay and r["agent"] == ag]
        ok = [r for r in rs if r["success"]]
        good = [r for r in ok if r["error_mm"] <= 10.0]

        def mean(key: str, sel: list[dict]) -> float:
            return float(np.mean([r[key] for r in sel])) if sel else float("nan")

        rows.append(
            {
                "K": k,
                "layout": lay,
                "agent": ag,
                "trials": len(rs),
                "success": len(ok),
                "success_rate": len(ok) / len(rs),
                "success_within_10mm": len(good),
                "error_median_mm": float(np.median([r["error_mm"] for r in rs])),
                "error_mean_success_mm": mean("error_mm", ok),
                "snapshots": mean("snapshots", ok),
                "readings": mean("readings", ok),
                "motions": mean("motions", ok),
                "motions_all": mean("motions", rs),
            }
        )
    return rows


def report(args: argparse.Namespace) -> None:
    recs = _load(args.jsonl)
    rows = summarise(recs)
    n_trials = len({r["trial"] for r in recs})
    lines = [
        f"Seed 0, the paper's eight conditions × {n_trials} trials per cell (calibrated model, 2500 particles, "
        "cap 35 snapshots). Means to localise over the successful trials; *success ≤ 10 mm*: successes whose "
        "estimate is within 10 mm of the target.",
        "",
        *markdown_table(
            (
                "K",
                "layout",
                "agent",
                "success / trials",
                "success ≤ 10 mm",
                "error median (mm)",
                "error mean, successes (mm)",
                "snapshots (= readings per pair)",
                "readings",
                "motions",
            ),
            [
                (
                    r["K"],
                    r["layout"],
                    r["agent"],
                    f"{r['success']}/{r['trials']} ({100 * r['success_rate']:.0f} %)",
                    r["success_within_10mm"],
                    f"{r['error_median_mm']:.1f}",
                    f"{r['error_mean_success_mm']:.1f}",
                    f"{r['snapshots']:.1f}",
                    f"{r['readings']:.1f}",
                    f"{r['motions']:.1f}",
                )
                for r in rows
            ],
        ),
    ]
    ks = sorted({(r["K"], r["layout"]) for r in recs})
    per_condition = []
    for c in PRESET_NAMES:
        cells = [c]
        for _, lay in ks:
            rs = [r for r in recs if r["agent"] == STATIONARY and r["layout"] == lay and r["condition"] == c]
            ok = sum(r["success"] for r in rs)
            good = sum(r["success"] and r["error_mm"] <= 10.0 for r in rs)
            cells.append(f"{ok}/{len(rs)} ({good})")
        per_condition.append(cells)
    lines += [
        "",
        "The stationary array per condition: successes (those within 10 mm of the target) of the trials.",
        "",
        *markdown_table(("condition", *(f"K = {k} {lay}" for k, lay in ks)), per_condition),
    ]
    with open(args.table, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.6))
        for ag in sorted({r["agent"] for r in rows}, key=lambda a: (_order(a), a)):
            sel = sorted((r for r in rows if r["agent"] == ag), key=lambda r: r["K"])
            ks = [r["K"] for r in sel]
            style = "o-" if _order(ag) < len(AGENTS) + 1 else "*"  # a learned policy: its own layout only
            ax1.plot(ks, [r["motions"] for r in sel], style, label=ag, markersize=10 if style == "*" else 6)
            ax2.plot(ks, [100 * r["success_rate"] for r in sel], style, label=ag, markersize=10 if style == "*" else 6)
        for ax in (ax1, ax2):
            ax.set_xscale("log", base=2)
            names = {r["K"]: r["layout"] for r in rows}
            ax.set_xticks(sorted(names), [f"{k}\n{names[k]}" for k in sorted(names)])
            ax.set_xlabel("sensing pairs K")
        ax1.set_ylabel("motions to localise (mean, successes)")
        ax2.set_ylabel("success (%)")
        ax2.legend(fontsize=8)
        fig.suptitle(f"Motion traded for sensing: eight conditions × {n_trials} trials, seed 0", fontsize=10)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
    for path in (args.table, args.figure):
        if path:
            print(f"wrote: {path}", file=sys.stderr)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--trials", type=int, default=50)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--layouts", type=lambda s: s.split(","), default=list(LAYOUTS))
    r.add_argument("--agents", type=lambda s: s.split(","), default=[*AGENTS, STATIONARY])
    r.add_argument("--out", default="array_tradeoff.jsonl")
    r.add_argument("--resume", action="store_true")
    q = sub.add_parser("report")
    q.add_argument("jsonl")
    q.add_argument("--table", default="array_tradeoff.md")
    q.add_argument("--figure", default=None)
    args = p.parse_args()
    if args.cmd == "run":
        check_output_options(p, files={"--out": args.out})
    else:
        check_output_options(p, files={"--table": args.table, "--figure": args.figure})
    run(args) if args.cmd == "run" else report(args)


if __name__ == "__main__":
    main()
