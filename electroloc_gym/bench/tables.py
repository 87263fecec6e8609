"""Markdown tables in the paper's layouts (Table 4, Table 1) with the paper's numbers beside ours.

The aggregate row of an agent is the paper's *All conditions* row (with the paper's totals beside
it) only when the agent ran all eight of the paper's conditions; over fewer it is labelled
*Subset (k conditions)* and has no paper values, since the paper's totals are over all eight.

A task's own statistics are laid out by its declaration (``Task.metrics``: its :class:`Column` s and
:class:`Table`, :mod:`electroloc_gym.contract.task_spec`) in one renderer (:func:`task_table_lines`): a
section after the Table-4 layout, or the whole document for a task without a success criterion.
"""

from __future__ import annotations

from functools import cache
from typing import Any

from electroloc_gym.baselines.agent import PAPER_AGENTS
from electroloc_gym.bench.fidelity import PAPER_TRIALS, UNTESTED, interval_mark, wilson_interval
from electroloc_gym.bench.schema import FAR_ERROR_MM
from electroloc_gym.bench.stats import records_metrics
from electroloc_gym.contract.task_spec import TaskMetrics, format_config_text
from electroloc_gym.registry import ENVS
from electroloc_gym.utils.agentspec import parse_agent_spec
from electroloc_gym.utils.markdown import markdown_table
from electroloc_gym.world.conditions import PRESET_NAMES

__all__ = [
    "PAPER_TABLE4",
    "PAPER_TABLE4_ALL",
    "PAPER_TABLE1",
    "PAPER_TABLE2",
    "render_table_md",
    "paper_agent_key",
    "aggregate_label",
    "is_all_conditions",
    "task_table_lines",
]

# Table 4 (App. B): (successes, failures, error mean, error median (mm), steps mean, steps median).
PAPER_TABLE4: dict[tuple[str, str], tuple[int, int, float, float, float, float]] = {
    ("fresh-steel-12.7", "rnd-wlk"): (41, 9, 2.0, 1.5, 10, 9),
    ("fresh-steel-12.7", "min-var"): (50, 0, 1.7, 1.1, 10, 5),
    ("fresh-delrin-12.7", "rnd-wlk"): (35, 15, 2.1, 2.0, 9, 10),
    ("fresh-delrin-12.7", "min-var"): (50, 0, 1.5, 1.1, 10, 6),
    ("fresh-steel-38.1", "rnd-wlk"): (32, 18, 2.2, 2.8, 15, 23.5),
    ("fresh-steel-38.1", "min-var"): (44, 6, 1.4, 1.5, 9, 6.5),
    ("fresh-delrin-38.1", "rnd-wlk"): (35, 15, 2.4, 2.8, 10, 9.5),
    ("fresh-delrin-38.1", "min-var"): (49, 1, 2.2, 2.4, 9, 5),
    ("salt-steel-12.7", "rnd-wlk"): (35, 15, 4.3, 4.9, 11, 11),
    ("salt-steel-12.7", "min-var"): (49, 1, 3.9, 3.7, 10, 7),
    ("salt-delrin-12.7", "rnd-wlk"): (41, 9, 2.3, 2.2, 10, 8.5),
    ("salt-delrin-12.7", "min-var"): (50, 0, 2.7, 1.9, 7, 5),
    ("salt-steel-38.1", "rnd-wlk"): (37, 13, 1.1, 1.0, 10, 13),
    ("salt-steel-38.1", "min-var"): (45, 5, 1.3, 1.0, 11, 6.5),
    ("salt-delrin-38.1", "rnd-wlk"): (31, 19, 3.1, 4.9, 11, 14.5),
    ("salt-delrin-38.1", "min-var"): (44, 6, 2.9, 2.8, 11, 12.5),
}
#: Table 4's "All conditions" rows.
PAPER_TABLE4_ALL: dict[str, tuple[int, int, float, float, float, float]] = {
    "rnd-wlk": (287, 113, 2.4, 2.8, 10.8, 12.4),
    "min-var": (381, 19, 2.2, 1.9, 9.7, 6.7),
}
#: Table 1: zero-crossing mean absolute error (x, y), mm, 50 trials per condition.
PAPER_TABLE1: dict[str, tuple[float, float]] = {
    "fresh-steel-12.7": (0.06, 0.39),
    "fresh-delrin-12.7": (0.05, 0.64),
    "fresh-steel-38.1": (0.05, 0.93),
    "fresh-delrin-38.1": (0.06, 0.89),
    "salt-steel-12.7": (0.23, 0.47),
    "salt-delrin-12.7": (0.14, 0.59),
    "salt-steel-38.1": (0.06, 0.78),
    "salt-delrin-38.1": (0.05, 0.69),
}

