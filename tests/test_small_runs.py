"""Runs of few trials per cell: every paper-interval mark is a real interval, or says it tests nothing.

At ``--trials 2`` the 90 % interval of the paper's 48 of 50 holds the rates (0.87, 0.99): no count of two
trials lies in it. Such a cell reads ``[none of 2] –``, never a lower bound above the upper one, and is not
counted among the insides. Below :func:`~electroloc_gym.bench.tables.verdict_min_trials` trials (3, derived
from the paper's intervals) no cell gets a ✓/✗ at all, and the note under the table says the threshold.
"""

from __future__ import annotations

import re

import pytest

from electroloc_gym.bench.fidelity import UNTESTED, interval_mark, paper_count_interval, wilson_interval
from electroloc_gym.bench.tables import PAPER_TABLE2, PAPER_TABLE4, render_table_md, verdict_min_trials

_INTERVAL = re.compile(r"\[(\d+)–(\d+)\]")


def _bounds_in_order(text: str) -> None:
    for lo, hi in _INTERVAL.findall(text):
        assert int(lo) <= int(hi), f"[{lo}–{hi}] in:\n{text}"


@pytest.mark.parametrize("n", [1, 2])
def test_every_paper_count_gets_an_ordered_interval_or_none(n: int) -> None:
    papers = [*PAPER_TABLE4.values(), *PAPER_TABLE2.values()]
    for paper in papers:
        lo, hi = paper_count_interval(paper[0], n, paper[0] + paper[1])
        for successes in range(n + 1):
            mark = interval_mark(successes, n, paper[0], paper[0] + paper[1])
            if lo > hi:
                assert mark == f"[none of {n}] {UNTESTED}"
            else:
                assert mark == f"[{lo}–{hi}] {'✓' if lo <= successes <= hi else '✗'}"
    assert interval_mark(2, 2, 48) == "[none of 2] –"  # the paper's Table 2 rnd-wlk at two trials
    assert interval_mark(31, 50, 31) == "[26–36] ✓"  # the rates 0.504–0.724 hold no count of 1 or 2
    assert interval_mark(1, 2, 31) == "[none of 2] –" and interval_mark(1, 1, 31) == "[none of 1] –"
    assert interval_mark(2, 2, 50) == "[2–2] ✓" and interval_mark(1, 2, 50) == "[2–2] ✗"
    assert interval_mark(1, 1, 50) == "[1–1] ✓" and interval_mark(0, 1, 50) == "[1–1] ✗"


def _row(condition: str, agent: str, successes: int, failures: int) -> dict:
    return {
        "condition": condition,
        "agent": agent,
        "successes": successes,
        "failures": failures,
        "error_mean_paired_mm": 1.0,
        "error_median_mm": 1.0,
        "readings_mean_paired": 5.0,
        "readings_median": 5.0,
        "decision_ms_median": 1.0,
    }


def test_table_2_at_two_trials() -> None:
    rows = [_row("six-cylinders", "rnd-wlk", 2, 0), _row("six-cylinders", "min-var", 2, 0)]
    md = render_table_md({"rows": rows, "config": {"env_id": "ElectroLocGlobal-v0", "trials": 2}})
    _bounds_in_order(md)
    assert "48(2) [none of 2] –" in md and "49(1) [none of 2] –" in md
    assert "–: no verdict below 3 trials per cell" in md and "2 such cells" in md


def _outside(k: int, n: int, paper: tuple) -> bool:
    """Whether k of n has its own 90 % interval disjoint from the paper's."""
    lo, hi = wilson_interval(paper[0], paper[0] + paper[1])
    own = wilson_interval(k, n)
    return own[1] < lo or own[0] > hi


