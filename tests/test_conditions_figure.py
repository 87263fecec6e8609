"""conditions.png: every statistic of a run's table per condition and agent, with its interval, from the declarations.

The panels come from the task's declared columns (``Task.metrics``: a column with a direction is a panel, its
``Column.interval`` the panel's error bars) after the localisation table's success rate (90 % Wilson interval)
and median readings, unless the task's own table replaces the localisation tables. The committed bench folders'
summaries render; a run writes the figure beside table.md, with the other outputs.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from electroloc_gym.bench.plots import SUCCESS_KEY, condition_panels, conditions_png
from electroloc_gym.bench.runner import OUTPUT_FILES
from electroloc_gym.registry import ENVS

ROOT = Path(__file__).resolve().parents[1]
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("entry", ENVS, ids=lambda e: e.env_id)
def test_the_panels_are_the_declared_columns_with_their_intervals(entry) -> None:
    metrics = entry.task_class.metrics
    panels = condition_panels(metrics)
    keys = [p.key for p in panels]
    table = metrics.table
    assert (SUCCESS_KEY in keys) == (table is None or not table.replaces)
    for column in metrics.columns:
        if column.interval:  # every declared interval is drawn, on its statistic's panel
            assert next(p for p in panels if p.key == column.key).interval == column.interval
        if not any(c.better for c in metrics.columns if c.key == column.key):  # a count, no direction: no panel
            assert column.key not in keys
    assert len(keys) == len(set(keys))
    for p in panels:
        if p.interval is not None and p.key != SUCCESS_KEY:
            assert p.rows == table.count


def _summary(path: str) -> dict:
    return json.loads((ROOT / path).read_text(encoding="utf-8"))


@pytest.mark.parametrize(
    "path", ["experiments/reference/bench/summary.json", "experiments/track/results/bench/summary.json"]
)
def test_the_committed_runs_render(path: str) -> None:
    png = conditions_png(_summary(path))
    assert png.startswith(PNG) and len(png) > 20_000


def test_a_summary_without_rows_renders_a_note() -> None:
    png = conditions_png({"rows": [], "config": {"env_id": "ElectroLoc-v0", "trials": 1}})
    assert png.startswith(PNG)


def test_the_figure_is_a_run_output() -> None:
    assert "conditions.png" in OUTPUT_FILES and OUTPUT_FILES[:3] == ("summary.json", "table.md", "steps.png")


def test_the_figure_writers_write_the_figures_to_a_path(tmp_path) -> None:
    """``plot_steps`` and ``plot_conditions`` (the docs' command) write the PNGs ``steps_png`` and
    ``conditions_png`` make, byte for byte, to the path given."""
    from electroloc_gym.bench.plots import plot_conditions, plot_steps, steps_png

    summary = _summary("experiments/reference/bench/summary.json")
    for write, make, name in ((plot_steps, steps_png, "s.png"), (plot_conditions, conditions_png, "c.png")):
        write(summary, tmp_path / name)
        assert (tmp_path / name).read_bytes() == make(summary)