#: Table 2 (§6.5, global self-localisation among six cylinders): (successes, failures, error mean,
#: error median (mm), steps mean, steps median).
PAPER_TABLE2: dict[str, tuple[int, int, float, float, float, float]] = {
    "rnd-wlk": (48, 2, 1.3, 1.0, 11.8, 11.0),
    "min-var": (49, 1, 1.4, 0.8, 6.9, 6.0),
}

_WATER = {"fresh": "Fresh", "salt": "Salt"}
_MATERIAL = {"steel": "steel", "delrin": "Delrin"}


def paper_agent_key(agent: str) -> str | None:
    """The paper's controller an agent spec corresponds to (``min-var[n_voters=2500]`` → ``min-var``)."""
    try:
        base = parse_agent_spec(agent).name
    except ValueError:  # a policy path
        return None
    return base if base in PAPER_AGENTS else None


def _cond_label(name: str) -> tuple[str, str]:
    if name.count("-") != 2:  # not a preset (e.g. the global-localisation map "six-cylinders")
        return name, ""
    water, material, diam = name.split("-")
    return _WATER.get(water, water), f"{diam}/{_MATERIAL.get(material, material)}"


def _f(x: Any, digits: int = 1) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _paper_cells(paper: tuple | None, row: dict[str, Any]) -> tuple[str, str, str]:
    """The paper's success (failure), error mean/median and steps mean/median cells ("" when absent); the
    success cell also gives the paper's 90 % binomial interval as counts of the run's trials and marks the
    run's count ✓ (inside) or ✗ (outside).
    """
    if not paper:
        return "", "", ""
    mark = _interval_mark(paper, row)
    success = f"{paper[0]}({paper[1]}) {mark}" if mark else f"{paper[0]}({paper[1]})"
    return success, _pair(paper[2], paper[3]), f"{paper[4]:g}/{paper[5]:g}"


def _decisive_trials(paper_successes: int, paper_trials: int) -> int:
    """The fewest trials N at which some count of N has its own 90 % Wilson interval disjoint from the paper's
    90 % interval of ``paper_successes`` of ``paper_trials``: with fewer, no outcome of the run can disagree
    with the paper beyond the run's own sampling noise, and a ✓/✗ against the paper's interval decides nothing.
    """
    lo, hi = wilson_interval(paper_successes, paper_trials)
    n = 1
    while not any(own[1] < lo or own[0] > hi for own in (wilson_interval(k, n) for k in range(n + 1))):
        n += 1
    return n


@cache
def verdict_min_trials() -> int:
    """The fewest trials per cell for a ✓/✗ against the paper's interval: :func:`_decisive_trials` of every
    paper count the tables mark (Tables 2 and 4), the largest (3: the paper's 31 and 32 of 50 need three).
    """
    papers = {(int(p[0]), int(p[0]) + int(p[1])) for p in (*PAPER_TABLE4.values(), *PAPER_TABLE2.values())}
    return max(_decisive_trials(s, n) for s, n in papers)


def _interval_mark(paper: tuple, row: dict[str, Any]) -> str:
    """The mark "[lo–hi] ✓/✗": the paper's 90 % interval as counts of the run's trials, and whether the run is
    in it ("[none of N] –" when no count of the run's trials is: :func:`~electroloc_gym.bench.fidelity.interval_mark`).
    Below :func:`verdict_min_trials` trials the mark gives the interval and no verdict ("[lo–hi] –").
    """
    n, paper_n = _trials(row), int(paper[0]) + int(paper[1])
    if n <= 0 or paper_n <= 0:
        return ""
    mark = interval_mark(int(row["successes"]), n, int(paper[0]), paper_n)
    if n < verdict_min_trials() and not mark.endswith(UNTESTED):
        mark = f"{mark[:-1]}{UNTESTED}"
    return mark