def test_the_verdict_threshold_is_the_fewest_trials_that_can_disagree_with_every_paper_count() -> None:
    papers = [*PAPER_TABLE4.values(), *PAPER_TABLE2.values()]
    n = verdict_min_trials()
    assert all(any(_outside(k, n, p) for k in range(n + 1)) for p in papers)  # at n: every cell can disagree
    assert not all(any(_outside(k, n - 1, p) for k in range(n)) for p in papers)  # one trial fewer: some cannot
    assert n == 3 and not any(_outside(k, 2, (31, 19)) for k in range(3))  # the paper's 31 of 50


@pytest.mark.parametrize("trials", [2, 3, 4])
def test_no_verdict_below_the_threshold(trials: int) -> None:
    rows = [
        _row(c, a, trials - k, k)
        for k, (c, a) in enumerate((("fresh-steel-12.7", "min-var"), ("fresh-delrin-12.7", "rnd-wlk")))
    ]
    rows += [{**r, "condition": "all", "conditions": 2} for r in rows]
    md = render_table_md({"rows": rows, "config": {"env_id": "ElectroLoc-v0", "trials": trials}})
    _bounds_in_order(md)
    verdicts = re.findall(r"\] [✓✗]", md)
    if trials < verdict_min_trials():
        assert not verdicts and "no verdict below 3 trials per cell" in md and "2 such cells, not counted" in md
    else:
        assert verdicts and "no verdict" not in md


@pytest.mark.parametrize("trials", [1, 2])
def test_a_bench_run_of_few_trials_prints_no_impossible_interval(trials: int, tmp_path, capsys) -> None:
    from electroloc_gym.cli import main

    out = tmp_path / "bench"
    argv = [
        "bench",
        "--agents",
        "rnd-wlk,min-var",
        "--conditions",
        "fresh-steel-12.7,salt-delrin-38.1",
        "--trials",
        str(trials),
        "--n-particles",
        "200",
        "--max-observations",
        "6",
        "--sensor-model",
        "analytic",
        "--backend",
        "serial",
        "--no-progress",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    md = (out / "table.md").read_text(encoding="utf-8")
    _bounds_in_order(md)
    # the paper's rnd-wlk counts (41 and 31 of 50) and min-var's 44 hold no count of 1 or 2 trials; min-var's
    # 50 of 50 (rates 0.95–1) holds exactly one: all trials, but below 3 trials there is no verdict
    assert f"41(9) [none of {trials}] –" in md and f"31(19) [none of {trials}] –" in md
    assert f"44(6) [none of {trials}] –" in md
    assert f"50(0) [{trials}–{trials}] –" in md and not re.search(r"\] [✓✗]", md)
    assert re.search(r"rnd-wlk 0 of 0; min-var 0 of 0\. –: no verdict below 3 trials per cell", md)
    assert "4 such cells, not counted" in md
    assert (out / "conditions.png").read_bytes().startswith(b"\x89PNG")  # the figures of a small run too
    assert "conditions.png" in capsys.readouterr().out


def test_the_note_under_the_table_names_each_reason_a_mark_decides_nothing() -> None:
    """The sentence under a table counts the cells whose mark decides nothing and gives each reason they have:
    below the verdict threshold, and a trial count none of whose counts lies inside the paper's interval."""
    from electroloc_gym.bench.tables import _untested_note

    k = verdict_min_trials()
    none_inside = f"[none of {k}] {UNTESTED}"
    assert _untested_note(["[1–2] ✓", "[3–4] ✗"], [k, k]) == ""
    only = _untested_note([none_inside], [k])
    assert only == (
        f"{UNTESTED}: no count of this run's trials lies inside the paper's interval (too few trials to compare); "
        "1 such cell, not counted."
    )
    both = _untested_note([none_inside, f"[0–1] {UNTESTED}", "[1–2] ✓"], [k, k - 1, k])
    assert both.startswith(f"{UNTESTED}: no verdict below {k} trials per cell") and both.endswith(
        "; or no count of this run's trials lies inside the paper's interval (too few trials to compare); "
        "2 such cells, not counted."
    )
