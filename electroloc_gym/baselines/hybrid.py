"""hybrid: a moving target's controller that searches while the belief is wide and pursues once it is tight.

Information gain and pursuit answer different questions. While the belief is spread over the tank, a move
is worth what it teaches: the paper's min-var rule (§4.1.3, Algorithm 1) picks the move whose predicted
reading best splits the hypotheses. Once the belief is tight, the prey is found and every move spent on
looking elsewhere lets it swim away: the greedy value of the fully observed pursuit (move toward the
predicted prey, :mod:`~electroloc_gym.baselines.pursuit`) is what keeps it. Carbone et al. (arXiv
2604.13121, 2026) show that, for olfactory pursuit of a moving target, infotaxis alone is near optimal
only for targets that turn often, and that a hybrid of information gain and the greedy pursuit value is
near optimal at every persistence; their hybrid weighs the two by the belief's uncertainty. Here the
weight is a switch on the same quantity:

* **the switch**: the belief's spread √trace Σ (mm) at or below ``switch_spread_mm`` → pursuit, above it →
  the explorer (``explore``: ``"min-var"``, the paper's rule, or ``"infotaxis"``);
* **its default** is the env's success criterion (10 mm, the paper's §5.4: the spread at which the paper
  calls the target localised), which is also the capture distance of the moving target (a carriage within
  10 mm strikes in one move): below it, what is left to learn is smaller than the capture tolerance, so the
  move that keeps the prey is worth more than the move that narrows the belief.

Each decision asks the belief's spread once (the agent view's ``belief.spread()``), then one of the two
controllers decides; the explorer keeps its own random generator (seeded with the agent). Reads what
min-var and pursuit read; never the true target.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import BaselineAgent, require_target_belief
from electroloc_gym.baselines.infotaxis import InfotaxisAgent
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.baselines.pursuit import PursuitAgent
from electroloc_gym.utils.checks import check_choice, check_float

__all__ = ["HybridAgent", "EXPLORERS"]

#: The information-gain controllers the hybrid searches with, by name.
EXPLORERS: dict[str, type] = {cls.name: cls for cls in (MinVarianceAgent, InfotaxisAgent)}


class HybridAgent(BaselineAgent):
    """Search with ``explore`` while the belief's spread is above ``switch_spread_mm``, pursue the predicted
    prey at or below it (module docstring).

    Args:
        seed: seed of the explorer's generator.
        explore: the information-gain controller, one of :data:`EXPLORERS`.
        switch_spread_mm: the spread √trace Σ (mm, > 0) at or below which it pursues; None: the env's
            success criterion (``success_spread_mm``, 10 mm by default).
    """

    name = "hybrid"
    cost_rank = 2

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        explore: str = MinVarianceAgent.name,
        switch_spread_mm: float | None = None,
    ) -> None:
        super().__init__(seed)
        self.explore = check_choice("explore", explore, tuple(EXPLORERS))
        self.switch_spread_mm = (
            None if switch_spread_mm is None else check_float("switch_spread_mm", switch_spread_mm, 0.0)
        )
        self.explorer: Any = EXPLORERS[self.explore](seed=self.rng)
        self.pursuer = PursuitAgent()
        #: How many decisions each controller made this episode: (explorer, pursuit).
        self.decisions = [0, 0]

    def seed(self, seed: int | None) -> None:
        super().seed(seed)
        self.explorer.seed(seed)

    def reset(self, env: Any) -> None:
        super().reset(env)
        require_target_belief(self.env, self.name)
        self.explorer.reset(env)
        self.pursuer.reset(env)
        self.decisions = [0, 0]

    def threshold_mm(self) -> float:
        """The spread at or below which it pursues, mm."""
        return float(self.env.success_spread_mm if self.switch_spread_mm is None else self.switch_spread_mm)

    def choose_move_mm(self) -> NDArray[np.float64]:
        pursue = float(self.env.belief.spread()) <= self.threshold_mm()
        self.decisions[int(pursue)] += 1
        return (self.pursuer if pursue else self.explorer).choose_move_mm()

    def __repr__(self) -> str:
        return f"HybridAgent(explore={self.explore!r}, switch_spread_mm={self.switch_spread_mm!r})"