def _untested_note(marks: list[str], trials: list[int]) -> str:
    """The sentence under a table with marks that decide nothing ("" when every mark decides): ``trials`` the
    trial count of each mark's cell.
    """
    untested = [n for m, n in zip(marks, trials, strict=True) if m.endswith(UNTESTED)]
    if not untested:
        return ""
    few = sum(n < verdict_min_trials() for n in untested)
    parts = []
    if few:
        parts.append(
            f"no verdict below {verdict_min_trials()} trials per cell, the fewest at which some count of the run "
            "has its own 90 % interval (Wilson) outside the paper's, for every paper count of Tables 2 and 4 "
            "(with fewer, no outcome could disagree with the paper beyond the run's own noise)"
        )
    if few < len(untested):
        parts.append("no count of this run's trials lies inside the paper's interval (too few trials to compare)")
    return (
        f"{UNTESTED}: {'; or '.join(parts)}; {len(untested)} such cell{'' if len(untested) == 1 else 's'}, not counted."
    )


def _trials(row: dict[str, Any]) -> int:
    return int(row["successes"]) + int(row["failures"])


def _inside_counts(rows: list[dict[str, Any]]) -> str:
    """One line: per paper controller, in how many conditions the run's count is inside the paper's interval."""
    parts, marks, trials = [], [], []
    for agent in dict.fromkeys(r["agent"] for r in rows if r["condition"] != "all"):
        key = paper_agent_key(agent) or ""
        mine = [r for r in rows if r["agent"] == agent and (r["condition"], key) in PAPER_TABLE4]
        cells = [_interval_mark(PAPER_TABLE4[(r["condition"], key)], r) for r in mine]
        tested = [m for m in cells if not m.endswith(UNTESTED)]
        marks += cells
        trials += [_trials(r) for r in mine]
        if cells:
            parts.append(f"{agent} {sum(m.endswith('✓') for m in tested)} of {len(tested)}")
    if not parts:
        return ""
    note = _untested_note(marks, trials)
    return (
        "Success counts inside the paper's 90 % binomial interval (Wilson, of its "
        f"{PAPER_TRIALS} trials; [lo–hi] = that interval in this run's trials): {'; '.join(parts)}."
    ) + (f" {note}" if note else "")


def is_all_conditions(row: dict[str, Any]) -> bool:
    """True when an aggregate (``"condition": "all"``) row covers all eight of the paper's conditions."""
    return row.get("conditions") == len(PRESET_NAMES)


def aggregate_label(row: dict[str, Any]) -> str:
    """The label of an aggregate row: "All conditions" over the paper's eight, else "Subset (k conditions)"."""
    if is_all_conditions(row):
        return "All conditions"
    k = row.get("conditions")
    return f"Subset ({k} condition{'' if k == 1 else 's'})"


def _pair(a: Any, b: Any, digits: int = 1) -> str:
    return f"{_f(a, digits)}/{_f(b, digits)}"


def _where(row: dict[str, Any], pooled: str = "") -> tuple[str, str]:
    """A row's Water and Sphere cells: its condition's, or an aggregate row's label (``pooled`` after it)."""
    return (aggregate_label(row) + pooled, "") if row["condition"] == "all" else _cond_label(row["condition"])


#: The columns of a particle-filter agent's row (Tables 4 and 2) after the row's own label columns.
_BELIEF_HEADERS = (
    "Success (failure)",
    "Error (mm) mean/median",
    "No. steps mean/median",
    "Decision ms",
    "Paper success (failure)",
    "Paper error",
    "Paper steps",
)
#: The columns of a zero-crossing agent's row (Table 1).
_ZERO_CROSSING_HEADERS = (
    "Condition",
    "Agent",
    "Success (failure)",
    "Mean abs. error x (mm)",
    "y (mm)",
    "Repeatability x/y (mm)",
    "Steps median",
    "Paper x (mm)",
    "Paper y (mm)",
)


def _belief_cells(r: dict[str, Any], paper: tuple | None) -> tuple[str, ...]:
    """A particle-filter agent's row under :data:`_BELIEF_HEADERS`, its label first."""
    return (
        r.get("label", r["agent"]),
        f"{r['successes']}({r['failures']})",
        _pair(r["error_mean_paired_mm"], r["error_median_mm"]),
        _pair(r["readings_mean_paired"], r["readings_median"]),
        _f(r["decision_ms_median"], 2),
        *_paper_cells(paper, r),
    )


