"""docs/results.md is the reference run's tables, and those tables are what the committed records give."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from electroloc_gym.bench.records import read_trials
from electroloc_gym.bench.stats import summarize
from electroloc_gym.bench.tables import render_table_md

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("results_page", ROOT / "docs" / "results_page.py")
results_page = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(results_page)
FOLDERS = [results_page.REFERENCE / name for name in results_page.RUNS]


def test_the_page_is_the_reference_tables() -> None:
    page = results_page.PAGE.read_text(encoding="utf-8")
    assert results_page.render(page) == page, "docs/results.md is stale: run python docs/results_page.py"
    for folder in FOLDERS:  # every row of every table is on the page, verbatim
        for line in (folder / "table.md").read_text(encoding="utf-8").splitlines():
            if line.startswith("|"):
                assert line in page, line


@pytest.mark.parametrize("folder", FOLDERS, ids=[f.name for f in FOLDERS])
def test_the_tables_are_the_records(folder: Path) -> None:
    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    assert render_table_md(summary) == (folder / "table.md").read_text(encoding="utf-8")
    config = summary["config"]
    records = read_trials(folder / "trials.jsonl")
    assert len(records) == len(config["agents"]) * len(config["conditions"]) * config["trials"]
    again = summarize(records, agents=config["agents"], conditions=config["conditions"])
    assert again["rows"] == summary["rows"]


def test_a_changed_table_makes_the_page_stale(tmp_path: Path) -> None:
    for name in results_page.RUNS:
        dest = tmp_path / name
        dest.mkdir()
        for f in ("table.md", "command.txt"):
            (dest / f).write_text((results_page.REFERENCE / name / f).read_text(encoding="utf-8"), encoding="utf-8")
    table = tmp_path / "bench" / "table.md"
    table.write_text(table.read_text(encoding="utf-8").replace("| rnd-wlk |", "| rnd-walk |", 1), encoding="utf-8")
    page = results_page.PAGE.read_text(encoding="utf-8")
    assert results_page.render(page, tmp_path) != page
    assert "| rnd-walk |" in results_page.render(page, tmp_path)


def test_a_page_without_one_block_is_refused() -> None:
    with pytest.raises(ValueError, match="exactly one results:full"):
        results_page.render("no markers here")
