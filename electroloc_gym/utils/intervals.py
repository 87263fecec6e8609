"""Confidence intervals shared by every layer (the engines' task declarations, the benchmark's statistics)."""

from __future__ import annotations

__all__ = ["wilson_interval"]


def wilson_interval(successes: int, trials: int, confidence: float) -> tuple[float, float]:
    """Wilson score interval (lo, hi) of a binomial success probability at two-sided ``confidence`` (scipy's,
    imported on the first call); a ValueError for ``trials`` ≤ 0 or ``successes`` outside [0, trials].
    """
    if trials <= 0 or not 0 <= successes <= trials:
        raise ValueError(f"need 0 ≤ successes ≤ trials and trials > 0, got {successes}/{trials}")
    from scipy.stats import binomtest

    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)
