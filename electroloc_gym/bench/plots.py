"""The benchmark's figures: steps.png and conditions.png, rendered from a run's summary.json.

* ``steps.png``, in the style of the paper's Fig. 12: failures and median steps per condition and agent.
* ``conditions.png``: every metric of the run's table per condition and agent, each with its interval where it
  has one, read from the declarations: the localisation table's success rate (with its 90 % Wilson interval,
  the paper's confidence, and the paper's Table-4 rate as a tick) and median readings — unless the task's own
  table replaces the localisation tables —, then one panel per declared column of the task's own table
  (``Task.metrics.columns``) that has a direction (``better``), its interval from ``Column.interval``; a column
  that restates another panel's statistic (a count beside its rate) adds none. The pooled *all* rows come last.
"""

from __future__ import annotations

import io
import os
import string
from dataclasses import dataclass
from typing import Any

import numpy as np

from electroloc_gym.bench.fidelity import CONFIDENCE, wilson_interval
from electroloc_gym.bench.tables import PAPER_TABLE4, _cond_label, _summary_metrics, paper_agent_key
from electroloc_gym.contract.task_spec import Column, TaskMetrics
from electroloc_gym.utils.fileio import atomic_write_bytes

__all__ = ["plot_steps", "steps_png", "plot_conditions", "conditions_png", "condition_panels"]


