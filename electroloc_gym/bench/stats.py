"""Statistics of benchmark trials, following the paper's Appendix B.

Appendix B (Table 4):

* **Success (failure)**: trials that reached √trace Σ ≤ 10 mm within 35 observations (and the rest).
* **Mean error and mean steps** omit every start position on which *either* controller failed
  ("if either controller yielded a failure trial, then data from these trials was omitted in
  calculating the mean error and the mean number of steps"): here, a trial index counts for the
  means only if every Table-4 agent of the run succeeded on it (``*_paired`` keys; with a single
  Table-4 agent this is its own successes).
* **Medians use all trials**, failures included (a failure's steps are the 35 observations it used,
  its error is that of its final estimate).
* **"All conditions"**: the paper's row averages the eight per-condition statistics (check: rnd-wlk
  median steps (9 + 10 + 23.5 + 9.5 + 11 + 8.5 + 13 + 14.5)/8 = 12.4, min-var
  (5 + 6 + 6.5 + 5 + 7 + 5 + 6.5 + 12.5)/8 = 6.7 — the paper's 12.4 and 6.7), with summed counts.
  Pooled medians over all trials are given too (``*_pooled`` keys).

A task's own statistics (``Task.metrics.statistics``, :mod:`electroloc_gym.contract.task_spec`) follow in
every row: per condition over the condition's trials, in the "all" rows over the agent's pooled trials. The
row keys, the per-agent means and Table 1's (zero-crossing) included: docs/benchmark.md, ``summary.json``
schema.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from electroloc_gym.bench.schema import is_far_success
from electroloc_gym.contract.task_spec import TaskMetrics
from electroloc_gym.utils.agentspec import is_path_like

__all__ = ["summarize", "agent_label", "records_metrics", "RULES"]

RULES = (
    "Appendix B: success (failure) counts; mean error and mean steps over the start positions on which every "
    "Table-4 agent succeeded (*_paired; error_mean_mm/readings_mean: the agent's own successes); medians over all "
    "trials, failures included; 'all' rows average the per-condition statistics as the paper's 'All conditions' "
    "row does (pooled medians in *_pooled). steps = observations fused (info['n_observations'])."
)


def _num(values: Iterable[Any]) -> np.ndarray:
    return np.asarray([float(v) for v in values if v is not None], dtype=float)


def _mean(values: Iterable[Any]) -> float | None:
    a = _num(values)
    return float(a.mean()) if a.size else None


def _median(values: Iterable[Any]) -> float | None:
    a = _num(values)
    return float(np.median(a)) if a.size else None


def agent_label(agent: str, recs: Sequence[dict[str, Any]]) -> str:
    """Table label: the spec for built-in agents (``min-var[n_voters=None]``), the policy's name for paths."""
    return str(recs[0].get("agent_label", agent)) if (is_path_like(agent) and recs) else agent


def _row(
    condition: str, agent: str, recs: list[dict[str, Any]], paired: set[int], metrics: TaskMetrics
) -> dict[str, Any]:
    ok = [r for r in recs if r["success"]]
    pair = [r for r in recs if int(r["trial"]) in paired]
    row: dict[str, Any] = {
        "condition": condition,
        "agent": agent,
        "label": agent_label(agent, recs),
        "table_layout": recs[0].get("table_layout", "table4") if recs else "table4",
        "trials": len(recs),
        "successes": len(ok),
        "failures": len(recs) - len(ok),
        "error_mean_mm": _mean(r["error_mm"] for r in ok),
        "error_median_mm": _median(r["error_mm"] for r in recs),
        "readings_mean": _mean(r["readings"] for r in ok),
        "readings_median": _median(r["readings"] for r in recs),
        "decision_ms_median": _median(r.get("decision_ms_median") for r in recs),
        "paired_trials": len(pair),
        "error_mean_paired_mm": _mean(r["error_mm"] for r in pair),
        "readings_mean_paired": _mean(r["readings"] for r in pair),
        "error_x_mean_abs_mm": _mean(abs(r["error_x_mm"]) for r in ok if r.get("error_x_mm") is not None),
        "error_y_mean_abs_mm": _mean(abs(r["error_y_mm"]) for r in ok if r.get("error_y_mm") is not None),
    }
    est = np.asarray([r["estimate"] for r in ok if r.get("estimate") is not None], dtype=float).reshape(-1, 2)
    dev = np.abs(est - est.mean(axis=0)) if est.shape[0] else None
    for i, axis in enumerate("xy"):
        row[f"error_{axis}_repeatability_mm"] = None if dev is None else float(dev[:, i].mean())
    row.update(metrics.statistics(recs))
    return row