def _paper_table(env_id: Any) -> str:
    """The paper's table a run's env is laid out like (an id no longer registered: Table 4's layout)."""
    return next((e.paper_table for e in ENVS if e.env_id == env_id), "table4")


def _summary_metrics(summary: dict[str, Any]) -> TaskMetrics:
    """The metrics of a summary's task: its env's (an id no longer registered: the paper's localisation metrics)."""
    return records_metrics([{"env_id": summary.get("config", {}).get("env_id")}])


def _has_task_rows(metrics: TaskMetrics, rows: list[dict[str, Any]]) -> bool:
    table = metrics.table
    return table is not None and any(r.get(table.count) and r["condition"] != "all" for r in rows)


def task_table_lines(metrics: TaskMetrics, rows: list[dict[str, Any]], config: dict[str, Any]) -> list[str]:
    """The table of a task's own statistics, from its declaration (module docstring): the title (a task without
    a success criterion's table is the document, titled by the env id), the paragraph, then one line per row
    holding the task's results (condition, agent, the declared columns).
    """
    table = metrics.table
    assert table is not None
    title = f"# electroloc bench — {config.get('env_id')}" if table.replaces else f"## {table.title}"
    headers = ("Water", "Sphere (mm)/material", "Agent", *(c.header for c in metrics.columns))
    cells = [
        (*_where(r, table.pooled), r.get("label", r["agent"]), *(c.cell(r) for c in metrics.columns))
        for r in rows
        if r.get(table.count)
    ]
    return [title, "", format_config_text(table.text, config), "", *markdown_table(headers, cells), ""]


def _pooled_text(row: dict[str, Any]) -> str:
    """An aggregate row's statistics pooled over all its trials (not the paper's convention)."""
    far = row.get("far_successes")
    return (
        f"{row.get('label', row['agent'])}: median steps {_f(row.get('readings_median_pooled'))}, median error "
        f"{_f(row.get('error_median_pooled_mm'), 2)} mm, own-success means: error "
        f"{_f(row.get('error_mean_mm'), 2)} mm, steps {_f(row.get('readings_mean'))}"
    ) + ("" if far is None else f", far successes (> {FAR_ERROR_MM:g} mm off) {far}")


