"""The paper's 90 % binomial intervals and the marks they put in the benchmark's tables."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binom

from electroloc_gym.bench.fidelity import inside_paper_interval, paper_count_interval, wilson_interval
from electroloc_gym.bench.tables import render_table_md


@pytest.mark.parametrize("s", [0, 1, 25, 31, 41, 49, 50])
def test_wilson_interval_covers_about_90_percent(s: int) -> None:
    lo, hi = wilson_interval(s, 50)
    assert 0.0 <= lo <= s / 50 <= hi <= 1.0
    if 5 <= s <= 45:  # away from the edges the coverage is close to nominal
        p = s / 50
        coverage = binom.cdf(np.floor(hi * 50), 50, p) - binom.cdf(np.ceil(lo * 50) - 1, 50, p)
        assert 0.85 < coverage < 0.97


def test_paper_counts_are_about_plus_minus_four_of_fifty() -> None:
    assert paper_count_interval(41, 50) == (36, 44)
    assert paper_count_interval(50, 50) == (48, 50)
    assert paper_count_interval(287, 400, 400) == (272, 301)
    # 35 of 50 by hand: p̂ = 0.7, z² = 2.706 → centre 0.6897, half-width 0.1043 → rates [0.585, 0.794]
    assert paper_count_interval(35, 50) == (30, 39)
    assert paper_count_interval(35, 100) == (59, 79)  # a run with twice the trials: the same rates
    assert inside_paper_interval(44, 50, 41) and not inside_paper_interval(45, 50, 41)
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(51, 50)


def test_table_marks_each_cell_inside_or_outside() -> None:
    rows = [
        {"condition": "fresh-steel-12.7", "agent": "rnd-wlk", "successes": 44, "failures": 6},
        {"condition": "fresh-steel-12.7", "agent": "min-var", "successes": 40, "failures": 10},
    ]
    for r in rows:
        r.update(
            error_mean_paired_mm=1.0,
            error_median_mm=1.0,
            readings_mean_paired=5.0,
            readings_median=5.0,
            decision_ms_median=1.0,
        )
    md = render_table_md({"rows": rows, "config": {"env_id": "ElectroLoc-v0"}})
    assert "41(9) [36–44] ✓" in md  # rnd-wlk 44/50 inside the paper's 41/50
    assert "50(0) [48–50] ✗" in md  # min-var 40/50 outside the paper's 50/50
    assert "rnd-wlk 1 of 1; min-var 0 of 1" in md


@pytest.mark.parametrize("s,n", [(0, 50), (1, 50), (35, 50), (41, 50), (50, 50), (287, 400)])
def test_scipy_wilson_interval_is_the_closed_form(s: int, n: int) -> None:
    z = 1.6448536269514722  # two-sided 90 %
    p = s / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    assert wilson_interval(s, n) == pytest.approx((max(0.0, centre - half), min(1.0, centre + half)), abs=1e-12)