def records_metrics(records: Sequence[dict[str, Any]]) -> TaskMetrics:
    """The metrics of the task the records were run on: their env's (the first record's ``env_id``); an env id
    the table does not hold: the registered task whose record fields the records' ``shape`` holds, else the
    paper's localisation metrics.
    """
    from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
    from electroloc_gym.registry import ENVS

    if not records:
        return LOCALIZATION_METRICS
    env_id = records[0].get("env_id")
    for e in ENVS:
        if e.env_id == env_id:
            return e.task_class.metrics
    shape = records[0].get("shape")
    return next(
        (e.task_class.metrics for e in ENVS if shape and e.task_class.metrics.accepts_record(shape)),
        LOCALIZATION_METRICS,
    )


def summarize(
    records: Sequence[dict[str, Any]],
    agents: Sequence[str] | None = None,
    conditions: Sequence[str] | None = None,
    metrics: TaskMetrics | None = None,
) -> dict[str, Any]:
    """Rows per condition × agent plus ``"condition": "all"`` rows (see the module docstring).

    Args:
        records: trial records (``run_trial`` output / trials.jsonl lines).
        agents: agent order (default: order of first appearance).
        conditions: condition order (default: order of first appearance).
        metrics: the task's metrics (default: :func:`records_metrics`), whose statistics every row adds.

    Returns:
        ``{"rules", "agents", "conditions", "rows"}``, the rows' keys as docs/benchmark.md lists them; a
        missing statistic is None (JSON null), never NaN.
    """
    metrics = records_metrics(records) if metrics is None else metrics
    agents = list(dict.fromkeys(agents if agents is not None else [r["agent"] for r in records]))
    conditions = list(dict.fromkeys(conditions if conditions is not None else [r["condition"] for r in records]))
    by: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in records:
        by.setdefault((r["condition"], r["agent"]), []).append(r)
    for recs in by.values():
        recs.sort(key=lambda r: int(r["trial"]))
    table_layout = {
        a: next((r.get("table_layout", "table4") for r in records if r["agent"] == a), "table4") for a in agents
    }
    table4 = [a for a in agents if table_layout[a] == "table4"]
    rows: list[dict[str, Any]] = []
    per_agent: dict[str, list[dict[str, Any]]] = {a: [] for a in agents}
    for c in conditions:
        # App. B pairing: trial indices on which every Table-4 agent succeeded.
        succ_sets = [{int(r["trial"]) for r in by.get((c, a), []) if r["success"]} for a in table4]
        paired_t4 = set.intersection(*succ_sets) if succ_sets else set()
        for a in agents:
            recs = by.get((c, a), [])
            if not recs:
                continue
            paired = paired_t4 if table_layout[a] == "table4" else {int(r["trial"]) for r in recs if r["success"]}
            row = _row(c, a, recs, paired, metrics)
            rows.append(row)
            per_agent[a].append(row)
    for a in agents:
        crow = per_agent[a]
        if not crow:
            continue
        recs = [r for c in conditions for r in by.get((c, a), [])]
        rows.append(
            {
                "condition": "all",
                "agent": a,
                "label": crow[0]["label"],
                "table_layout": table_layout[a],
                "conditions": len(crow),
                **{k: sum(r[k] for r in crow) for k in ("trials", "successes", "failures")},
                **{
                    k: _mean(r[k] for r in crow)
                    for k in ("error_mean_mm", "error_median_mm", "readings_mean", "readings_median")
                },
                "decision_ms_median": _median(r.get("decision_ms_median") for r in recs),
                "paired_trials": sum(r["paired_trials"] for r in crow),
                **{k: _mean(r[k] for r in crow) for k in ("error_mean_paired_mm", "readings_mean_paired")},
                "error_median_pooled_mm": _median(r["error_mm"] for r in recs),
                "readings_median_pooled": _median(r["readings"] for r in recs),
                "far_successes": sum(is_far_success(r["success"], r["error_mm"]) for r in recs),
                **{k: _mean(r[k] for r in crow) for k in ("error_x_mean_abs_mm", "error_y_mean_abs_mm")},
                **metrics.statistics(recs),  # pooled over the conditions' trials
            }
        )
    return {"rules": RULES, "agents": agents, "conditions": conditions, "rows": rows}