def render_table_md(summary: dict[str, Any]) -> str:
    """table.md: Table 4 layout for the belief agents, Table 1 layout for zero-crossing agents."""
    rows = summary["rows"]
    cfg = summary.get("config", {})
    if _paper_table(cfg.get("env_id")) == "table2":
        return _render_table2(summary)
    metrics = _summary_metrics(summary)
    if metrics.table is not None and metrics.table.replaces and _has_task_rows(metrics, rows):
        return "\n".join(task_table_lines(metrics, rows, cfg))
    t4 = [r for r in rows if r.get("table_layout", "table4") == "table4"]
    t1 = [r for r in rows if r.get("table_layout") == "table1"]
    out = [f"# electroloc bench — {cfg.get('env_id', 'ElectroLoc-v0')}", ""]
    if cfg:
        out.append(
            f"{cfg.get('trials')} trials per condition and agent, seed {cfg.get('seed')}, sensor model "
            f"`{cfg.get('sensor_model')}`, signal `{cfg.get('signal')}`, {cfg.get('n_particles')} particles, "
            f"cap {cfg.get('max_observations')} observations. Paper values (Solberg, Lynch & MacIver 2008) "
            f"in the right-hand columns."
        )
        out.append("")
        if cfg.get("gain_levels"):
            out.append(
                f"Dynamic gain (§7): every reading's amplifier gain is part of the action, factors "
                f"{', '.join(f'{g:g}' for g in cfg['gain_levels'])} of the preset gain; `min-var` votes over "
                f"moves × gains, `min-var[gain=preset]` and the other controllers read at the preset gain."
            )
            out.append("")
    if t4:
        out += ["## Table 4 layout (particle-filter agents)", ""]
        subset = any(r["condition"] == "all" and not is_all_conditions(r) for r in t4)
        aggregate = (
            "the *Subset* row averages the per-condition values over this run's conditions (as the paper's "
            "*All conditions* row does over all eight; the paper's totals are not shown beside a subset)"
            if subset
            else "the *All conditions* row averages the per-condition values (as the paper's row does: its 12.4 "
            "and 6.7 median steps are the averages of the eight medians)"
        )
        out.append(
            "Appendix B rules, followed here: *success (failure)* counts trials with √trace Σ ≤ 10 mm within "
            "the cap; the **mean** error and mean steps omit every start position on which either (here: any) "
            f"Table-4 agent of the run failed; the **medians** use all trials, failures included; {aggregate}. "
            "Steps = observations fused."
        )
        out.append("")
        cells = []
        for r in t4:
            key = paper_agent_key(r["agent"]) or ""
            if r["condition"] == "all":
                paper = PAPER_TABLE4_ALL.get(key) if is_all_conditions(r) else None
            else:
                paper = PAPER_TABLE4.get((r["condition"], key))
            cells.append((*_where(r), *_belief_cells(r, paper)))
        out += [*markdown_table(("Water", "Sphere (mm)/material", "Agent", *_BELIEF_HEADERS), cells), ""]
        if inside := _inside_counts(t4):
            out += [inside, ""]
        if alls := [r for r in t4 if r["condition"] == "all"]:
            out += [f"Pooled over all trials (not the paper's convention): {'; '.join(map(_pooled_text, alls))}.", ""]
    if metrics.table is not None and not metrics.table.replaces and _has_task_rows(metrics, t4):
        out.extend(task_table_lines(metrics, t4, cfg))
    if t1:
        out += ["## Table 1 layout (zero-crossing)", ""]
        out.append(
            "Workspace 160 × 160 mm centred at a random point within ±75 mm (paper §6.4); mean absolute error "
            "of the final estimate in x and y over successful trials. *Repeatability* is the mean distance "
            "of the estimates from their own mean (what the paper's text says its table measures). Steps = "
            "readings taken (the paper does not report them)."
        )
        out.append("")
        cells = []
        for r in t1:
            if r["condition"] == "all":
                label, paper, rep = f"{aggregate_label(r)} (average)", None, ""
                if is_all_conditions(r):
                    paper = tuple(sum(axis) / len(axis) for axis in zip(*PAPER_TABLE1.values()))
            else:
                label = " ".join(_cond_label(r["condition"]))
                paper = PAPER_TABLE1.get(r["condition"])
                rep = _pair(r.get("error_x_repeatability_mm"), r.get("error_y_repeatability_mm"), 2)
            cells.append(
                (
                    label,
                    r.get("label", r["agent"]),
                    f"{r['successes']}({r['failures']})",
                    _f(r.get("error_x_mean_abs_mm"), 2),
                    _f(r.get("error_y_mean_abs_mm"), 2),
                    rep,
                    _f(r["readings_median"], 0),
                    _f(paper[0], 2) if paper else "",
                    _f(paper[1], 2) if paper else "",
                )
            )
        out += [*markdown_table(_ZERO_CROSSING_HEADERS, cells), ""]
    return "\n".join(out)


def _render_table2(summary: dict[str, Any]) -> str:
    """table.md for ElectroLocGlobal-v0: the paper's Table 2 layout (§6.5), same Appendix-B rules."""
    cfg = summary.get("config", {})
    rows = [r for r in summary["rows"] if r["condition"] != "all"]
    out = [
        f"# electroloc bench — {cfg.get('env_id')}",
        "",
        (
            f"Global self-localisation among six cylinders (paper §6.5, Table 2): {cfg.get('trials')} trials per "
            f"agent, seed {cfg.get('seed')}, sensor model `{cfg.get('sensor_model')}`, {cfg.get('n_particles')} "
            f"particles, cap {cfg.get('max_observations')} observations; the map is "
            f"`electroloc_gym.world.scene.BENCHMARK_SCENE`. Error = |belief mean − true carriage position|. Same "
            f"Appendix-B rules as Table 4 (mean error/steps over the trials every agent solved, medians over all "
            f"trials). Paper values in the right-hand columns."
        ),
        "",
    ]
    cells = [_belief_cells(r, PAPER_TABLE2.get(paper_agent_key(r["agent"]) or "")) for r in rows]
    out += [*markdown_table(("Control type", *_BELIEF_HEADERS), cells), ""]
    if note := _untested_note([str(c[5]) for c in cells], [_trials(r) for r in rows]):
        out += [note, ""]
    return "\n".join(out)
