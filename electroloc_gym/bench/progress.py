"""The benchmark's progress bar: trials done, the agent and condition of the last one, an honest ETA.

Every worker's first trial also pays its start-up (imports, loading the compiled kernels, building
the env), so a rate measured from the start of the run predicts hours for a run of minutes. The
ETA here is measured from the moment every worker has delivered its first trial: before that the bar
says "ETA after warm-up"; afterwards ETA = trials left ÷ trials per second since then.
"""

from __future__ import annotations

import time
from typing import Any

from electroloc_gym.bench.agents import agent_display_name

__all__ = ["eta_s", "TrialProgress"]


def eta_s(done_at_s: list[float], total: int, warm: int) -> float | None:
    """Seconds left of ``total`` trials, from the completion times ``done_at_s`` (s, increasing) of those done.

    The first ``warm`` results (the worker count) include start-up: the rate is measured after the ``warm``-th,
    and None returned until a trial finished after it.
    """
    warm = max(1, min(warm, total))
    if len(done_at_s) <= warm:
        return None
    t0, t1 = done_at_s[warm - 1], done_at_s[-1]
    return None if t1 <= t0 else (total - len(done_at_s)) * (t1 - t0) / (len(done_at_s) - warm)


class TrialProgress:
    """A tqdm bar over a run's ``total`` trials (or nothing, when ``enabled`` is False); the first results of
    the ``workers`` are the warm-up.
    """

    def __init__(self, total: int, workers: int, enabled: bool = True) -> None:
        self.total, self.warm = total, max(1, workers)
        self._done: list[float] = []
        self._bar: Any = None
        if enabled and total:
            from tqdm.auto import tqdm

            self._bar = tqdm(
                total=total,
                desc="trials",
                unit="trial",
                dynamic_ncols=True,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]",
            )
            self._bar.set_postfix_str("ETA after warm-up", refresh=True)

    def update(self, record: dict[str, Any]) -> None:
        """One trial finished."""
        self._done.append(time.perf_counter())
        if self._bar is None:
            return
        eta = eta_s(self._done, self.total, self.warm)
        when = "ETA after warm-up" if eta is None else f"ETA {self._bar.format_interval(round(eta))}"
        self._bar.set_postfix_str(
            f"{when}, last: {agent_display_name(record['agent'])} on {record['condition']}", refresh=False
        )
        self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
