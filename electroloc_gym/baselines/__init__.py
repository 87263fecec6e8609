"""The built-in agents: the paper's three controllers and three planners.

The controllers are those of Solberg, Lynch & MacIver 2008 (§4.1.3, §4.2, Algorithm 1).

* ``rnd-wlk`` — :class:`~electroloc_gym.baselines.random_walk.RandomWalkAgent`
* ``min-var`` — :class:`~electroloc_gym.baselines.min_variance.MinVarianceAgent` (particle voting, Algorithm 1)
* ``zero-crossing`` — :class:`~electroloc_gym.baselines.zero_crossing.ZeroCrossingAgent` (§4.2, no belief)
* ``lookahead``, ``infotaxis``, ``eedi`` — :mod:`~electroloc_gym.baselines.lookahead`,
  :mod:`~electroloc_gym.baselines.infotaxis`, :mod:`~electroloc_gym.baselines.eedi`

All follow the protocol of :mod:`electroloc_gym.baselines.base`; the names are declared once in
:mod:`electroloc_gym.baselines.agent` (:data:`AGENT_NAMES`); build them with :func:`make_agent` (a shipped
learned policy by its name too) and run them with :func:`run_agent` (:mod:`electroloc_gym.baselines.rollout`).
"""

from electroloc_gym.baselines.agent import (
    AGENT_NAMES,
    AGENT_REGISTRY,
    EXTRA_AGENTS,
    PAPER_AGENTS,
    Agent,
    BaselineAgent,
    make_agent,
    parse_agent_spec,
)
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.baselines.random_walk import RandomWalkAgent
from electroloc_gym.baselines.rollout import Episode, run_agent
from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent

__all__ = [
    "AGENT_NAMES",
    "AGENT_REGISTRY",
    "PAPER_AGENTS",
    "EXTRA_AGENTS",
    "Agent",
    "BaselineAgent",
    "make_agent",
    "run_agent",
    "Episode",
    "parse_agent_spec",
    "RandomWalkAgent",
    "MinVarianceAgent",
    "ZeroCrossingAgent",
]
