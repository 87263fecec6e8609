r"""Learning curves from run directories' ``eval.csv``: the task's panels vs timesteps.

The panels are the run's task's (``Task.metrics.curves``: the success rate and median steps on the
localisation tasks, the capture rate and mean tracking error on the moving target), the run's env read from
the ``summary.json`` the training callback writes beside ``eval.csv``; the title names the env.

Each run is one line (no interval: one seed per run); ``rl_zoo3.plots`` draws the training monitor's
returns, not the benchmark's readings on seeded validation episodes that ``eval.csv`` holds, hence this
short plot. Aggregates over seeds with intervals are the learned report's (rliable's curves).

Usage::

    python -m electroloc_gym.train.curves runs/ppo-s1000 runs/ppo-s2000 --labels "seed 1000" "seed 2000" \
        --out electroloc_gym/models/ppo-belief/learning_curves.png [--reference min-var=0.58,7]
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["REQUIRED_COLUMNS", "read_eval_csv", "run_env_id", "plot_learning_curves", "main"]


#: The columns every reader of an ``eval.csv`` needs (the callback writes ``EVAL_FIELDS``, a superset).
REQUIRED_COLUMNS = ("timesteps", "success_rate", "mean_readings", "median_readings")


def read_eval_csv(path: str | Path) -> dict[str, list[float]]:
    """Columns of an ``eval.csv`` (a run directory or the file itself) as lists of finite floats: the one
    reader of the evaluation logs :class:`~electroloc_gym.train.callbacks.BenchEvalCallback` writes (the
    learning curves here and the learned report read through it).

    Raises:
        ValueError: one line naming the file: missing, empty, not UTF-8 CSV, a column of
            :data:`REQUIRED_COLUMNS` missing, or a cell that is not a finite number.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "eval.csv"
    if not p.is_file():
        raise ValueError(f"no eval.csv at {str(path)!r}")
    try:
        with p.open(encoding="utf-8", newline="") as fh:
            rows = list(csv.DictReader(fh))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"{p}: not a readable evaluation log ({type(exc).__name__}: {exc})") from None
    if not rows:
        raise ValueError(f"{p}: not a readable evaluation log (no rows)")
    missing = [k for k in REQUIRED_COLUMNS if k not in rows[0]]
    if missing:
        raise ValueError(f"{p}: not a readable evaluation log (missing column(s) {missing})")
    cols: dict[str, list[float]] = {}
    for k in rows[0]:
        try:
            cols[k] = [float(r[k]) for r in rows]
        except (TypeError, ValueError):
            raise ValueError(f"{p}: not a readable evaluation log (a non-number in column {k!r})") from None
        if not all(math.isfinite(v) for v in cols[k]):
            raise ValueError(f"{p}: not a readable evaluation log (a non-finite evaluation in column {k!r})")
    return cols


def run_env_id(run: str | Path) -> str | None:
    """The env id of a run (a run directory or its eval.csv) from the callback's ``summary.json`` beside it
    (None: no readable one).
    """
    from electroloc_gym.train.summary import read_summary

    p = Path(run)
    try:
        return read_summary((p if p.is_dir() else p.parent) / "summary.json").env_id
    except ValueError:
        return None


def _panels(env_ids: Sequence[str]) -> Any:
    """The curve panels of the runs' task (one env: its task's; none known: the localisation panels)."""
    from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
    from electroloc_gym.registry import ENVS

    if len(set(env_ids)) > 1:
        raise ValueError(f"the runs are of different envs {sorted(set(env_ids))}; plot one env's runs at a time")
    metrics = next((e.task_class.metrics for e in ENVS if e.env_id in env_ids), LOCALIZATION_METRICS)
    return metrics.curves


def plot_learning_curves(
    runs: Sequence[str | Path],
    labels: Sequence[str] | None,
    out: str | Path,
    references: Mapping[str, Sequence[float]] | None = None,
) -> Path:
    """The task's panels (module docstring; two on the built-in tasks) vs env steps for each run; written
    atomically as PNG.

    Args:
        runs: run directories (or eval.csv files).
        labels: one label per run (default: the directory names).
        out: the PNG path.
        references: optional horizontal lines, name → one value per panel (the localisation tasks: success
            rate, median steps).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from electroloc_gym.utils.fileio import atomic_write_bytes

    labels = list(labels) if labels else [Path(r).name for r in runs]
    if len(labels) != len(runs):
        raise ValueError(f"--labels needs one label per run ({len(runs)}), got {len(labels)}")
    env_ids = [e for e in (run_env_id(r) for r in runs) if e is not None]
    panels = _panels(env_ids)
    for name, values in (references or {}).items():
        if len(values) != len(panels):
            raise ValueError(f"reference {name!r} needs one value per panel ({len(panels)}), got {len(values)}")
    data = [read_eval_csv(run) for run in runs]
    for run, d in zip(runs, data):
        absent = [p.key for p in panels if p.key not in d]
        if absent:
            raise ValueError(f"{run}: the evaluation log has no column(s) {absent} (written by an older callback?)")
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.8), squeeze=False)
    axes = list(axes[0])
    for d, label in zip(data, labels):
        for ax, panel in zip(axes, panels):
            ax.plot(d["timesteps"], d[panel.key], marker=".", label=label)
    for i, (name, values) in enumerate((references or {}).items()):
        style = dict(color=f"C{7 + i % 3}", ls="--", lw=1)
        for ax, v in zip(axes, values):
            ax.axhline(v, **style, label=name)
    for ax, panel in zip(axes, panels):
        ax.set(xlabel="env steps", ylabel=panel.label)
        if panel.ylim is not None:
            ax.set_ylim(*panel.ylim)
        ax.grid(alpha=0.3)
    axes[-1].legend(fontsize=8)
    title = ", ".join(dict.fromkeys(env_ids)) or "env unknown: no summary.json beside eval.csv"
    fig.suptitle(f"Seeded evaluation during training ({title})", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(out, buf.getvalue())
    return Path(out)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point."""
    p = argparse.ArgumentParser(
        prog="python -m electroloc_gym.train.curves",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("runs", nargs="+", help="run directories (or eval.csv files)")
    p.add_argument("--labels", nargs="*", default=None)
    p.add_argument("--out", default="learning_curves.png")
    p.add_argument(
        "--reference",
        nargs="*",
        default=[],
        metavar="NAME=V1,V2",
        help="horizontal reference lines, one value per panel (localisation: success rate, median steps), "
        "e.g. min-var=0.58,7",
    )
    a = p.parse_args(argv)
    from electroloc_gym.utils.fileio import check_output_options

    check_output_options(p, files={"--out": a.out})
    refs = {}
    for item in a.reference:
        name, _, vals = item.partition("=")
        try:
            refs[name] = tuple(float(v) for v in vals.split(","))
        except ValueError:
            print(f"error: --reference expects NAME=V1,V2 (one number per panel), got {item!r}", file=sys.stderr)
            return 2
    try:
        path = plot_learning_curves(a.runs, a.labels, a.out, refs)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
