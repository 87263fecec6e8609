"""steps.png in the style of the paper's Fig. 12: failures and median steps per condition and agent."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from electroloc_gym.bench.tables import PAPER_TABLE4, _cond_label, paper_agent_key

__all__ = ["plot_steps", "steps_png"]


def plot_steps(summary: dict[str, Any], path: str | os.PathLike[str]) -> None:
    """:func:`steps_png` written atomically to ``path``."""
    from electroloc_gym.utils.fileio import atomic_write_bytes

    atomic_write_bytes(path, steps_png(summary))


def steps_png(summary: dict[str, Any]) -> bytes:
    """Two bar charts (failed trials; median steps) per condition, one bar per Table-4 agent, as PNG bytes.

    The paper's Fig. 12 values (rnd-wlk, min-var) are drawn as black ticks on the matching bars (its
    failure counts, out of 50 trials, scaled to this run's trial count).
    """
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    rows = [r for r in summary["rows"] if r.get("table_layout", "table4") == "table4" and r["condition"] != "all"]
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    agents = list(dict.fromkeys(r["agent"] for r in rows))
    fig, axes = plt.subplots(2, 1, figsize=(max(6.0, 1.3 * len(conditions) + 2), 6.5), sharex=True)
    if not rows:
        for ax in axes:
            ax.text(0.5, 0.5, "no Table-4 agents in this run", ha="center", va="center", transform=ax.transAxes)
        fig.savefig(buf, format="png", dpi=110)
        plt.close(fig)
        return buf.getvalue()
    x = np.arange(len(conditions))
    width = 0.8 / max(1, len(agents))
    lookup = {(r["condition"], r["agent"]): r for r in rows}
    table4_agents = {a for _, a in PAPER_TABLE4}  # the paper's agents with Table-4 (Fig. 12) values
    for j, agent in enumerate(agents):
        label = next((r.get("label", agent) for r in rows if r["agent"] == agent), agent)
        fails = [lookup.get((c, agent), {}).get("failures", np.nan) for c in conditions]
        med = [lookup.get((c, agent), {}).get("readings_median", np.nan) for c in conditions]
        xs = x - 0.4 + width * (j + 0.5)
        axes[0].bar(xs, [np.nan if v is None else v for v in fails], width, label=label)
        axes[1].bar(xs, [np.nan if v is None else v for v in med], width, label=label)
        key = paper_agent_key(agent)
        if key in table4_agents:
            n_trials = summary.get("config", {}).get("trials") or 50
            # the paper ran 50 trials per condition: scale its failure counts to this run's trial count
            pf = [PAPER_TABLE4.get((c, key), (None, np.nan))[1] * n_trials / 50 for c in conditions]
            pm = [PAPER_TABLE4.get((c, key), (None,) * 5 + (np.nan,))[5] for c in conditions]
            kw = {"marker": "_", "color": "k", "markersize": 14, "linestyle": "none", "markeredgewidth": 2}
            axes[0].plot(xs, pf, **kw, label="paper (Fig. 12)" if j == 0 else None)
            axes[1].plot(xs, pm, **kw)
    axes[0].set_ylabel("failed trials")
    axes[1].set_ylabel("median steps")
    n = summary.get("config", {}).get("trials")
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
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()
