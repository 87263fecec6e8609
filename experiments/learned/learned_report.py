"""Learned baselines across training seeds, with rliable's interval estimates (Agarwal et al., NeurIPS 2021).

Reads the benchmark runs of a learned-baseline results folder laid out as::

    RESULTS/<env-id>/<algo>/seed-<k>/bench/trials.jsonl    one `electroloc bench` run per trained seed
    RESULTS/<env-id>/_baselines/bench/trials.jsonl         the non-learned agents on the same trials

and writes ``RESULTS/report.md``, ``RESULTS/report.json`` and figures: per algorithm and env, the IQM and
the mean of readings-to-localise and of successes with 95 % stratified bootstrap confidence intervals,
a normalised score, performance profiles, the probability of improvement over min-var and over the
look-ahead planner, and between the pairs of learned configurations in ``COMPARISONS`` (or ``--compare``).

Scores, one per (run, condition), each over the condition's trials:

* **readings**: the mean number of readings fused until the belief was tight; a failed trial counts as
  the cap (35 readings: the most an episode can use), so a policy cannot look fast by failing.
* **success**: the fraction of trials that localised.
* **normalised**: ``(R_rnd − R) / (R_rnd − R_best)`` with R the readings score, R_rnd that of rnd-wlk
  and R_best that of the best non-learned planner on the condition (the lowest of the baselines' scores
  other than rnd-wlk): 0 at rnd-wlk, 1 at the best planner, above 1 better than every planner.

The conditions are rliable's tasks (stratified bootstrap: runs are resampled within each condition); the
non-learned agents are deterministic given the benchmark seed, so each is one run. rliable computes every
aggregate and interval; this script only arranges the records into its (runs × tasks) matrices.

Run: ``python benchmarks/learned_report.py RESULTS [--reps 2000]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

BASELINES_DIR = "_baselines"


class NoLearnedRuns(ValueError):
    """An env of the results folder has no learned run with a finished benchmark yet."""

RND = "rnd-wlk"
#: The non-learned agents the probability of improvement is stated against (when they were benched).
REFERENCES = ("min-var", "lookahead")
#: Pairs of learned configurations (suite labels) whose P(A better than B) the report states when both
#: ran on an env: memory against stacked frames on the raw reading, and the belief given against memory.
COMPARISONS = (("ppo_lstm-raw", "ppo-framestack-raw"), ("ppo", "ppo_lstm-raw"))


class ReportError(ValueError):
    """A results folder the report cannot read (a missing, empty or unreadable file): one line."""


#: The most bootstrap replications accepted (each keeps a runs × conditions matrix per replication).
MAX_REPS = 100_000


def _config(bench: Path) -> dict[str, Any]:
    path = bench / "config.json"
    try:
        cfg = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ReportError(f"{path}: not a readable benchmark config ({type(exc).__name__})") from None
    if not (isinstance(cfg, dict) and isinstance(cfg.get("conditions"), list) and isinstance(cfg.get("agents"), list)
            and isinstance(cfg.get("trials"), int) and isinstance(cfg.get("env_id"), str)):
        raise ReportError(f"{path}: a benchmark config names its conditions, agents, trials and env_id")
    return cfg


def read_trials(path: Path, set_aside: list[str] | None = None) -> list[dict[str, Any]]:
    """The valid trial records of one benchmark run's ``trials.jsonl``, read through the bench's own
    record schema (:func:`electroloc_gym.bench.records.load_records` with the run's
    :class:`~electroloc_gym.bench.schema.RecordRules` from its ``config.json``): a damaged or impossible
    line — out of range, inconsistent, another run's agent or condition, a duplicate — is left out and
    named in ``set_aside``.

    Raises:
        ReportError: the file is missing or holds no valid record.
    """
    from electroloc_gym.bench.records import load_records
    from electroloc_gym.bench.schema import RecordRules
    from electroloc_gym.protocol import SUCCESS_SPREAD_MM
    from electroloc_gym.registry import env_entry

    if not path.is_file():
        raise ReportError(f"{path} is missing")
    cfg = _config(path.parent)
    rules = RecordRules(conditions=frozenset(c for c in cfg["conditions"] if isinstance(c, str)),
                        agents=frozenset(a for a in cfg["agents"] if isinstance(a, str)), trials=cfg["trials"],
                        success_spread_mm=SUCCESS_SPREAD_MM, shape=bool(env_entry(cfg["env_id"]).record_keys))
    loaded = load_records(path, rules=rules)
    if set_aside is not None:
        set_aside.extend(loaded.messages())
    rows = list(loaded.records.values())
    if not rows:
        raise ReportError(f"{path} holds no valid trial record")
    return rows


def condition_scores(records: Sequence[dict[str, Any]], conditions: Sequence[str]) -> dict[str, np.ndarray]:
    """``{"readings", "success"}`` → (conditions,) scores of one run of one agent."""
    readings, success = [], []
    for cond in conditions:
        rows = [r for r in records if r["condition"] == cond]
        if not rows:
            raise ValueError(f"no trials of condition {cond!r}")
        cap = [int(r["max_observations"]) for r in rows]
        readings.append(float(np.mean([r["readings"] if r["success"] else c for r, c in zip(rows, cap)])))
        success.append(float(np.mean([bool(r["success"]) for r in rows])))
    return {"readings": np.array(readings), "success": np.array(success)}


def collect(results: Path, env_id: str, set_aside: list[str] | None = None) -> tuple[
        list[str], dict[str, dict[str, np.ndarray]], dict[str, dict[str, np.ndarray]], dict[str, list[str]]]:
    """(conditions, learned, baselines, seeds) of one env; what was left out is appended to ``set_aside``.

    ``learned[algo][metric]`` is a (seeds × conditions) matrix; ``baselines[agent][metric]`` is (1 ×
    conditions); ``seeds[algo]`` names the runs in row order (``seed-<integer>`` folders only).
    """
    set_aside = [] if set_aside is None else set_aside
    env_dir = results / env_id
    base_path = env_dir / BASELINES_DIR / "bench" / "trials.jsonl"
    base_rows = read_trials(base_path, set_aside)
    conditions = sorted({r["condition"] for r in base_rows})
    baselines: dict[str, dict[str, np.ndarray]] = {}
    for agent in sorted({r["agent"] for r in base_rows}):
        s = condition_scores([r for r in base_rows if r["agent"] == agent], conditions)
        baselines[agent] = {k: v[None, :] for k, v in s.items()}
    learned: dict[str, dict[str, np.ndarray]] = {}
    seeds: dict[str, list[str]] = {}
    for algo_dir in sorted(p for p in env_dir.iterdir() if p.is_dir() and p.name != BASELINES_DIR):
        runs = sorted(p for p in algo_dir.glob("seed-*") if (p / "bench" / "summary.json").is_file())
        odd = [p for p in runs if not p.name[len("seed-"):].isdecimal() or not p.name.isascii()]
        set_aside.extend(f"{p}: not a seed-<integer> folder" for p in odd)
        runs = [p for p in runs if p not in odd]
        if not runs:
            continue
        per_run = [condition_scores(read_trials(p / "bench" / "trials.jsonl", set_aside), conditions) for p in runs]
        learned[algo_dir.name] = {k: np.stack([s[k] for s in per_run]) for k in ("readings", "success")}
        seeds[algo_dir.name] = [p.name for p in runs]
    return conditions, learned, baselines, seeds


def normalised(readings: np.ndarray, baselines: dict[str, dict[str, np.ndarray]]) -> np.ndarray:
    """The normalised score of a (runs × conditions) readings matrix (0 at rnd-wlk, 1 at the best planner)."""
    if RND not in baselines:
        raise ValueError(f"the baselines' run must include {RND!r} to normalise")
    planners = [v["readings"][0] for k, v in baselines.items() if k != RND]
    if not planners:
        raise ValueError("the baselines' run must include a planner besides rnd-wlk to normalise")
    rnd = baselines[RND]["readings"][0]
    best = np.min(np.stack(planners), axis=0)
    gap = rnd - best
    if np.any(gap <= 0):
        raise ValueError("rnd-wlk is not worse than the best planner on some condition; the score is undefined")
    return (rnd - readings) / gap


def bootstrap(score_dict: dict[str, Any], func: Any, reps: int, seed: int) -> tuple[dict, dict]:
    """Point estimates and 95 % stratified bootstrap CIs (rliable), reproducible from ``seed``.

    rliable 1.2's bootstraps draw their resampling indices from NumPy's global stream
    (``np.random.choice`` in ``update_indices``), so its ``random_state`` argument does not make a run
    repeatable. Each entry is therefore resampled after seeding the global stream with ``seed`` (its
    previous state restored afterwards): the same records give the same intervals, and an algorithm's
    interval depends on its own runs only, not on which other algorithms are in the table.
    """
    from rliable import library as rly

    point, ci = {}, {}
    saved = np.random.get_state()
    try:
        for k, scores in score_dict.items():
            np.random.seed(seed)
            p, c = rly.get_interval_estimates({k: scores}, func, reps=reps)
            point[k], ci[k] = p[k], c[k]
    finally:
        np.random.set_state(saved)
    return point, ci


def interval(score_dict: dict[str, Any], func: Any, reps: int, seed: int) -> dict[str, list[float]]:
    """``{name: [point, lower, upper]}`` of ``func`` with a 95 % stratified bootstrap CI (rliable)."""
    point, ci = bootstrap(score_dict, func, reps, seed)
    return {k: [float(np.ravel(point[k])[0]), float(np.ravel(ci[k])[0]), float(np.ravel(ci[k])[1])]
            for k in score_dict}


def p_better(x: np.ndarray, y: np.ndarray, reps: int, seed: int) -> list[float]:
    """P(a run of X needs fewer readings than a run of Y on a condition) [95 % CI]: rliable's probability
    of improvement of (−X) over (−Y), the readings matrices (runs × conditions) negated, lower being better.
    """
    from rliable import metrics

    func = lambda a, b: np.array([metrics.probability_of_improvement(a, b)])  # noqa: E731
    return interval({"p": (-x, -y)}, func, reps, seed)["p"]


def analyse(results: Path, env_id: str, reps: int = 2000, seed: int = 0,
            comparisons: Sequence[tuple[str, str]] = COMPARISONS) -> dict[str, Any]:
    """Every statistic of one env (plain data, see the module docstring); ``comparisons`` are the
    (A, B) pairs of learned labels whose P(A better than B) is stated, where both ran on the env.
    """
    from rliable import metrics

    set_aside: list[str] = []
    conditions, learned, baselines, seeds = collect(results, env_id, set_aside)
    if not learned:
        raise NoLearnedRuns(f"no learned runs with a benchmark under {results / env_id}")
    iqm = lambda x: np.array([metrics.aggregate_iqm(x)])  # noqa: E731
    mean = lambda x: np.array([metrics.aggregate_mean(x)])  # noqa: E731
    out: dict[str, Any] = {"env_id": env_id, "conditions": conditions, "seeds": seeds, "reps": reps, "seed": seed,
                           "algorithms": {}, "baselines": {}}
    readings = {a: v["readings"] for a, v in learned.items()}
    success = {a: v["success"] for a, v in learned.items()}
    norm = {a: normalised(v, baselines) for a, v in readings.items()} if RND in baselines else {}
    stats = {"readings_iqm": interval(readings, iqm, reps, seed), "readings_mean": interval(readings, mean, reps, seed),
             "success_iqm": interval(success, iqm, reps, seed), "success_mean": interval(success, mean, reps, seed)}
    if norm:
        stats["normalised_iqm"] = interval(norm, iqm, reps, seed)
    for algo in learned:
        row = {k: v[algo] for k, v in stats.items()}
        row["per_condition_readings"] = {c: readings[algo][:, j].tolist() for j, c in enumerate(conditions)}
        row["per_condition_success"] = {c: success[algo][:, j].tolist() for j, c in enumerate(conditions)}
        row["p_improvement"] = {ref: p_better(readings[algo], baselines[ref]["readings"], reps, seed)
                                for ref in REFERENCES if ref in baselines}
        out["algorithms"][algo] = row
    for agent, v in baselines.items():
        row = {"readings_mean": float(v["readings"].mean()), "success_mean": float(v["success"].mean()),
               "per_condition_readings": dict(zip(conditions, v["readings"][0].tolist()))}
        if norm:
            row["normalised_mean"] = float(normalised(v["readings"], baselines).mean())
        out["baselines"][agent] = row
    out["comparisons"] = [{"better": a, "than": b, "p": p_better(readings[a], readings[b], reps, seed)}
                          for a, b in comparisons if a in readings and b in readings]
    out["set_aside"] = set_aside
    out["_matrices"] = {"normalised": norm, "readings": readings}
    return out


def _fmt(v: Sequence[float], digits: int = 2) -> str:
    return f"{v[0]:.{digits}f} [{v[1]:.{digits}f}, {v[2]:.{digits}f}]"


def table(analyses: Sequence[dict[str, Any]]) -> str:
    """The aggregate table (markdown): algorithm × env."""
    lines = ["| env | algorithm | seeds | readings IQM [95 % CI] | readings mean [CI] | success mean [CI] | "
             "normalised IQM [CI] | P(better than min-var) [CI] | P(better than lookahead) [CI] |",
             "|---|---|---|---|---|---|---|---|---|"]
    for a in analyses:
        for algo, row in a["algorithms"].items():
            norm = _fmt(row["normalised_iqm"]) if "normalised_iqm" in row else "–"
            poi = [_fmt(row["p_improvement"][r]) if r in row["p_improvement"] else "–" for r in REFERENCES]
            lines.append(f"| {a['env_id']} | {algo} | {len(a['seeds'][algo])} | {_fmt(row['readings_iqm'])} | "
                         f"{_fmt(row['readings_mean'])} | {_fmt(row['success_mean'])} | {norm} | {poi[0]} | {poi[1]} |")
        for agent, row in a["baselines"].items():
            norm = f"{row['normalised_mean']:.2f}" if "normalised_mean" in row else "–"
            lines.append(f"| {a['env_id']} | {agent} (not learned) | 1 | – | {row['readings_mean']:.2f} | "
                         f"{row['success_mean']:.2f} | {norm} | | |")
    pairs = [(a["env_id"], c) for a in analyses for c in a.get("comparisons", [])]
    if pairs:
        lines += ["", "| env | A | B | P(A needs fewer readings than B) [95 % CI] |", "|---|---|---|---|"]
        lines += [f"| {env} | {c['better']} | {c['than']} | {_fmt(c['p'])} |" for env, c in pairs]
    return "\n".join(lines) + "\n"


def condition_table(a: dict[str, Any]) -> str:
    """Per condition of one env: each algorithm's readings score, mean over its seeds (min–max), and each
    non-learned agent's (markdown).
    """
    conds = a["conditions"]
    lines = [f"{a['env_id']}: readings to localise per condition (a failure counts as the cap), learned: mean over "
             "seeds (min–max)", "", "| agent | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for algo, row in a["algorithms"].items():
        cells = []
        for c in conds:
            v = np.asarray(row["per_condition_readings"][c])
            cells.append(f"{v.mean():.2f} ({v.min():.1f}–{v.max():.1f})")
        lines.append(f"| {algo} ({len(a['seeds'][algo])} seeds) | " + " | ".join(cells) + " |")
    for agent, row in a["baselines"].items():
        lines.append(f"| {agent} | " + " | ".join(f"{row['per_condition_readings'][c]:.2f}" for c in conds) + " |")
    return "\n".join(lines) + "\n"


def figures(analyses: Sequence[dict[str, Any]], out: Path) -> list[Path]:
    """One performance-profile figure per env (normalised score), saved atomically; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from rliable import library as rly

    from electroloc_gym.fileio import save_figure_atomic

    paths = []
    for a in analyses:
        norm = a["_matrices"]["normalised"]
        if not norm:
            continue
        taus = np.linspace(min(-0.5, min(float(v.min()) for v in norm.values())),
                           max(1.5, max(float(v.max()) for v in norm.values())), 101)
        # rliable's create_performance_profile with its default score distributions, seeded like the table
        profiles, cis = bootstrap(norm, lambda s, t=taus: rly.score_distributions(s, t), a["reps"], a["seed"])
        fig, ax = plt.subplots(figsize=(6, 4))
        for algo, prof in profiles.items():
            ax.plot(taus, prof, label=algo)
            ax.fill_between(taus, cis[algo][0], cis[algo][1], alpha=0.2)
        ax.axvline(1.0, color="k", lw=0.8, ls=":")
        ax.set_xlabel("normalised score τ (0: rnd-wlk, 1: best planner)")
        ax.set_ylabel("fraction of (run, condition) with score > τ")
        ax.set_title(f"{a['env_id']}: performance profiles")
        ax.legend(fontsize=8)
        path = out / f"profile_{a['env_id']}.png"
        save_figure_atomic(fig, path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths.append(path)
    return paths


def eval_curves(results: Path, env_id: str) -> dict[str, dict[str, Any]]:
    """Per algorithm: the validation evaluations of its seeds (``eval.csv`` of each rl-zoo3 run) on a common
    step grid, and the training wall times (``summary.json``).

    Returns:
        ``{algo: {"timesteps": (T,), "success_rate": (seeds, T), "mean_readings": (seeds, T),
        "wall_time_s": [per seed]}}``; the grid is the steps every seed evaluated at.
    """
    import csv

    out: dict[str, dict[str, Any]] = {}
    env_dir = results / env_id
    for algo_dir in sorted(p for p in env_dir.iterdir() if p.is_dir() and p.name != BASELINES_DIR):
        runs = []
        for seed_dir in sorted(algo_dir.glob("seed-*")):
            found = sorted(seed_dir.glob("zoo/*/*/eval.csv"))
            if not found or not (seed_dir / "bench" / "summary.json").is_file():  # finished and benchmarked only
                continue
            try:
                with open(found[-1], encoding="utf-8", newline="") as fh:
                    rows = {int(r["timesteps"]): r for r in csv.DictReader(fh)}
                for r in rows.values():
                    if not all(np.isfinite(float(r[k])) for k in ("success_rate", "mean_readings")):
                        raise ValueError("a non-finite evaluation")
            except (KeyError, TypeError, ValueError, UnicodeDecodeError, csv.Error) as exc:
                raise ReportError(f"{found[-1]}: not a readable evaluation log ({exc})") from None
            summary = found[-1].parent / "summary.json"
            wall = None
            if summary.is_file():
                try:
                    data = json.loads(summary.read_text(encoding="utf-8"))
                    wall = data.get("wall_time_s")
                    if wall is not None and (isinstance(wall, bool) or not isinstance(wall, (int, float))
                                             or not np.isfinite(wall)):
                        raise ValueError("wall_time_s is not a finite number")
                except (AttributeError, ValueError, UnicodeDecodeError, RecursionError) as exc:
                    raise ReportError(f"{summary}: not a readable training summary ({exc})") from None
            runs.append((rows, wall))
        if not runs:
            continue
        grid = sorted(set.intersection(*(set(r) for r, _ in runs)))
        out[algo_dir.name] = {
            "timesteps": np.array(grid),
            **{k: np.array([[float(r[t][k]) for t in grid] for r, _ in runs])
               for k in ("success_rate", "mean_readings")},
            "wall_time_s": [w for _, w in runs],
        }
    return out


def curve_figure(results: Path, env_id: str, curves: dict[str, dict[str, Any]]) -> Path | None:
    """Success rate and mean readings on validation episodes against env steps: the mean over seeds and its
    95 % t-interval (scipy) clipped to the metric's range (a rate in [0, 1], readings in [0, the episode
    cap]: with five seeds an early, bimodal step's t-interval reaches past both), every algorithm of the env
    in one figure; saved atomically.
    """
    if not curves:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter
    from scipy import stats

    from electroloc_gym.core.params import EnvParams
    from electroloc_gym.fileio import save_figure_atomic

    ranges = {"success_rate": (0.0, 1.0), "mean_readings": (0.0, float(EnvParams().max_observations))}
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for algo, c in curves.items():
        for ax, key in zip(axes, ("success_rate", "mean_readings")):
            y = c[key]
            m = y.mean(axis=0)
            if y.shape[0] > 1:
                half = stats.t.ppf(0.975, y.shape[0] - 1) * y.std(axis=0, ddof=1) / np.sqrt(y.shape[0])
                ax.fill_between(c["timesteps"], *np.clip([m - half, m + half], *ranges[key]), alpha=0.2)
            ax.plot(c["timesteps"], m, marker=".", label=f"{algo} ({y.shape[0]} seeds)")
    axes[0].set_ylabel("success rate (validation episodes)")
    axes[1].set_ylabel("mean readings to localise (failure = cap)")
    for ax in axes:
        ax.set_xlabel("env steps (thousands)")
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1000:g}"))
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{env_id}: learning curves, mean and 95 % interval over training seeds")
    path = results / f"curves_{env_id}.png"
    save_figure_atomic(fig, path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="the results folder (RESULTS/<env-id>/<algo>/seed-<k>/)")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap replications (≥ 100)")
    parser.add_argument("--seed", type=int, default=0, help="the bootstrap's seed (0 to 2**32 - 1)")
    parser.add_argument("--compare", action="append", metavar="A:B",
                        help="learned labels A:B whose P(A better than B) to state (repeatable; default "
                             + ", ".join(f"{a}:{b}" for a, b in COMPARISONS) + ")")
    args = parser.parse_args(argv)
    comparisons = COMPARISONS
    if args.compare:
        pairs = [c.split(":") for c in args.compare]
        if any(len(p) != 2 or not all(p) for p in pairs):
            parser.error(f"--compare takes A:B, two learned labels, got {args.compare!r}")
        comparisons = tuple((a, b) for a, b in pairs)
    if not 100 <= args.reps <= MAX_REPS:
        parser.error(f"--reps must be in [100, {MAX_REPS}], got {args.reps}")
    if not 0 <= args.seed < 2**32:
        parser.error(f"--seed must be in [0, 2**32), got {args.seed}")
    if not args.results.is_dir():
        parser.error(f"results folder {str(args.results)!r} does not exist")

    envs = sorted(p.name for p in args.results.iterdir() if (p / BASELINES_DIR / "bench" / "summary.json").is_file())
    if not envs:
        parser.error(f"no finished <env-id>/{BASELINES_DIR}/bench/ under {str(args.results)!r}")
    try:
        return _report(args, envs, comparisons)
    except (ValueError, OSError, RecursionError) as exc:  # a damaged results folder: one line
        text = str(exc).strip().splitlines()
        print(f"learned_report: error: {text[0] if text else type(exc).__name__}", file=sys.stderr)
        return 2


