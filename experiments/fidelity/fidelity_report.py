r"""Every number the paper reports beside the simulation's, as the markdown tables of docs/fidelity.md.

Physics-only rows (Table 3 detection distances, start coverage, Fig. 5 slopes) are computed here;
controller rows (Tables 4, 1, 2, Fig. 12) are read from finished ``electroloc bench`` folders::

    python experiments/fidelity/fidelity_report.py --bench results/bench --other results/bench-coverage \\
        --expected results/bench-expected --global results/bench-global > /tmp/fidelity_tables.md

Success counts carry the paper's 90 % binomial interval (Wilson; about ±4 of 50) and ✓/✗ for
inside/outside; "inside/outside the detection region" splits trials by whether the noise-free
reading at the start exceeded 2σ (the paper's §6.3 criterion).

A folder is read as ``electroloc bench --resume`` reads it (:func:`electroloc_gym.bench.stored_run.read_run_records`:
its config, its records in the current key names, damaged or foreign lines set aside and named on stderr),
and its rows are the package's summary (:func:`electroloc_gym.bench.stats.summarize`) of the records of the
agents and conditions its ``summary.json`` was written for (its ``config``, read as a run's config:
:func:`electroloc_gym.bench.stored_run.config_from_json`), so a folder written by any version reads the same;
a folder without ``summary.json`` (an unfinished run) is left out, and one whose config, records file or summary
cannot be read ends the report with one line naming the file.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from electroloc_gym.baselines.agent import RANDOM_AGENT
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.fidelity import interval_mark
from electroloc_gym.bench.stats import summarize
from electroloc_gym.bench.stored_run import config_from_json, read_run_records
from electroloc_gym.bench.tables import PAPER_TABLE1, PAPER_TABLE2, PAPER_TABLE4, PAPER_TABLE4_ALL
from electroloc_gym.utils.markdown import markdown_table
from electroloc_gym.world import detection
from electroloc_gym.world.conditions import (
    PAPER_START_COVERAGE,
    PAPER_TABLE3_MEASURED_MM,
    PAPER_TABLE3_THEORY_MM,
    PRESET_NAMES,
    get_condition,
    start_box_coverage,
)
from electroloc_gym.world.sensor import expected_reading

SIGNALS = ("paper", "fitted", "coverage")


def _fmt(value: Any, spec: str) -> str:
    """``value`` formatted by ``spec``; "–" for a statistic a run has none of (None: no successes)."""
    return "–" if value is None else format(value, spec)


def _mark(sim_s: int, sim_n: int, paper_s: int, paper_n: int) -> str:
    return f"{sim_s} {interval_mark(sim_s, sim_n, paper_s, paper_n)}"


def table3() -> list[str]:
    rows = []
    for n in PRESET_NAMES:
        c = {s: get_condition(n, s) for s in SIGNALS}
        rows.append(
            (
                n,
                f"{c['paper'].amplifier.noise_rms_mV:.2f}",
                f"{PAPER_TABLE3_THEORY_MM[n]:.1f}",
                f"{PAPER_TABLE3_MEASURED_MM[n]:.1f}",
                f"{c['paper'].detection_distance_mm():.1f}",
                f"{c['fitted'].signal_scale:.2f}",
                f"{c['fitted'].detection_distance_mm():.1f}",
                f"{c['coverage'].signal_scale:.2f}",
                f"{c['coverage'].detection_distance_mm():.1f}",
            )
        )
    return markdown_table(
        (
            "Condition",
            "σ_s (mV)",
            "paper theory",
            "paper measured",
            "model, scale 1",
            "fitted scale",
            "model, fitted",
            "coverage scale",
            "model, coverage",
        ),
        rows,
    )


def coverage() -> list[str]:
    # Built by hand, not by markdown_table: the **mean** row's empty cell is "| |", one space, not the helper's "|  |".
    out = [
        "| Condition | paper signal | fitted | coverage | peak \\|Φ\\| at coverage (V) "
        "| saturated share of the start box at coverage |",
        "|---|---|---|---|---|---|",
    ]
    cov = {s: [] for s in SIGNALS}
    for n in PRESET_NAMES:
        row = []
        for s in SIGNALS:
            c = get_condition(n, s)
            cov[s].append(start_box_coverage(c))
            row.append(f"{cov[s][-1]:.2f}")
        c = get_condition(n, "coverage")
        h = c.start_half_width_mm
        g = np.linspace(-h, h, 161)
        gx, gy = np.meshgrid(g, g, indexing="ij")
        phi = expected_reading(c, -np.stack([gx, gy], axis=-1))
        out.append(f"| {n} | " + " | ".join(row) + f" | {np.abs(phi).max():.2f} | {np.mean(np.abs(phi) >= 10.0):.2f} |")
    out.append(
        "| **mean** | "
        + " | ".join(f"**{np.mean(cov[s]):.2f}**" for s in SIGNALS)
        + f" | | paper §6.3: **{PAPER_START_COVERAGE:.2f}** |"
    )
    return out


def fig5_slopes() -> list[str]:
    a, e, chi = 0.05, 0.005, 1.0  # the paper's Fig. 4/5 example
    ns = np.geomspace(1e-9, 1e-2, 60)
    rd = np.array([detection.eq6_detection_distance(n, a, e, chi) for n in ns])
    near, far = rd < 0.1, rd > 3.0
    s_near = np.polyfit(np.log(ns[near]), np.log(rd[near]), 1)[0] if near.sum() > 2 else float("nan")
    s_far = np.polyfit(np.log(ns[far]), np.log(rd[far]), 1)[0] if far.sum() > 2 else float("nan")
    return markdown_table(
        ("Regime", "paper (Fig. 5)", "model (Eq. 5–6)"),
        [("near field, r_d < 0.1 L", "−1/2", f"{s_near:.3f}"), ("far field, r_d > 3 L", "−1/5", f"{s_far:.3f}")],
    )


class _Summarised(msgspec.Struct):
    """What the report reads of a bench ``summary.json``: the run it was written for (``config``, the runner's
    :class:`~electroloc_gym.bench.config.BenchConfig`; absent: the folder's config.json); its rows are summarised
    again from the records.
    """

    config: dict[str, Any] | None = None


def _summarised(path: Path) -> BenchConfig | None:
    """The run the bench ``summary.json`` at ``path`` was written for, read through the run's schema
    (:func:`~electroloc_gym.bench.stored_run.config_from_json`); None where it names none.

    Raises:
        ValueError: unreadable, not JSON, or its config not a run's — one line naming the file.
    """
    try:
        block = msgspec.json.decode(path.read_bytes(), type=_Summarised).config
    except OSError as exc:
        raise ValueError(f"{path}: not readable ({exc.strerror or exc})") from None
    except (msgspec.MsgspecError, RecursionError) as exc:
        raise ValueError(f"{path}: not a benchmark summary ({type(exc).__name__}: {exc})") from None
    return None if block is None else config_from_json(block, f"{path} (its config)")


def _load(folder: str | None) -> tuple[list[dict[str, Any]], list[dict[str, Any]], dict[str, Any]] | None:
    """A finished run's summary rows, records and config (None: no folder given, or the run is unfinished).

    Raises:
        ValueError: the folder's config.json, records or summary.json unreadable — one line naming the file.
    """
    if not folder or not (Path(folder) / "summary.json").is_file():
        return None
    run = read_run_records(folder)
    for line in run.messages():
        print(f"fidelity_report: set aside {line}", file=sys.stderr)
    # the agents and conditions the summary was written for (config.json holds every one ever asked for)
    summarised = _summarised(Path(folder) / "summary.json") or run.config
    agents, conditions = list(summarised.agents), list(summarised.conditions)
    records = [r for r in run.records if r["agent"] in agents and r["condition"] in conditions]
    rows = summarize(records, agents=agents, conditions=conditions)["rows"]
    return rows, records, asdict(run.config)


def _inside(record: dict[str, Any], signal: str) -> bool:
    c = get_condition(record["condition"], signal)
    off = np.asarray(record["target"]) - np.asarray(record["start"])
    return bool(abs(float(expected_reading(c, off[None, :])[0])) > 2.0 * c.noise_std_V)


def table4(rows: list[dict[str, Any]], label: str) -> list[str]:
    cells = []
    for n in PRESET_NAMES + ("all",):
        for r in (r for r in rows if r["condition"] == n and r.get("table_layout", "table4") == "table4"):
            key = r["agent"].split("[", 1)[0]
            paper = PAPER_TABLE4_ALL.get(key) if n == "all" else PAPER_TABLE4.get((n, key))
            sim_n = r["successes"] + r["failures"]
            if paper and r["agent"] == key:
                cell = _mark(r["successes"], sim_n, paper[0], paper[0] + paper[1])
                p_s, p_steps, p_err = f"{paper[0]}", f"{paper[5]:g}", f"{paper[3]:g}"
            else:
                cell, p_s, p_steps, p_err = f"{r['successes']}", "", "", ""
            cells.append(
                (
                    "All conditions" if n == "all" else n,
                    r.get("label", r["agent"]),
                    cell,
                    p_s,
                    _fmt(r["readings_median"], ".3g"),
                    p_steps,
                    _fmt(r["error_median_mm"], ".1f"),
                    p_err,
                )
            )
    return [
        f"Run: {label}.",
        "",
        *markdown_table(
            (
                "Condition",
                "Agent",
                "success [paper 90 % interval]",
                "paper",
                "median steps",
                "paper",
                "median error (mm)",
                "paper",
            ),
            cells,
        ),
    ]


def fig12(rows: list[dict[str, Any]]) -> list[str]:
    by = {(r["condition"], r["agent"]): r for r in rows}
    mv, rnd = MinVarianceAgent.name, RANDOM_AGENT
    both = [n for n in PRESET_NAMES if (n, mv) in by and (n, rnd) in by]
    fewer_steps = sum(by[(n, mv)]["readings_median"] < by[(n, rnd)]["readings_median"] for n in both)
    fewer_fail = sum(by[(n, mv)]["failures"] <= by[(n, rnd)]["failures"] for n in both)
    a, b = by.get(("all", mv)), by.get(("all", rnd))
    ratio = a["readings_median"] / b["readings_median"] if a and b else float("nan")
    return markdown_table(
        ("Fig. 12 statement", "paper", "simulation"),
        [
            ("conditions where min-var needs fewer median steps", "8 of 8", f"{fewer_steps} of 8"),
            ("conditions where min-var fails no more often", "8 of 8", f"{fewer_fail} of 8"),
            (
                "min-var / rnd-wlk, mean of the 8 median steps",
                "6.7 / 12.4 = 0.54",
                f"{a['readings_median'] if a else float('nan'):.3g} / "
                f"{b['readings_median'] if b else float('nan'):.3g} = {ratio:.2f}",
            ),
            (
                "failures min-var / rnd-wlk",
                "19 / 113",
                f"{a['failures'] if a else '–'} / {b['failures'] if b else '–'}",
            ),
        ],
    )


def _median_obs(xs: list[dict[str, Any]]) -> str:
    return f"{statistics.median(x['readings'] for x in xs):g}" if xs else "–"


def inside_outside(records: list[dict[str, Any]], signal: str) -> list[str]:
    rows = []
    for agent in dict.fromkeys(r["agent"] for r in records if r.get("table_layout", "table4") == "table4"):
        rs = [r for r in records if r["agent"] == agent]
        ins = [r for r in rs if _inside(r, signal)]
        outs = [r for r in rs if not _inside(r, signal)]
        rows.append(
            (
                agent,
                f"{len(ins)}/{len(rs)} ({len(ins) / len(rs):.0%})",
                _median_obs(ins),
                _median_obs(outs),
                f"{sum(x['success'] for x in ins)}/{len(ins)}",
                f"{sum(x['success'] for x in outs)}/{len(outs)}",
            )
        )
    return markdown_table(
        (
            "Agent",
            "starts inside",
            "median steps inside",
            "median steps outside",
            "successes inside",
            "successes outside",
        ),
        rows,
    )


def table1(rows: list[dict[str, Any]]) -> list[str]:
    cells = []
    for r in rows:
        if r.get("table_layout") != "table1" or r["condition"] == "all":
            continue
        px, py = PAPER_TABLE1[r["condition"]]
        cells.append(
            (
                r["condition"],
                f"{r['successes']}({r['failures']})",
                _fmt(r["error_x_mean_abs_mm"], ".2f"),
                f"{px:.2f}",
                _fmt(r["error_y_mean_abs_mm"], ".2f"),
                f"{py:.2f}",
            )
        )
    return markdown_table(
        ("Condition", "success", "mean \\|error x\\| (mm)", "paper", "mean \\|error y\\| (mm)", "paper"), cells
    )


def table2(rows: list[dict[str, Any]]) -> list[str]:
    cells = []
    for r in rows:
        if r["condition"] == "all":
            continue
        paper = PAPER_TABLE2.get(r["agent"])
        if not paper:
            continue
        cell = _mark(r["successes"], r["successes"] + r["failures"], paper[0], paper[0] + paper[1])
        cells.append(
            (
                r["agent"],
                cell,
                paper[0],
                _fmt(r["readings_median"], "g"),
                f"{paper[5]:g}",
                _fmt(r["error_median_mm"], ".1f"),
                f"{paper[3]:g}",
            )
        )
    return markdown_table(
        ("Agent", "success [paper 90 % interval]", "paper", "median steps", "paper", "median error (mm)", "paper"),
        cells,
    )


def _read(ap: argparse.ArgumentParser, folder: str | None) -> Any:
    """:func:`_load`; a folder it cannot read ends the command with one line naming the file (exit status 2)."""
    try:
        return _load(folder)
    except ValueError as exc:
        ap.exit(2, f"fidelity_report: error: {exc}\n")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", default="results/bench", help="the default main-job run")
    ap.add_argument("--other", nargs="*", default=[], help="runs with other settings (e.g. --signal coverage)")
    ap.add_argument("--expected", default=None, help="min-var[vote=expected] with the default settings")
    ap.add_argument("--global", dest="global_", default=None, help="an --env global run")
    args = ap.parse_args(argv)
    sections: list[tuple[str, list[str]]] = [
        ("Table 3: detection distance along the 45° line (mm)", table3()),
        ("Start coverage: share of the start box inside the 2σ detection region (§6.3)", coverage()),
        ("Fig. 5: slopes of log r_d against log n", fig5_slopes()),
    ]
    runs = [(args.bench, "default simulation"), (args.expected, "min-var with the expected-variance vote")]
    runs += [(folder, "other settings") for folder in args.other]
    for folder, label in runs:
        loaded = _read(ap, folder)
        if loaded is None:
            continue
        rows, records, cfg = loaded
        if folder == args.expected:  # only what the default run does not already show
            rows = [r for r in rows if "vote=" in r["agent"]]
            records = [r for r in records if "vote=" in r["agent"]]
        if label == "other settings":
            label = f"signal `{cfg.get('signal')}`"
        sections.append(
            (
                f"Table 4, {label} (`{folder}`, seed {cfg.get('seed')}, {cfg.get('trials')} trials)",
                table4(rows, f"signal `{cfg.get('signal')}`"),
            )
        )
        if any(r["agent"] == MinVarianceAgent.name for r in rows) and any(r["agent"] == RANDOM_AGENT for r in rows):
            sections.append((f"Fig. 12, {label}", fig12(rows)))
        sections.append(
            (
                f"Starts inside and outside the detection region, {label}",
                inside_outside(records, cfg.get("signal", "coverage")),
            )
        )
        if any(r.get("table_layout") == "table1" for r in rows):
            sections.append((f"Table 1 (zero-crossing), {label}", table1(rows)))
    loaded = _read(ap, args.global_)
    if loaded is not None:
        sections.append((f"Table 2 (`{args.global_}`)", table2(loaded[0])))
    for title, lines in sections:
        print(f"### {title}\n")
        print("\n".join(lines))
        print()


if __name__ == "__main__":
    main()
