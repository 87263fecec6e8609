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


CONFIGS = sorted((ROOT / "experiments").glob("**/bench*/config.json"))


def test_every_stored_config_reads_through_the_runs_schema() -> None:
    from electroloc_gym.bench.stored_run import load_config

    assert len(CONFIGS) >= 40
    for path in CONFIGS:
        config = load_config(path)
        assert config.trials >= 1 and config.agents and config.conditions, path
    assert load_config(str(CONFIGS[0])) == load_config(CONFIGS[0])  # a path as text, as the signature takes


@pytest.mark.parametrize(
    "content, words",
    [
        (None, "not readable"),
        (b"[[[", "not valid UTF-8 JSON (DecodeError"),
        (b"\xff\xfe", "not valid UTF-8 JSON (DecodeError"),
        (b"[]", "not a benchmark run's config"),
        (b'{"trials": 3}', "not a benchmark run's config: missing key(s)"),
        ("trials=-1", "not a benchmark run's config"),
        ("agents=7", "not a benchmark run's config"),
    ],
)
def test_a_config_that_is_not_a_runs_is_one_line_naming_it(tmp_path: Path, content, words: str) -> None:
    from electroloc_gym.bench.stored_run import load_config

    path = tmp_path / "config.json"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif isinstance(content, str):
        key, value = content.split("=")
        stored = json.loads((ROOT / "experiments/reference/bench/config.json").read_text(encoding="utf-8"))
        path.write_text(json.dumps({**stored, key: json.loads(value)}), encoding="utf-8")
    with pytest.raises(ValueError) as err:
        load_config(path)
    assert str(err.value).startswith(str(path)) and words in str(err.value) and "\n" not in str(err.value)