def _report(args: argparse.Namespace, envs: list[str], comparisons: Sequence[tuple[str, str]]) -> int:
    from electroloc_gym.fileio import atomic_write_text, write_json_atomic

    analyses = []
    for env in list(envs):  # a suite still running: an env without a benchmarked learned run is left out
        try:
            analyses.append(analyse(args.results, env, args.reps, args.seed, comparisons))
        except NoLearnedRuns as exc:
            print(f"learned_report: {env} left out: {exc}", file=sys.stderr)
            envs.remove(env)
    if not analyses:
        raise ReportError(f"no benchmarked learned run under {str(args.results)!r}")
    text = table(analyses) + "".join("\n" + condition_table(a) for a in analyses)
    aside = [m for a in analyses for m in a["set_aside"]]
    for m in aside:
        print(f"learned_report: set aside: {m}", file=sys.stderr)
    if aside:
        text += f"\n{len(aside)} record(s) or folder(s) set aside (impossible or not this run's):\n\n"
        text += "".join(f"* {m}\n" for m in aside)
    figures(analyses, args.results)
    compute = ["", "| env | algorithm | training wall time per seed, s (2-core CPU) |", "|---|---|---|"]
    for env in envs:
        curves = eval_curves(args.results, env)
        curve_figure(args.results, env, curves)
        for algo, c in curves.items():
            walls = [w for w in c["wall_time_s"] if w is not None]
            compute.append(f"| {env} | {algo} | {', '.join(f'{w:.0f}' for w in walls) or '–'} |")
    text += "\n".join(compute) + "\n"
    atomic_write_text(args.results / "report.md", text)
    write_json_atomic(args.results / "report.json",
                      [{k: v for k, v in a.items() if not k.startswith("_") and not (k == "set_aside" and not v)}
                       for a in analyses])
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
