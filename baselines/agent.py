"""The agent registry: names → the controllers, built from an agent spec by :func:`make_agent`.

A spec is a name, optionally with keyword options in brackets (``min-var[n_voters=2500]``,
``lookahead[objective=steps,depth=2]``), parsed by the package's one spec parser
(:mod:`electroloc_gym.agentspec`). The agent protocol and the controllers' common base live in
:mod:`electroloc_gym.baselines.base` (re-exported here); the controller modules import that module,
never this one, so the registry → controllers imports run one way.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from electroloc_gym.agentspec import AgentSpec
from electroloc_gym.agentspec import parse_agent_spec as _parse
from electroloc_gym.baselines.base import (
    MAX_STEP_MM,
    Agent,
    BaselineAgent,
    move_bounds_mm,
    sample_options_mm,
)

__all__ = [
    "Agent",
    "BaselineAgent",
    "AGENT_REGISTRY",
    "EXTRA_AGENTS",
    "make_agent",
    "parse_agent_spec",
    "sample_options_mm",
    "move_bounds_mm",
    "MAX_STEP_MM",
]


def _registry() -> dict[str, type]:
    """Name → controller class (imported when first needed: min-var and lookahead load scipy's kernels)."""
    from electroloc_gym.baselines.eedi import EEDIAgent
    from electroloc_gym.baselines.infotaxis import InfotaxisAgent
    from electroloc_gym.baselines.lookahead import LookaheadAgent
    from electroloc_gym.baselines.min_variance import MinVarianceAgent
    from electroloc_gym.baselines.random_walk import RandomWalkAgent
    from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent

    return {"rnd-wlk": RandomWalkAgent, "min-var": MinVarianceAgent, "zero-crossing": ZeroCrossingAgent,
            "lookahead": LookaheadAgent, "infotaxis": InfotaxisAgent, "eedi": EEDIAgent}


#: Names of the built-in agents (classes resolved lazily by :func:`make_agent`).
AGENT_REGISTRY: tuple[str, ...] = ("rnd-wlk", "min-var", "zero-crossing")
#: Agents beyond the paper's controllers, built by :func:`make_agent` but not in default benchmark runs.
EXTRA_AGENTS: tuple[str, ...] = ("lookahead", "infotaxis", "eedi")


def parse_agent_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"min-var[n_voters=2500,n_options=16]"`` → ``("min-var", {"n_voters": 2500, ...})``.

    Raises:
        ValueError: malformed spec, option or value, or a key given twice (:mod:`electroloc_gym.agentspec`).
    """
    parsed = _parse(spec)
    return parsed.name, dict(parsed.options)


def make_agent(spec: str | AgentSpec, seed: int | np.random.Generator | None = None) -> BaselineAgent:
    """Build one of the registered controllers from its spec.

    Args:
        spec: ``"rnd-wlk"``, ``"min-var"``, ``"zero-crossing"``, ``"lookahead"`` or e.g.
            ``"min-var[n_voters=2500]"`` (or a parsed :class:`~electroloc_gym.agentspec.AgentSpec`).
        seed: seed of the agent's own generator.

    Raises:
        ValueError: an unknown name or bad options (the message lists the names).
    """
    parsed = spec if isinstance(spec, AgentSpec) else _parse(spec)
    registry = _registry()
    if parsed.name not in registry:
        raise ValueError(f"unknown agent {parsed.name!r}; choose from {list(AGENT_REGISTRY + EXTRA_AGENTS)}")
    try:
        return registry[parsed.name](seed=seed, **parsed.options)
    except TypeError as exc:
        raise ValueError(f"bad options for agent {parsed.name!r} in {parsed.text!r}: {exc}") from exc
