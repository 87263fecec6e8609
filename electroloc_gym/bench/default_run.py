"""What a benchmark run without ``--agents`` runs: the paper's controllers, then the shipped learned policies.

:func:`default_agents` lists every agent such a run considers, in order, each an :class:`AgentChoice`: the
controllers first (a bench row's own set, or the paper's three, and ``min-var[gain=preset]`` beside
``min-var`` when the run chooses among gain levels), then every shipped model of ``electroloc_gym.models``.
A shipped model runs only where it was trained: one recorded for another env or other gain levels, or
for another sensor layout, is listed as skipped with the reason and the ``electroloc bench`` options of
the run it belongs to (:func:`_bench_options_of` finds the bench row); one that cannot load here (the
training extra missing, its files refused) is skipped with the loader's reason. Nothing is read from the
working directory: only the installed models are candidates.

Agents are built through the registry (:func:`electroloc_gym.bench.agents.cached_agent`), so a model
checked here is the one the run then uses; what a model was trained on is read from its files
(:mod:`electroloc_gym.bench.policy_fit`).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

from electroloc_gym.baselines.agent import PAPER_AGENTS
from electroloc_gym.bench.agents import TRAIN_EXTRA_HINT, cached_agent
from electroloc_gym.bench.policy_fit import policy_meta, shipped_model_env, shipped_models, trained_sensor_layout
from electroloc_gym.registry import BENCH_ENVS, PAPER_ENV_ID

__all__ = ["AgentChoice", "default_agents"]


@dataclass(frozen=True)
class AgentChoice:
    """An agent a default run considered: its spec, why it was skipped (None: it runs), and for a shipped
    policy trained on other settings the ``electroloc bench`` options it runs with (None: unknown).
    """

    spec: str
    skipped: str | None = None
    runs_with: str | None = None


def _bench_options_of(env_id: str, gain_levels: tuple[float, ...] | None) -> str | None:
    """The ``--env`` option of the bench row that runs ``env_id`` with these gain levels (None: no row)."""
    for name, (entry, row) in BENCH_ENVS.items():
        levels = row.env_kwargs.get("gain_levels")
        if entry.env_id == env_id and (None if levels is None else tuple(levels)) == gain_levels:
            return f"--env {name}"
    return None


def _training_extra_missing() -> str | None:
    """Why learned policies cannot run here (None: they can)."""
    module = "electroloc_gym.policy"
    try:
        if importlib.util.find_spec(module) is None:
            return f"the training extra is not installed ({module} missing; {TRAIN_EXTRA_HINT})"
    except (ImportError, ValueError) as exc:
        return f"the training extra is not importable ({module}: {exc})"
    return None


def default_agents(
    *,
    names: tuple[str, ...] | None = None,
    trust_pickle: bool = False,
    env_id: str = PAPER_ENV_ID,
    gain_levels: tuple[float, ...] | None = None,
    sensor_layout: str | None = None,
) -> list[AgentChoice]:
    """What a run on ``env_id`` with ``gain_levels`` and ``sensor_layout`` (None: the paper's single pair)
    considers without ``--agents`` (module docstring): ``names``, the controllers (None: the paper's three),
    then every shipped model, each loaded with ``trust_pickle`` or skipped with the reason.
    """
    choices = [AgentChoice(name) for name in (PAPER_AGENTS if names is None else names)]
    if gain_levels is not None:
        choices.insert(2, AgentChoice("min-var[gain=preset]"))
    models = shipped_models()
    missing = _training_extra_missing() if models else None
    for name, folder in models.items():
        trained_on = shipped_model_env(folder)
        if trained_on is not None and trained_on != (env_id, gain_levels):
            what = trained_on[0] + ("" if trained_on[1] is None else f" with gain_levels={list(trained_on[1])}")
            here = env_id + ("" if gain_levels is None else f" with gain_levels={list(gain_levels)}")
            choice = AgentChoice(name, f"trained on {what}, not {here}", _bench_options_of(*trained_on))
        elif (layout := trained_sensor_layout(policy_meta(name))) is not None and layout != (sensor_layout or "single"):
            choice = AgentChoice(
                name,
                f"trained with sensor_layout={layout!r}, not {sensor_layout or 'single'!r}",
                f"--sensor-layout {layout}",
            )
        elif missing:
            choice = AgentChoice(name, missing)
        else:
            try:
                cached_agent(name, trust_pickle=trust_pickle)
                choice = AgentChoice(name)
            except ValueError as exc:
                choice = AgentChoice(name, str(exc))
        choices.append(choice)
    return choices
