r"""Learning curves from run directories' ``eval.csv``: success rate and median steps vs timesteps.

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

__all__ = ["REQUIRED_COLUMNS", "read_eval_csv", "plot_learning_curves", "main"]


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


def plot_learning_curves(
    runs: Sequence[str | Path],
    labels: Sequence[str] | None,
    out: str | Path,
    references: Mapping[str, tuple[float, float]] | None = None,
) -> Path:
    """Two panels (success rate, median steps) vs env steps for each run; written atomically as PNG.

    Args:
        runs: run directories (or eval.csv files).
        labels: one label per run (default: the directory names).
        out: the PNG path.
        references: optional horizontal lines, name → (success rate, median steps).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from electroloc_gym.utils.fileio import atomic_write_bytes

    labels = list(labels) if labels else [Path(r).name for r in runs]
    if len(labels) != len(runs):
        raise ValueError(f"--labels needs one label per run ({len(runs)}), got {len(labels)}")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    for run, label in zip(runs, labels):
        d = read_eval_csv(run)
        ax1.plot(d["timesteps"], d["success_rate"], marker=".", label=label)
        ax2.plot(d["timesteps"], d["median_readings"], marker=".", label=label)
    for i, (name, (succ, steps)) in enumerate((references or {}).items()):
        style = dict(color=f"C{7 + i % 3}", ls="--", lw=1)
        ax1.axhline(succ, **style, label=name)
        ax2.axhline(steps, **style, label=name)
    ax1.set(xlabel="env steps", ylabel="success rate (spread ≤ 10 mm within 35 obs.)", ylim=(0, 1.02))
    ax2.set(xlabel="env steps", ylabel="median readings to localise", ylim=(0, 36))
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    fig.suptitle("Seeded evaluation during training (ElectroLoc-v0, 8 conditions)", fontsize=10)
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
        metavar="NAME=SUCCESS,STEPS",
        help="horizontal reference lines, e.g. min-var=0.58,7",
    )
    a = p.parse_args(argv)
    from electroloc_gym.utils.fileio import check_output_options

    check_output_options(p, files={"--out": a.out})
    refs = {}
    for item in a.reference:
        name, _, vals = item.partition("=")
        try:
            s, st = (float(v) for v in vals.split(","))
        except ValueError:
            print(f"error: --reference expects NAME=SUCCESS,STEPS, got {item!r}", file=sys.stderr)
            return 2
        refs[name] = (s, st)
    try:
        path = plot_learning_curves(a.runs, a.labels, a.out, refs)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
