"""rnd-wlk: the paper's baseline controller #1 (§4.1.3).

Each step the controller draws the paper's 16 control options — stay, plus 15 moves uniform in the
±10 mm square around the carriage (restricted to the allowed box) — and picks one of them uniformly
at random. The belief (the env's particle filter) is updated as for min-var; only the choice differs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import BaselineAgent, move_bounds_mm, sample_options_mm

__all__ = ["RandomWalkAgent"]


class RandomWalkAgent(BaselineAgent):
    """Random choice among the 16 control options (paper §4.1.3, policy #1).

    Args:
        seed: seed or generator of the option draws and the choice.
        n_options: options per step including "stay" (paper: 16).
    """

    name = "rnd-wlk"
    #: No belief to weigh: the quickest trials.
    cost_rank = 0

    def __init__(self, seed: int | np.random.Generator | None = None, n_options: int = 16) -> None:
        super().__init__(seed)
        if isinstance(n_options, bool) or not isinstance(n_options, int) or n_options < 1:
            raise ValueError(f"n_options must be an integer ≥ 1, got {n_options!r}")
        self.n_options = n_options

    def choose_move_mm(self) -> NDArray[np.float64]:
        options = sample_options_mm(self.rng, *move_bounds_mm(self.env), self.n_options)
        return options[int(self.rng.integers(self.n_options))]

    def __repr__(self) -> str:
        return f"RandomWalkAgent(n_options={self.n_options})"