def _pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any) -> bytes:
    """``fig`` as PNG bytes; the figure is closed."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    _pyplot().close(fig)
    return buf.getvalue()


def plot_steps(summary: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """:func:`steps_png` written atomically to ``path``."""
    atomic_write_bytes(path, steps_png(summary))


def steps_png(summary: dict[str, Any]) -> bytes:
    """Two bar charts (failed trials; median steps) per condition, one bar per Table-4 agent, as PNG bytes.

    The paper's Fig. 12 values (rnd-wlk, min-var) are drawn as black ticks on the matching bars (its
    failure counts, out of 50 trials, scaled to this run's trial count).
    """
    plt = _pyplot()
    rows = [r for r in summary["rows"] if r.get("table_layout", "table4") == "table4" and r["condition"] != "all"]
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    agents = list(dict.fromkeys(r["agent"] for r in rows))
    fig, axes = plt.subplots(2, 1, figsize=(max(6.0, 1.3 * len(conditions) + 2), 6.5), sharex=True)
    if not rows:
        for ax in axes:
            ax.text(0.5, 0.5, "no Table-4 agents in this run", ha="center", va="center", transform=ax.transAxes)
        return _png(fig)
    x = np.arange(len(conditions))
    width = 0.8 / max(1, len(agents))
    lookup = {(r["condition"], r["agent"]): r for r in rows}
    n = summary.get("config", {}).get("trials")
    table4_agents = {a for _, a in PAPER_TABLE4}  # the paper's agents with Table-4 (Fig. 12) values
    for j, agent in enumerate(agents):
        label = next((r.get("label", agent) for r in rows if r["agent"] == agent), agent)
        xs = x - 0.4 + width * (j + 0.5)
        for ax, stat in zip(axes, ("failures", "readings_median"), strict=True):
            ax.bar(xs, [_value(lookup.get((c, agent)), stat) for c in conditions], width, label=label)
        key = paper_agent_key(agent)
        if key in table4_agents:
            # the paper ran 50 trials per condition: scale its failure counts to this run's trial count
            pf = [PAPER_TABLE4.get((c, key), (None, np.nan))[1] * (n or 50) / 50 for c in conditions]
            pm = [PAPER_TABLE4.get((c, key), (None,) * 5 + (np.nan,))[5] for c in conditions]
            kw = {"marker": "_", "color": "k", "markersize": 14, "linestyle": "none", "markeredgewidth": 2}
            axes[0].plot(xs, pf, **kw, label="paper (Fig. 12)" if j == 0 else None)
            axes[1].plot(xs, pm, **kw)
    axes[0].set_ylabel("failed trials")
    axes[1].set_ylabel("median steps")
    axes[0].set_title(
        f"Failed trials and median steps ({n} trials per condition and agent)\n"
        f"black ticks: paper's Fig. 12 (failures scaled to {n} trials)",
        fontsize=10,
    )
    axes[1].set_xticks(x)
    axes[1].set_xticklabels([" ".join(_cond_label(c)) for c in conditions], rotation=30, ha="right")
    axes[0].legend(fontsize=8, ncol=min(4, len(agents) + 1))
    for ax in axes:
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _png(fig)


@dataclass(frozen=True)
class Panel:
    """One panel of conditions.png: the statistic ``key`` of the summary's rows per condition and agent, with
    its interval's (lo, hi) keys where it has one; ``percent``: a fraction drawn as a percentage; ``rows``:
    ``"table4"`` (the localisation table's rows) or the task table's count key (the rows that hold it).
    """

    key: str
    label: str
    interval: tuple[str, str] | None = None
    percent: bool = False
    rows: str = "table4"


#: The localisation table's panels (success's interval is computed from the counts, :func:`_success`).
SUCCESS_KEY = "success_rate"
_LOCALISATION_PANELS = (
    Panel(SUCCESS_KEY, f"success rate (%), {CONFIDENCE:.0%} Wilson interval", ("success_lo", "success_hi"), True),
    Panel("readings_median", "median readings"),
)


def _percent_fields(column: Column) -> set[str]:
    """The fields a column's format writes as percentages (``!p``)."""
    return {f for _, f, _, conv in string.Formatter().parse(column.format) if f and conv == "p"}


def condition_panels(metrics: TaskMetrics) -> tuple[Panel, ...]:
    """The panels of a task's conditions.png, from its declaration (module docstring)."""
    table = metrics.table
    panels: list[Panel] = [] if table is not None and table.replaces else list(_LOCALISATION_PANELS)
    if table is None:
        return tuple(panels)
    directed = [c for c in metrics.columns if c.better is not None]
    keys = {c.key for c in directed}
    for column in directed:
        if any(p.key == column.key for p in panels):
            continue
        if (set(column.keys()) - {column.key}) & keys:  # a restatement of another plotted statistic
            continue
        same = [c for c in metrics.columns if c.key == column.key]
        lo_hi = next((c for c in same if c.interval), None)
        percent = any(
            column.key in _percent_fields(c) or (c.interval and set(c.interval) & _percent_fields(c)) for c in same
        )
        label = column.header + (" (%)" if percent and "%" not in column.header else "")
        if lo_hi is not None and lo_hi.header != column.header:
            label += f", {lo_hi.header}"
        interval = None if lo_hi is None else lo_hi.interval
        panels.append(Panel(column.key, label, interval, bool(percent), table.count))
    return tuple(panels)


def _success(row: dict[str, Any]) -> dict[str, Any]:
    """A localisation row with its success rate and the rate's Wilson interval."""
    n = int(row.get("successes") or 0) + int(row.get("failures") or 0)
    if n <= 0:
        return row
    lo, hi = wilson_interval(int(row["successes"]), n)
    return {**row, SUCCESS_KEY: int(row["successes"]) / n, "success_lo": lo, "success_hi": hi}


def _value(row: dict[str, Any] | None, key: str) -> float:
    v = None if row is None else row.get(key)
    return np.nan if v is None else float(v)


def plot_conditions(summary: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """:func:`conditions_png` written atomically to ``path``."""
    atomic_write_bytes(path, conditions_png(summary))


def conditions_png(summary: dict[str, Any]) -> bytes:
    """conditions.png (module docstring) as PNG bytes: one panel per statistic, conditions along x (the pooled
    *all* rows last), one marker per agent with its interval as an error bar.
    """
    plt = _pyplot()
    metrics = _summary_metrics(summary)
    panels = condition_panels(metrics)
    all_rows = [_success(r) for r in summary["rows"]]

    def rows_of(panel: Panel) -> list[dict[str, Any]]:
        if panel.rows == "table4":
            return [
                r for r in all_rows if r.get("table_layout", "table4") == "table4" and r.get("successes") is not None
            ]
        return [r for r in all_rows if r.get(panel.rows)]

    drawn = [(p, rows_of(p)) for p in panels]
    drawn = [(p, rows) for p, rows in drawn if rows]
    cfg = summary.get("config", {})
    if not drawn:
        fig, ax = plt.subplots(figsize=(6.0, 2.5))
        ax.text(0.5, 0.5, "no per-condition statistics in this run", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return _png(fig)
    conditions = list(dict.fromkeys(r["condition"] for _, rows in drawn for r in rows if r["condition"] != "all"))
    if any(r["condition"] == "all" for _, rows in drawn for r in rows):
        conditions.append("all")
    agents = list(dict.fromkeys(r["agent"] for _, rows in drawn for r in rows))
    labels = {r["agent"]: r.get("label", r["agent"]) for _, rows in drawn for r in rows}
    x = np.arange(len(conditions))
    width = 0.8 / max(1, len(agents))
    fig, axes = plt.subplots(
        len(drawn),
        1,
        figsize=(max(6.5, 1.1 * len(conditions) + 2.5), 2.6 * len(drawn) + 1.0),
        sharex=True,
        squeeze=False,
    )
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    paper_ticks = False
    for ax, (panel, rows) in zip(axes[:, 0], drawn, strict=True):
        scale = 100.0 if panel.percent else 1.0
        lookup = {(r["condition"], r["agent"]): r for r in rows}
        for j, agent in enumerate(agents):
            xs = x - 0.4 + width * (j + 0.5)
            cells = [lookup.get((c, agent)) for c in conditions]
            ys = np.array([_value(r, panel.key) for r in cells]) * scale
            color = colors[j % len(colors)]
            if panel.interval:
                lo, hi = (np.array([_value(r, k) for r in cells]) * scale for k in panel.interval)
                err = np.vstack([np.where(np.isnan(lo), 0.0, ys - lo), np.where(np.isnan(hi), 0.0, hi - ys)])
                ax.errorbar(
                    xs, ys, yerr=np.clip(err, 0.0, None), fmt="o", color=color, capsize=3, ms=5, label=labels[agent]
                )
            else:
                ax.plot(xs, ys, "o", color=color, ms=5, label=labels[agent])
            key = paper_agent_key(agent)
            if key is not None and panel.key == SUCCESS_KEY and any((c, key) in PAPER_TABLE4 for c in conditions):
                paper = [PAPER_TABLE4.get((c, key)) for c in conditions]
                py = [np.nan if p is None else 100.0 * p[0] / (p[0] + p[1]) for p in paper]
                ax.plot(xs, py, "_", color="k", ms=12, mew=2, label=None if paper_ticks else "paper (Table 4)")
                paper_ticks = True
        ax.set_ylabel(panel.label, fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        if len(conditions) > 1 and conditions[-1] == "all":
            ax.axvline(len(conditions) - 1.5, color="0.6", lw=0.8, ls=":")
    axes[0, 0].legend(fontsize=7, ncol=min(4, len(agents) + 1), loc="best")
    axes[0, 0].set_title(
        f"{cfg.get('env_id', '')}: per condition and agent, {cfg.get('trials')} trials each (bars: intervals)",
        fontsize=10,
    )
    axes[-1, 0].set_xticks(x)
    axes[-1, 0].set_xticklabels(
        ["all (pooled)" if c == "all" else " ".join(_cond_label(c)) for c in conditions], rotation=30, ha="right"
    )
    fig.tight_layout()
    return _png(fig)
