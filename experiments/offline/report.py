"""The offline and imitation baselines beside the controllers their data came from, with rliable's intervals.

Reads ``RESULTS/<env-id>/<label>/seed-<k>/bench/trials.jsonl`` (one ``electroloc bench`` run per trained
seed, written by ``run_suite.py``) and the controllers' runs on the same trials (the learned suite's
``<learned>/<env-id>/_baselines/bench``, and ``RESULTS/<env-id>/_sources/bench`` for the shipped policy in
the mix); writes ``RESULTS/report.md``, ``RESULTS/report.json`` and ``RESULTS/curves_<env-id>.png``.

Scores are the learned report's (its functions are imported, not copied): per (run, condition) the mean
readings to localise (a failure counted as the cap), success, the normalised score (0 rnd-wlk, 1 the best
planner); IQM and mean with 95 % stratified bootstrap CIs; P(improvement) — P(a run of the method needs
fewer readings than the reference on a condition) — over the controller the data came from (BC) or over
the best controller of the mix (offline RL). The controllers are compared on exactly the trials the
methods ran (the first trials of each condition of the benchmark's seed 0). Decision time: the median over
trials of each trial's median ms per ``predict``.

    python experiments/offline/report.py experiments/offline/results --learned experiments/learned/results [--out DIR]

The outputs go to ``--out`` (default: ``RESULTS`` itself); a line on stderr says each env's progress as it
starts, and the last lines list every file written.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "learned"))  # the learned report's statistics
import learned_scores  # noqa: E402

from electroloc_gym.baselines.agent import PLANNER_AGENTS, RANDOM_AGENT  # noqa: E402
from electroloc_gym.baselines.infotaxis import InfotaxisAgent  # noqa: E402
from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
MIX = (RANDOM_AGENT, MinVarianceAgent.name, LookaheadAgent.name, InfotaxisAgent.name, "ppo-belief")
PLANNERS = (RANDOM_AGENT, *PLANNER_AGENTS)
#: Per method label: its data and the controller it is compared with ("best": the best of the mix).
METHODS = {
    "bc-lookahead": (LookaheadAgent.name, LookaheadAgent.name),
    "bc-min-var": (MinVarianceAgent.name, MinVarianceAgent.name),
    "td3bc-mixed": (", ".join(MIX), "best"),
}


def _controllers(lr: Any, paths: list[Path], keys: set[tuple[str, int]]) -> dict[str, list[dict[str, Any]]]:
    rows: dict[str, list[dict[str, Any]]] = {}
    from electroloc_gym.bench.records import stored_trials

    for p in paths:
        if stored_trials(p).is_file():
            for r in lr.read_trials(p):
                if (r["condition"], int(r["trial"])) in keys:
                    rows.setdefault(r["agent"], []).append(r)
    return rows


def _ms(rows: list[dict[str, Any]]) -> float | None:
    dms = [r["decision_ms_median"] for r in rows if r.get("decision_ms_median") is not None]
    return float(np.median(dms)) if dms else None


def analyse(results: Path, learned: Path, env_id: str, reps: int, seed: int) -> dict[str, Any]:
    """Every statistic of one env (plain data)."""
    from rliable import metrics

    lr = learned_scores
    env_dir = results / env_id
    runs = {
        m: sorted(p for p in (env_dir / m).glob("seed-*") if (p / "bench" / "summary.json").is_file()) for m in METHODS
    }
    runs = {m: v for m, v in runs.items() if v}
    trials = {m: [lr.read_trials(p / "bench" / "trials.jsonl") for p in v] for m, v in runs.items()}
    keys = {(r["condition"], int(r["trial"])) for r in next(iter(trials.values()))[0]}
    conditions = sorted({c for c, _ in keys})
    ctrl = _controllers(
        lr,
        [learned / env_id / "_baselines" / "bench" / "trials.jsonl", env_dir / "_sources" / "bench" / "trials.jsonl"],
        keys,
    )
    base = {a: {k: v[None, :] for k, v in lr.condition_scores(rows, conditions).items()} for a, rows in ctrl.items()}
    planners = {a: v for a, v in base.items() if a in PLANNERS}
    iqm = lambda x: np.array([metrics.aggregate_iqm(x)])  # noqa: E731
    mean = lambda x: np.array([metrics.aggregate_mean(x)])  # noqa: E731
    scores = {m: [lr.condition_scores(t, conditions) for t in ts] for m, ts in trials.items()}
    readings = {m: np.stack([s["readings"] for s in v]) for m, v in scores.items()}
    success = {m: np.stack([s["success"] for s in v]) for m, v in scores.items()}
    mix = [a for a in MIX if a in base]
    best_mix = min(mix, key=lambda a: base[a]["readings"].mean()) if mix else None
    best_planner = min((a for a in planners if a != RANDOM_AGENT), key=lambda a: base[a]["readings"].mean())
    stats = {
        "readings_iqm": lr.interval(readings, iqm, reps, seed),
        "readings_mean": lr.interval(readings, mean, reps, seed),
        "success_mean": lr.interval(success, mean, reps, seed),
        "normalised_iqm": lr.interval({m: lr.normalised(v, planners) for m, v in readings.items()}, iqm, reps, seed),
    }
    out: dict[str, Any] = {
        "env_id": env_id,
        "conditions": conditions,
        "trials_per_condition": len(keys) // len(conditions),
        "reps": reps,
        "seed": seed,
        "best_of_mix": best_mix,
        "methods": {},
        "controllers": {},
    }
    for m in readings:
        ref = best_mix if METHODS[m][1] == "best" else METHODS[m][1]
        out["methods"][m] = {
            **{k: v[m] for k, v in stats.items()},
            "seeds": [p.name for p in runs[m]],
            "data": METHODS[m][0],
            "reference": ref,
            "p_improvement": lr.p_better(readings[m], base[ref]["readings"], reps, seed) if ref in base else None,
            "best_planner": best_planner,
            "p_improvement_best_planner": lr.p_better(readings[m], base[best_planner]["readings"], reps, seed),
            "decision_ms": _ms([r for t in trials[m] for r in t]),
            "per_condition_readings": {c: readings[m][:, j].tolist() for j, c in enumerate(conditions)},
        }
    for a, v in base.items():
        out["controllers"][a] = {
            "readings_mean": float(v["readings"].mean()),
            "success_mean": float(v["success"].mean()),
            "normalised_mean": float(lr.normalised(v["readings"], planners).mean()),
            "decision_ms": _ms(ctrl[a]),
        }
    return out


def table(a: dict[str, Any]) -> str:
    """The markdown table of one env."""
    f = lambda v: f"{v[0]:.2f} [{v[1]:.2f}, {v[2]:.2f}]"  # noqa: E731
    # Built by hand, not by electroloc_gym.utils.markdown: a controller row's empty cells are "| |", one space, not
    # the helper's "|  |".
    lines = [
        f"### {a['env_id']} ({len(a['conditions'])} condition{'s' if len(a['conditions']) != 1 else ''} × "
        f"{a['trials_per_condition']} trials of the "
        f"benchmark's seed 0)",
        "",
        "| agent | data | seeds | readings IQM [95 % CI] | readings mean [CI] | success | normalised IQM [CI] | "
        "P(better than the reference) [CI] | reference | P(better than the best planner) [CI] | ms / decision |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for m, r in a["methods"].items():
        p = "–" if r["p_improvement"] is None else f(r["p_improvement"])
        lines.append(
            f"| {m} | {r['data']} | {len(r['seeds'])} | {f(r['readings_iqm'])} | {f(r['readings_mean'])} | "
            f"{r['success_mean'][0]:.2f} | {f(r['normalised_iqm'])} | {p} | {r['reference']} | "
            f"{f(r['p_improvement_best_planner'])} ({r['best_planner']}) | {r['decision_ms']:.3f} |"
        )
    for c, r in sorted(a["controllers"].items(), key=lambda kv: kv[1]["readings_mean"]):
        ms = "–" if r["decision_ms"] is None else f"{r['decision_ms']:.3f}"
        lines.append(
            f"| {c} (controller) | | 1 | | {r['readings_mean']:.2f} | {r['success_mean']:.2f} | "
            f"{r['normalised_mean']:.2f} (mean) | | | | {ms} |"
        )
    return "\n".join(lines)


def curves(results: Path, env_id: str, out: Path | None = None) -> Path | None:
    """Validation readings against gradient steps, mean and min–max over seeds, per method; saved in ``out``
    (default ``results``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from electroloc_gym.utils.fileio import save_figure_atomic

    fig, ax = plt.subplots(figsize=(6, 3.5))
    drawn = False
    for m in METHODS:
        paths = sorted((results / env_id / m).glob("seed-*/curve.json"))
        rows = [json.loads(p.read_text(encoding="utf-8")) for p in paths]
        if not rows:
            continue
        n = min(len(r) for r in rows)
        steps = np.array([c["step"] for c in rows[0][:n]])
        y = np.array([[c["readings"] for c in r[:n]] for r in rows])
        ax.plot(steps, y.mean(0), marker="o", label=f"{m} ({len(rows)} seeds)")
        ax.fill_between(steps, y.min(0), y.max(0), alpha=0.2)
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_xlabel("gradient steps")
    ax.set_ylabel("validation readings (failure = 35)")
    ax.set_title(f"{env_id}: offline learning curves (mean, min–max over seeds)", fontsize=9)
    ax.legend(fontsize=8)
    path = (results if out is None else out) / f"curves_{env_id}.png"
    save_figure_atomic(fig, path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Analyse, print and write the report."""
    from electroloc_gym.bench.bench_command import ascii_int

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="the offline results folder")
    parser.add_argument(
        "--learned",
        type=Path,
        default=ROOT / "experiments" / "learned" / "results",
        help="the learned suite's results (its _baselines runs)",
    )
    parser.add_argument("--reps", type=ascii_int, default=2000, help="bootstrap replications (100 … 10**6)")
    parser.add_argument("--seed", type=ascii_int, default=0, help="the bootstrap's seed (0 … 2**32 − 1)")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="where report.md, report.json and the figures go (default: the results folder; created if missing)",
    )
    args = parser.parse_args(argv)
    if not 100 <= args.reps <= 10**6:
        parser.error(f"--reps must be an integer in [100, 1000000], got {args.reps}")
    if not 0 <= args.seed < 2**32:
        parser.error(f"--seed must be in [0, 2**32 − 1], got {args.seed}")
    if not args.results.is_dir():
        parser.error(f"{args.results} is not a folder")
    from electroloc_gym.utils.fileio import atomic_write_text, check_output_options, write_json_atomic

    out: Path = args.results if args.out is None else args.out
    check_output_options(parser, folders={"results" if args.out is None else "--out": out})

    envs = sorted(
        p.name
        for p in args.results.iterdir()
        if p.is_dir() and any((p / m).glob("seed-*/bench/summary.json") for m in METHODS)
    )
    if not envs:
        parser.error(f"{args.results} holds no benchmarked offline runs")
    t0 = time.perf_counter()

    def progress(text: str) -> None:
        print(f"offline report: [{time.perf_counter() - t0:6.1f} s] {text}", file=sys.stderr, flush=True)

    analyses = []
    for k, e in enumerate(envs, 1):
        progress(f"{e} ({k} of {len(envs)}): scores and {args.reps} bootstrap replications")
        analyses.append(analyse(args.results, args.learned, e, args.reps, args.seed))
    out.mkdir(parents=True, exist_ok=True)
    progress("learning curves")
    figs = [p for p in (curves(args.results, e, out) for e in envs) if p is not None]
    text = "\n\n".join(table(a) for a in analyses)
    text += "\n\n" + "\n".join(f"![curves]({p.name})" for p in figs) + "\n"
    atomic_write_text(out / "report.md", text)
    write_json_atomic(out / "report.json", analyses)
    print(text)
    written = [out / "report.md", out / "report.json", *figs]
    progress(f"wrote {len(written)} files:")
    for path in written:
        print(f"wrote: {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
