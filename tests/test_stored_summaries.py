"""The stored benchmark summaries (the reference run's, the learned suite's) use the keys the bench writes now."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from electroloc_gym.bench.stats import RULES

ROOT = Path(__file__).resolve().parents[1]
SUMMARIES = sorted(
    [
        *(ROOT / "experiments" / "reference").glob("*/summary.json"),
        *(ROOT / "experiments" / "learned" / "results").glob("*/*/**/bench/summary.json"),
    ]
)
#: What a row of the current summary always has, and the names it once had instead.
CURRENT = {"readings_mean", "readings_median", "readings_mean_paired", "table_layout"}


def test_there_are_stored_summaries() -> None:
    assert len(SUMMARIES) >= 40


@pytest.mark.parametrize("path", SUMMARIES, ids=[p.parent.relative_to(ROOT).as_posix() for p in SUMMARIES])
def test_a_stored_summary_has_the_current_keys(path: Path) -> None:
    summary = json.loads(path.read_text(encoding="utf-8"))
    assert summary["rules"] == RULES
    for row in summary["rows"]:
        assert CURRENT <= set(row), (row["condition"], row["agent"])
        old = [k for k in row if k.startswith("steps_") or k == "layout"]
        assert not old, (row["condition"], row["agent"], old)
