"""pursuit: a moving target's controller that moves the carriage toward the belief's mean.

The simplest tracker: each step the carriage moves toward the mean of the predicted belief (the belief's
hypotheses after one step of the filter's motion model, ``predicted_particles_mm``; the belief's own
mean on an env whose target sits still), as far as one move allows (±10 mm per axis, kept in the
allowed box). It keeps the carriage over its best guess, where the sphere's reading is strongest, and
spends no move on looking elsewhere: what the paper's min-var rule (§4.1.3) trades against staying
close is here never traded. Reads the agent view's ``belief``, ``position_mm``, ``move_bounds_mm`` (or
``allowed_box_mm``) and ``predicted_particles_mm``; never the true target.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import BaselineAgent, move_bounds_mm, require_target_belief

__all__ = ["PursuitAgent"]


class PursuitAgent(BaselineAgent):
    """Move toward the predicted belief's mean (module docstring); deterministic.

    Args:
        seed: unused (the controller draws nothing); kept for the agents' common signature.
    """

    name = "pursuit"
    #: Its trials are among the quickest (one weighted mean per decision).
    cost_rank = 0

    def choose_move_mm(self) -> NDArray[np.float64]:
        env = self.env
        require_target_belief(env, self.name)
        particles = np.asarray(env.belief.particles)
        weights = np.asarray(env.belief.weights, dtype=np.float64)
        predicted = np.asarray(env.predicted_particles_mm(particles, np.zeros(2)), dtype=np.float64)[..., :2]
        goal = weights @ predicted / weights.sum()
        lo, hi = move_bounds_mm(env)
        return np.minimum(np.maximum(goal - np.asarray(env.position_mm, dtype=np.float64), lo), hi)

    def __repr__(self) -> str:
        return "PursuitAgent()"
