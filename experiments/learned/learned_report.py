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

A tracking env (ElectroLocTrack-v0: the target swims, every trial runs to its 70 readings) is scored by
its **tracking error** instead (the mean over the condition's trials of ``tracking_error_mm``, mm, lower
better) and its **capture** fraction, in a table of its own: the same aggregates, the normalised tracking
error (0 at rnd-wlk, 1 at the best non-learned controller on the condition), the probability of a lower
tracking error than min-var and between the learned pairs of ``TRACK_COMPARISONS``; its learning curves
show the validation episodes' mean return and final error (``learned_scores`` says more).

The conditions are rliable's tasks (stratified bootstrap: runs are resampled within each condition); the
non-learned agents are deterministic given the benchmark seed, so each is one run. rliable computes every
aggregate and interval; this script only arranges the records into its (runs × tasks) matrices.

``--extra DIR`` (repeatable) adds the runs of another folder with the same layout — the offline and
imitation baselines of ``experiments/offline/results`` — to the same table, scored against this folder's
non-learned run (their benchmarks must use the same trials).

Run: ``python experiments/learned/learned_report.py RESULTS [--reps 2000] [--extra experiments/offline/results]
[--out DIR]``. The outputs go to ``--out`` (default: ``RESULTS`` itself, beside the runs); a line on stderr says
each env's and section's progress as it starts (the bootstrap takes minutes), and the last lines list every file
written.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the scores beside this script

from learned_level import reach, reach_table  # noqa: E402
from learned_scores import (  # noqa: E402
    BASELINES_DIR,
    COMPARISONS,
    MAX_REPS,
    REFERENCES,
    TRACK_COMPARISONS,
    NoLearnedRuns,
    ReportError,
    analyse,
    bootstrap,
    tracks,
)


def _fmt(v: Sequence[float], digits: int = 2) -> str:
    return f"{v[0]:.{digits}f} [{v[1]:.{digits}f}, {v[2]:.{digits}f}]"


def _tracking(a: dict[str, Any]) -> bool:
    """Whether an analysis is a tracking env's (scored by its task's own score and rate: it names the score)."""
    return "metric" in a


