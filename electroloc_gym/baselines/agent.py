"""The agent registry: names → the controllers, built from an agent spec by :func:`make_agent`.

The package's one registry of built-in agents: their names are declared here once
(:data:`PAPER_AGENTS`, :data:`EXTRA_AGENTS`, :data:`AGENT_NAMES`) and the benchmark's agent resolver
(:mod:`electroloc_gym.bench.agents`, which adds shipped models, policy paths and users' factories) and its
tables read them. A spec is a name, optionally with keyword options in brackets
(``min-var[n_voters=2500]``, ``lookahead[objective=steps,depth=2]``), parsed by the package's one spec
parser (:mod:`electroloc_gym.utils.agentspec`, re-exported as :func:`parse_agent_spec`).
The agent protocol and the controllers' common base live in
:mod:`electroloc_gym.baselines.base` (re-exported here); the controller modules import that module,
never this one, so the registry → controllers imports run one way.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from electroloc_gym.baselines.base import (
    MAX_STEP_MM,
    Agent,
    BaselineAgent,
    move_bounds_mm,
    sample_options_mm,
)
from electroloc_gym.models import shipped_models
from electroloc_gym.utils.agentspec import AgentSpec, parse_agent_spec

__all__ = [
    "Agent",
    "BaselineAgent",
    "AGENT_REGISTRY",
    "PAPER_AGENTS",
    "EXTRA_AGENTS",
    "AGENT_NAMES",
    "RANDOM_AGENT",
    "PLANNER_AGENTS",
    "belief_agents",
    "agent_class",
    "make_agent",
    "parse_agent_spec",
    "sample_options_mm",
    "move_bounds_mm",
    "MAX_STEP_MM",
]


def _registry() -> dict[str, type]:
    """Name → controller class (imported when first needed: min-var and lookahead load scipy's kernels);
    each class's ``name`` is its registry name.
    """
    from electroloc_gym.baselines.eedi import EEDIAgent
    from electroloc_gym.baselines.hybrid import HybridAgent
    from electroloc_gym.baselines.infotaxis import InfotaxisAgent
    from electroloc_gym.baselines.lookahead import LookaheadAgent
    from electroloc_gym.baselines.min_variance import MinVarianceAgent
    from electroloc_gym.baselines.pursuit import PursuitAgent
    from electroloc_gym.baselines.random_walk import RandomWalkAgent
    from electroloc_gym.baselines.zero_crossing import ZeroCrossingAgent

    classes = (
        RandomWalkAgent,
        MinVarianceAgent,
        ZeroCrossingAgent,
        LookaheadAgent,
        InfotaxisAgent,
        EEDIAgent,
        PursuitAgent,
        HybridAgent,
    )
    return {cls.name: cls for cls in classes}


#: The random walk, the chance level: the normalised scores' 0 (a dataset's reference scores, the learned
#: and offline policies' reports).
RANDOM_AGENT: str = "rnd-wlk"
#: The paper's three controllers: a default benchmark run's agents, and the paper's rows of its tables.
PAPER_AGENTS: tuple[str, ...] = (RANDOM_AGENT, "min-var", "zero-crossing")
#: The paper's controllers under their older name.
AGENT_REGISTRY = PAPER_AGENTS
#: Agents beyond the paper's controllers, built by :func:`make_agent` but not in default benchmark runs.
EXTRA_AGENTS: tuple[str, ...] = ("lookahead", "infotaxis", "eedi", "pursuit", "hybrid")
#: Every built-in agent's name.
AGENT_NAMES: tuple[str, ...] = PAPER_AGENTS + EXTRA_AGENTS
#: The non-learned planners that choose moves by the belief: the best of them is the normalised scores' 1.
PLANNER_AGENTS: tuple[str, ...] = ("min-var", "lookahead", "infotaxis", "eedi")


def agent_class(name: str) -> type:
    """The controller class registered as ``name``.

    Raises:
        ValueError: an unknown name (the message lists the names).
    """
    registry = _registry()
    if name not in registry:
        raise ValueError(
            f"unknown agent {name!r}; choose from {list(AGENT_NAMES)} or a shipped policy {sorted(shipped_models())}"
        )
    return registry[name]


def belief_agents() -> tuple[str, ...]:
    """The built-in agents judged by the belief (the Table-4 layout), in registry order: every controller but
    those that end trials with their own estimate (zero-crossing, the paper's Table 1).
    """
    return tuple(name for name, cls in _registry().items() if getattr(cls, "table_layout", "table4") == "table4")


def make_agent(spec: str | AgentSpec, seed: int | np.random.Generator | None = None) -> Any:
    """Build one of the registered controllers from its spec.

    Args:
        spec: ``"rnd-wlk"``, ``"min-var"``, ``"zero-crossing"``, ``"lookahead"`` or e.g.
            ``"min-var[n_voters=2500]"`` (or a parsed :class:`~electroloc_gym.utils.agentspec.AgentSpec`), or
            the name of a shipped learned policy (``"ppo-belief"``: :func:`electroloc_gym.policy.load_policy`).
        seed: seed of the agent's own generator.

    An option a task declares the agent's own (the moving target's ``motion_model``, say) goes to the agent's
    ``env_kwargs``, not to its constructor.

    Raises:
        ValueError: an unknown name or bad options (the message lists the names).
    """
    parsed = spec if isinstance(spec, AgentSpec) else parse_agent_spec(spec)
    if parsed.name not in _registry() and parsed.name in shipped_models():
        if parsed.options:
            raise ValueError(f"the shipped policy {parsed.name!r} takes no options, got {parsed.text!r}")
        from electroloc_gym.policy import load_policy  # the agents' layer: numpy only

        return load_policy(parsed.name)
    cls = agent_class(parsed.name)
    own_env = _agent_env_options()
    env_options = {k: v for k, v in parsed.options.items() if k in own_env}
    try:
        agent = cls(seed=seed, **{k: v for k, v in parsed.options.items() if k not in env_options})
    except TypeError as exc:
        raise ValueError(f"bad options for agent {parsed.name!r} in {parsed.text!r}: {exc}") from exc
    agent.env_kwargs = {**agent.env_kwargs, **env_options}
    return agent


def _agent_env_options() -> frozenset[str]:
    """The env options some registered task declares the agent's own (``EnvEntry.agent_arguments``): in a
    controller's spec they go to its ``env_kwargs`` (``min-var[motion_model=swimmer]``: min-var with the
    moving target's velocity belief), the env checking their values when it is made.
    """
    from electroloc_gym.registry import ENVS

    return frozenset(name for entry in ENVS for name in entry.agent_arguments)
