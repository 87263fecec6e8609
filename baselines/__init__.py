"""The paper's three controllers as agents (Solberg, Lynch & MacIver 2008, §4.1.3, §4.2, Algorithm 1).

* ``rnd-wlk`` — :class:`~electroloc_gym.baselines.random_walk.RandomWalkAgent`
* ``min-var`` — :class:`~electroloc_gym.baselines.min_variance.MinVarianceAgent` (particle voting, Algorithm 1)
* ``zero-crossing`` — :class:`~electroloc_gym.baselines.zero_crossing.ZeroCrossingAgent` (§4.2, no belief)

All follow the protocol of :mod:`electroloc_gym.baselines.agent`; build them with :func:`make_agent`.
"""

from electroloc_gym.baselines.agent import AGENT_REGISTRY, Agent, BaselineAgent, make_agent, parse_agent_spec
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.baselines.random_walk import RandomWalkAgent
from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent

__all__ = [
    "AGENT_REGISTRY",
    "Agent",
    "BaselineAgent",
    "make_agent",
    "parse_agent_spec",
    "RandomWalkAgent",
    "MinVarianceAgent",
    "ZeroCrossingAgent",
]