def table(analyses: Sequence[dict[str, Any]]) -> str:
    """The aggregate table (markdown): algorithm × env; the tracking envs' in a table of their own after it
    (:func:`tracking_table`).
    """
    track = [a for a in analyses if _tracking(a)]
    analyses = [a for a in analyses if not _tracking(a)]
    if not analyses:
        return tracking_table(track)

    # The main table is built by hand, not by markdown_table: a baseline row's empty cells are "| |", one space,
    # not the helper's "|  |".
    lines = [
        "| env | algorithm | seeds | readings IQM [95 % CI] | readings mean [CI] | success mean [CI] | "
        "normalised IQM [CI] | P(better than min-var) [CI] | P(better than lookahead) [CI] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for a in analyses:
        for algo, row in a["algorithms"].items():
            norm = _fmt(row["normalised_iqm"]) if "normalised_iqm" in row else "–"
            poi = [_fmt(row["p_improvement"][r]) if r in row["p_improvement"] else "–" for r in REFERENCES]
            lines.append(
                f"| {a['env_id']} | {algo} | {len(a['seeds'][algo])} | {_fmt(row['readings_iqm'])} | "
                f"{_fmt(row['readings_mean'])} | {_fmt(row['success_mean'])} | {norm} | {poi[0]} | {poi[1]} |"
            )
        for agent, row in a["baselines"].items():
            norm = f"{row['normalised_mean']:.2f}" if "normalised_mean" in row else "–"
            lines.append(
                f"| {a['env_id']} | {agent} (not learned) | 1 | – | {row['readings_mean']:.2f} | "
                f"{row['success_mean']:.2f} | {norm} | | |"
            )
    lines += _pairs_table(analyses, "needs fewer readings than")
    return "\n".join(lines) + "\n" + ("\n" + tracking_table(track) if track else "")


def tracking_table(analyses: Sequence[dict[str, Any]]) -> str:
    """The tracking envs' aggregate table (markdown): algorithm × env, by tracking error (mm) and capture,
    then their learned pairs' probabilities of a lower tracking error.
    """
    from electroloc_gym.utils.markdown import markdown_table

    refs = [r for r in REFERENCES if any(r in a["baselines"] for a in analyses)]
    rows = []
    for a in analyses:
        for algo, row in a["algorithms"].items():
            norm = _fmt(row["normalised_iqm"]) if "normalised_iqm" in row else "–"
            rows.append(
                (
                    a["env_id"],
                    algo,
                    str(len(a["seeds"][algo])),
                    _fmt(row["tracking_error_iqm"]),
                    _fmt(row["tracking_error_mean"]),
                    _fmt(row["capture_mean"]),
                    norm,
                    *(_fmt(row["p_improvement"][r]) if r in row["p_improvement"] else "–" for r in refs),
                )
            )
        for agent, row in a["baselines"].items():
            norm = f"{row['normalised_mean']:.2f}" if "normalised_mean" in row else "–"
            rows.append(
                (
                    a["env_id"],
                    f"{agent} (not learned)",
                    "1",
                    "–",
                    f"{row['tracking_error_mean']:.2f}",
                    f"{row['capture_mean']:.2f}",
                    norm,
                    *("–" for _ in refs),
                )
            )
    lines = [
        "Tracking envs (the target swims; every trial runs to its reading cap): tracking error = the belief "
        "mean's mean distance to the target over the episode's second half, mm (lower is better); capture = "
        "the carriage within 10 mm of the target at the end",
        "",
        *markdown_table(
            (
                "env",
                "algorithm",
                "seeds",
                "tracking error IQM, mm [95 % CI]",
                "tracking error mean, mm [CI]",
                "capture mean [CI]",
                "normalised IQM [CI]",
                *(f"P(lower error than {r}) [CI]" for r in refs),
            ),
            rows,
        ),
    ]
    lines += _pairs_table(analyses, "tracks with a lower error than")
    return "\n".join(lines) + "\n"


def _pairs_table(analyses: Sequence[dict[str, Any]], better: str) -> list[str]:
    """The learned pairs' table (markdown lines, after a blank one; none without pairs): P(A ``better`` B)."""
    from electroloc_gym.utils.markdown import markdown_table

    pairs = [(a["env_id"], c) for a in analyses for c in a.get("comparisons", [])]
    if not pairs:
        return []
    return [
        "",
        *markdown_table(
            ("env", "A", "B", f"P(A {better} B) [95 % CI]"),
            [(env, c["better"], c["than"], _fmt(c["p"])) for env, c in pairs],
        ),
    ]


def condition_table(a: dict[str, Any]) -> str:
    """Per condition of one env: each algorithm's score, mean over its seeds (min–max), and each non-learned
    agent's (markdown): the readings to localise, or a tracking env's tracking error (mm) and capture
    fraction, a table each.
    """
    from electroloc_gym.utils.markdown import markdown_table

    sections = (
        (("tracking_error", "tracking error, mm per condition", 1), ("capture", "capture fraction per condition", 2))
        if _tracking(a)
        else (("readings", "readings to localise per condition (a failure counts as the cap)", 1),)
    )
    conds = a["conditions"]
    lines: list[str] = []
    for key, what, digits in sections:
        rows = []
        for algo, row in a["algorithms"].items():
            cells = [f"{algo} ({len(a['seeds'][algo])} seeds)"]
            for c in conds:
                v = np.asarray(row[f"per_condition_{key}"][c])
                cells.append(f"{v.mean():.2f} ({v.min():.{digits}f}–{v.max():.{digits}f})")
            rows.append(cells)
        for agent, row in a["baselines"].items():
            rows.append([agent, *(f"{row[f'per_condition_{key}'][c]:.2f}" for c in conds)])
        lines += [
            *([""] if lines else []),
            f"{a['env_id']}: {what}, learned: mean over seeds (min–max)",
            "",
            *markdown_table(("agent", *conds), rows),
        ]
    return "\n".join(lines) + "\n"


def figures(analyses: Sequence[dict[str, Any]], out: Path) -> list[Path]:
    """One performance-profile figure per env (normalised score), saved atomically; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from rliable import library as rly

    from electroloc_gym.utils.fileio import save_figure_atomic

    paths = []
    for a in analyses:
        norm = a["_matrices"]["normalised"]
        if not norm:
            continue
        taus = np.linspace(
            min(-0.5, min(float(v.min()) for v in norm.values())),
            max(1.5, max(float(v.max()) for v in norm.values())),
            101,
        )
        # rliable's create_performance_profile with its default score distributions, seeded like the table
        profiles, cis = bootstrap(norm, lambda s, t=taus: rly.score_distributions(s, t), a["reps"], a["seed"])
        fig, ax = plt.subplots(figsize=(6, 4))
        for algo, prof in profiles.items():
            ax.plot(taus, prof, label=algo)
            ax.fill_between(taus, cis[algo][0], cis[algo][1], alpha=0.2)
        ax.axvline(1.0, color="k", lw=0.8, ls=":")
        best = "best non-learned controller" if _tracking(a) else "best planner"
        ax.set_xlabel(f"normalised score τ (0: rnd-wlk, 1: {best})")
        ax.set_ylabel("fraction of (run, condition) with score > τ")
        ax.set_title(f"{a['env_id']}: performance profiles")
        ax.legend(fontsize=8)
        path = out / f"profile_{a['env_id']}.png"
        save_figure_atomic(fig, path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths.append(path)
    return paths


#: The ``eval.csv`` columns the learning curves show: success and readings, or (a tracking env, whose
#: episodes all run to the cap) the validation return and the final error.
CURVE_KEYS = ("success_rate", "mean_readings")
TRACK_CURVE_KEYS = ("mean_return", "mean_error_mm")


def eval_curves(results: Path, env_id: str) -> dict[str, dict[str, Any]]:
    """Per algorithm: the validation evaluations of its seeds (``eval.csv`` of each rl-zoo3 run) on a common
    step grid, and the training wall times (each run's ``summary.json``, read through its schema by
    :func:`~electroloc_gym.train.summary.read_summary`).

    Returns:
        ``{algo: {"timesteps": (T,), "success_rate": (seeds, T), "mean_readings": (seeds, T),
        "wall_time_s": [per seed]}}`` (a tracking env: ``"mean_return"`` and ``"mean_error_mm"`` in place of
        the success rate and readings); the grid is the steps every seed evaluated at.
    """
    from electroloc_gym.train.curves import read_eval_csv
    from electroloc_gym.train.summary import read_summary

    keys = TRACK_CURVE_KEYS if tracks(env_id) else CURVE_KEYS
    out: dict[str, dict[str, Any]] = {}
    env_dir = results / env_id
    for algo_dir in sorted(p for p in env_dir.iterdir() if p.is_dir() and p.name != BASELINES_DIR):
        runs = []
        for seed_dir in sorted(algo_dir.glob("seed-*")):
            found = sorted(seed_dir.glob("zoo/*/*/eval.csv"))
            if not found or not (seed_dir / "bench" / "summary.json").is_file():  # finished and benchmarked only
                continue
            try:
                cols = read_eval_csv(found[-1])
            except ValueError as exc:
                raise ReportError(str(exc)) from None
            absent = [k for k in keys if k not in cols]
            if absent:
                raise ReportError(f"{found[-1]}: not a readable evaluation log (missing column(s) {absent})")
            rows = {int(t): {k: v[i] for k, v in cols.items()} for i, t in enumerate(cols["timesteps"])}
            summary = found[-1].parent / "summary.json"
            wall = None
            if summary.is_file():
                try:
                    wall = read_summary(summary).wall_time_s  # its one schema: a finite number of seconds ≥ 0
                except ValueError as exc:  # one line naming the file and the field
                    raise ReportError(str(exc)) from None
            runs.append((rows, wall))
        if not runs:
            continue
        grid = sorted(set.intersection(*(set(r) for r, _ in runs)))
        out[algo_dir.name] = {
            "timesteps": np.array(grid),
            **{k: np.array([[float(r[t][k]) for t in grid] for r, _ in runs]) for k in keys},
            "wall_time_s": [w for _, w in runs],
        }
    return out


def curve_figure(results: Path, env_id: str, curves: dict[str, dict[str, Any]], out: Path | None = None) -> Path | None:
    """Success rate and mean readings on validation episodes against env steps: the mean over seeds and its
    95 % t-interval (scipy) clipped to the metric's range (a rate in [0, 1], readings in [0, the episode
    cap]: with five seeds an early, bimodal step's t-interval reaches past both), every algorithm of the env
    in one figure, drawn by rliable's ``plot_sample_efficiency_curve``; saved atomically in ``out`` (default
    ``results``). A tracking env shows its validation episodes' mean return (≤ 0) and mean final error (mm,
    ≥ 0) instead.
    """
    if not curves:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter
    from rliable import plot_utils
    from scipy import stats

    from electroloc_gym.contract.params import EnvParams
    from electroloc_gym.utils.fileio import save_figure_atomic

    ranges = {
        "success_rate": (0.0, 1.0),
        "mean_readings": (0.0, float(EnvParams().max_observations)),
        "mean_return": (None, 0.0),
        "mean_error_mm": (0.0, None),
    }
    track = tracks(env_id)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, key in zip(axes, TRACK_CURVE_KEYS if track else CURVE_KEYS):
        for algo, c in curves.items():  # one call per algorithm: each has its own evaluation steps
            y = c[key]
            m = y.mean(axis=0)
            half = (
                stats.t.ppf(0.975, y.shape[0] - 1) * y.std(axis=0, ddof=1) / np.sqrt(y.shape[0])
                if y.shape[0] > 1
                else np.zeros_like(m)
            )
            label = f"{algo} ({y.shape[0]} seeds)"
            plot_utils.plot_sample_efficiency_curve(
                c["timesteps"],
                {label: m},
                {label: np.clip([m - half, m + half], *ranges[key])},
                colors={label: f"C{list(curves).index(algo)}"},
                ax=ax,
                xlabel="",
                ylabel="",
                marker=".",
                labelsize="medium",
                ticklabelsize="small",
            )
    if track:
        axes[0].set_ylabel("mean return (validation episodes)")
        axes[1].set_ylabel("mean error at the last reading, mm")
    else:
        axes[0].set_ylabel("success rate (validation episodes)")
        axes[1].set_ylabel("mean readings to localise (failure = cap)")
    for ax in axes:
        ax.set_xlabel("env steps (thousands)")
        ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1000:g}"))
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{env_id}: learning curves, mean and 95 % interval over training seeds")
    path = (results if out is None else out) / f"curves_{env_id}.png"
    save_figure_atomic(fig, path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path, help="the results folder (RESULTS/<env-id>/<algo>/seed-<k>/)")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap replications (≥ 100)")
    parser.add_argument("--seed", type=int, default=0, help="the bootstrap's seed (0 to 2**32 - 1)")
    parser.add_argument(
        "--compare",
        action="append",
        metavar="A:B",
        help="learned labels A:B whose P(A better than B) to state (repeatable; default "
        + ", ".join(f"{a}:{b}" for a, b in COMPARISONS)
        + "; on a tracking env "
        + ", ".join(f"{a}:{b}" for a, b in TRACK_COMPARISONS)
        + ")",
    )
    parser.add_argument(
        "--extra",
        action="append",
        type=Path,
        default=[],
        metavar="DIR",
        help="another results folder (DIR/<env-id>/<label>/seed-<k>/bench/) whose labels join the table (repeatable)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="where report.md, report.json and the figures go (default: the results folder; created if missing)",
    )
    parser.add_argument(
        "--min-var-level",
        action="store_true",
        help="run min-var on the runs' validation episodes where its score is not cached yet (once per env and "
        "setting, cached in RESULTS/<env-id>/_baselines/validation/; minutes: 64 episodes), for the env steps and "
        "wall time each run took to reach it; without it only cached levels are used",
    )
    args = parser.parse_args(argv)
    missing = [str(d) for d in args.extra if not d.is_dir()]
    if missing:
        parser.error(f"--extra folder(s) {missing} do not exist")
    comparisons = None  # each env's default pairs
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
    from electroloc_gym.utils.fileio import check_output_options

    option = "results" if args.out is None else "--out"  # the folder the outputs go to, by the name it was given
    args.out = args.results if args.out is None else args.out
    check_output_options(parser, folders={option: args.out})  # report.md, report.json, figures

    envs = sorted(p.name for p in args.results.iterdir() if (p / BASELINES_DIR / "bench" / "summary.json").is_file())
    if not envs:
        parser.error(f"no finished <env-id>/{BASELINES_DIR}/bench/ under {str(args.results)!r}")
    try:
        return _report(args, envs, comparisons)
    except (ValueError, OSError, RecursionError) as exc:  # a damaged results folder: one line
        text = str(exc).strip().splitlines()
        print(f"learned_report: error: {text[0] if text else type(exc).__name__}", file=sys.stderr)
        return 2


def _progress(t0: float, text: str) -> None:
    """One progress line on stderr, with the seconds since the start."""
    print(f"learned_report: [{time.perf_counter() - t0:6.1f} s] {text}", file=sys.stderr, flush=True)


def _report(args: argparse.Namespace, envs: list[str], comparisons: Sequence[tuple[str, str]] | None) -> int:
    from electroloc_gym.utils.fileio import atomic_write_text, write_json_atomic
    from electroloc_gym.utils.markdown import markdown_table

    t0 = time.perf_counter()
    out: Path = args.out
    analyses = []
    for k, env in enumerate(
        list(envs), 1
    ):  # a suite still running: an env without a benchmarked learned run is left out
        _progress(t0, f"{env} ({k} of {len(envs)}): scores and {args.reps} bootstrap replications")
        try:
            analyses.append(analyse(args.results, env, args.reps, args.seed, comparisons, args.extra))
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
    out.mkdir(parents=True, exist_ok=True)
    _progress(t0, f"performance profiles of {len(analyses)} env(s)")
    written = figures(analyses, out)
    compute = []
    for env in envs:
        _progress(t0, f"{env}: learning curves")
        curves = eval_curves(args.results, env)
        path = curve_figure(args.results, env, curves, out)
        if path is not None:
            written.append(path)
        for algo, c in curves.items():
            walls = [w for w in c["wall_time_s"] if w is not None]
            compute.append((env, algo, ", ".join(f"{w:.0f}" for w in walls) or "–"))
    text += (
        "\n".join(["", *markdown_table(("env", "algorithm", "training wall time per seed, s (2-core CPU)"), compute)])
        + "\n"
    )
    levels = {}
    for env in envs:
        _progress(t0, f"{env}: env steps and wall time to min-var's validation level")
        rows = reach(args.results, env, lambda line: _progress(t0, line), compute=args.min_var_level)
        if rows:
            levels[env] = rows
    text += reach_table(levels)
    for a in analyses:
        a["min_var_level"] = levels.get(a["env_id"])
    atomic_write_text(out / "report.md", text)
    write_json_atomic(
        out / "report.json",
        [{k: v for k, v in a.items() if not k.startswith("_") and not (k == "set_aside" and not v)} for a in analyses],
    )
    written = [out / "report.md", out / "report.json", *written]
    print(text)
    _progress(t0, f"wrote {len(written)} files:")
    for path in written:
        print(f"wrote: {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
