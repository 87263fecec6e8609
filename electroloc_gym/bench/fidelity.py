"""The paper's success counts as 90 % binomial intervals, and whether a run's counts fall inside them.

The paper ran 50 trials per condition and controller (Table 4, Table 2). Its count ``s`` of 50 is one
draw of a binomial; the 90 % Wilson score interval of its success probability,

    p ∈ (p̂ + z²/2n ± z·√(p̂(1 − p̂)/n + z²/4n²)) / (1 + z²/n),  z = 1.645,

(about ±4 successes at 50 trials) is the range of rates the robot's result is consistent with. A run
of ``N`` trials is *inside* when its own rate lies in that range, i.e. its count in
``[⌈lo·N⌉, ⌊hi·N⌋]``. The run's own sampling noise is not added: the test is strict, and a run of the
robot itself would fall outside about one time in ten. The interval is scipy's
(``scipy.stats.binomtest(k, n).proportion_ci(confidence_level, method="wilson")``).

A run of very few trials may have no count inside: at ``N = 2`` the rates of 48 of 50, (0.87, 0.99),
contain neither 1/2 nor 2/2. Its mark (:func:`interval_mark`) then says so and tests nothing.
"""

from __future__ import annotations

import math

from electroloc_gym.utils.intervals import wilson_interval as _wilson

__all__ = [
    "PAPER_TRIALS",
    "UNTESTED",
    "wilson_interval",
    "paper_count_interval",
    "inside_paper_interval",
    "interval_mark",
]

#: Trials per condition and controller in the paper (§5.4).
PAPER_TRIALS = 50
#: Two-sided confidence of the paper's intervals.
CONFIDENCE = 0.90
#: The mark of a count that cannot be tested: no count of the run's trials lies inside the interval.
UNTESTED = "–"


def wilson_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The Wilson interval (lo, hi), 90 % by default: :func:`electroloc_gym.utils.intervals.wilson_interval`."""
    return _wilson(successes, trials, confidence)


def paper_count_interval(paper_successes: int, n_trials: int, paper_trials: int = PAPER_TRIALS) -> tuple[int, int]:
    """The counts (lo, hi) out of ``n_trials`` inside the paper's 90 % interval; lo > hi when there is none
    (a few trials: the interval lies between two counts).
    """
    lo, hi = wilson_interval(paper_successes, paper_trials)
    return math.ceil(lo * n_trials - 1e-9), math.floor(hi * n_trials + 1e-9)


def inside_paper_interval(
    successes: int, n_trials: int, paper_successes: int, paper_trials: int = PAPER_TRIALS
) -> bool:
    """True when ``successes`` of ``n_trials`` lies inside the paper's 90 % interval."""
    lo, hi = paper_count_interval(paper_successes, n_trials, paper_trials)
    return lo <= successes <= hi


def interval_mark(successes: int, n_trials: int, paper_successes: int, paper_trials: int = PAPER_TRIALS) -> str:
    """``"[lo–hi] ✓"`` when ``successes`` of ``n_trials`` is inside the paper's 90 % interval (as counts of
    ``n_trials``), ``"[lo–hi] ✗"`` when outside, and ``"[none of N] –"`` (:data:`UNTESTED`) when no count of
    ``n_trials`` lies inside it: too few trials to test.
    """
    lo, hi = paper_count_interval(paper_successes, n_trials, paper_trials)
    if lo > hi:
        return f"[none of {n_trials}] {UNTESTED}"
    return f"[{lo}–{hi}] {'✓' if lo <= successes <= hi else '✗'}"
