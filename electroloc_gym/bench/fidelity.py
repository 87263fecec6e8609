"""The paper's success counts as 90 % binomial intervals, and whether a run's counts fall inside them.

The paper ran 50 trials per condition and controller (Table 4, Table 2). Its count ``s`` of 50 is one
draw of a binomial; the 90 % Wilson score interval of its success probability,

    p ∈ (p̂ + z²/2n ± z·√(p̂(1 − p̂)/n + z²/4n²)) / (1 + z²/n),  z = 1.645,

(about ±4 successes at 50 trials) is the range of rates the robot's result is consistent with. A run
of ``N`` trials is *inside* when its own rate lies in that range, i.e. its count in
``[⌈lo·N⌉, ⌊hi·N⌋]``. The run's own sampling noise is not added: the test is strict, and a run of the
robot itself would fall outside about one time in ten. The interval is scipy's
(``scipy.stats.binomtest(k, n).proportion_ci(confidence_level, method="wilson")``).
"""

from __future__ import annotations

import math

__all__ = ["PAPER_TRIALS", "wilson_interval", "paper_count_interval", "inside_paper_interval"]

#: Trials per condition and controller in the paper (§5.4).
PAPER_TRIALS = 50
#: Two-sided confidence of the paper's intervals.
CONFIDENCE = 0.90


def wilson_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval (lo, hi) of a binomial success probability (scipy's ``binomtest``)."""
    if trials <= 0 or not 0 <= successes <= trials:
        raise ValueError(f"need 0 ≤ successes ≤ trials and trials > 0, got {successes}/{trials}")
    from scipy.stats import binomtest

    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def paper_count_interval(paper_successes: int, n_trials: int, paper_trials: int = PAPER_TRIALS) -> tuple[int, int]:
    """The counts (lo, hi) out of ``n_trials`` inside the paper's 90 % interval."""
    lo, hi = wilson_interval(paper_successes, paper_trials)
    return math.ceil(lo * n_trials - 1e-9), math.floor(hi * n_trials + 1e-9)


def inside_paper_interval(
    successes: int, n_trials: int, paper_successes: int, paper_trials: int = PAPER_TRIALS
) -> bool:
    """True when ``successes`` of ``n_trials`` lies inside the paper's 90 % interval."""
    lo, hi = paper_count_interval(paper_successes, n_trials, paper_trials)
    return lo <= successes <= hi
