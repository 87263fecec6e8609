"""One episode of an agent in an env: the rollout loop shared by the benchmark and the training evaluation.

The loop is the agent protocol of :mod:`electroloc_gym.baselines.agent` and nothing else::

    obs, info = env.reset(seed=seed)
    agent.seed(agent_seed)            # if given and the agent has its own generator
    agent.reset(agent_view(env))      # bind to the env's agent view after the reset
    repeat: action, state = agent.predict(obs, state, episode_start, deterministic)
            stop if agent.done        # an agent that ends the episode itself (zero-crossing)
            obs, ..., terminated, truncated, info = env.step(action)
    until terminated or truncated

so an episode counted by ``electroloc bench``, one recorded into a dataset and one counted by the
training's seeded evaluation are the same episode. :func:`run_agent` is the public way to run an agent:
it builds the env with the agent's ``env_kwargs`` (what the agent needs of it: zero-crossing's own
budget, a policy's observation mode) and runs one seeded episode or a batch of them through this loop.
The agent is handed the env's agent view (:func:`electroloc_gym.envs.agent_view.agent_view`: the
documented agent accessors, never the ground truth), not the env. Whatever an agent's ``seed``,
``reset`` or ``predict`` raises (any exception, ``SystemExit`` included) comes out as one
:class:`AgentCallError` naming the method, so a caller can tell the agent's failure from the env's.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from electroloc_gym.envs.agent_view import agent_view
from electroloc_gym.registry import PAPER_ENV_ID

__all__ = ["Episode", "run_episode", "run_agent", "AgentCallError", "call_agent"]


class AgentCallError(Exception):
    """An agent's method raised during an episode.

    Attributes:
        method: ``"seed"``, ``"reset"`` or ``"predict"``.
        error: one line: the exception's type and the first line of its message.
    """

    def __init__(self, method: str, error: str) -> None:
        super().__init__(f"its {method}() raised {error}")
        self.method, self.error = method, error

    def __reduce__(self) -> tuple[Any, ...]:  # picklable across worker processes
        return (AgentCallError, (self.method, self.error))


def exception_line(exc: BaseException, limit: int = 300) -> str:
    """``Type: first line of the message``, at most ``limit`` characters."""
    try:
        text = str(exc)
    except Exception:  # noqa: BLE001 - an exception whose __str__ fails still has a type
        text = ""
    first = text.strip().splitlines()[0] if text.strip() else ""
    line = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
    return line if len(line) <= limit else line[: limit - 1] + "…"


def call_agent(method: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)``, an agent's method: what it raises is one :class:`AgentCallError` naming ``method``."""
    try:
        return fn(*args, **kwargs)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - the agent's failure, whatever it is, becomes one line
        raise AgentCallError(method, exception_line(exc)) from None


@dataclass
class Episode:
    """What :func:`run_episode` saw.

    Attributes:
        start_info: the ``info`` of ``env.reset``.
        info: the last ``info`` (of the last ``env.step``; ``start_info`` if the agent stopped first).
        terminated: the env terminated (the belief is tight: the paper's success criterion).
        truncated: the env hit its observation cap.
        ended_by: ``"success"`` (terminated), ``"cap"`` (truncated) or ``"agent"`` (the agent set ``done``).
        decision_s: wall time of every ``agent.predict`` call, seconds.
    """

    start_info: dict[str, Any]
    info: dict[str, Any]
    terminated: bool = False
    truncated: bool = False
    ended_by: str = "cap"
    decision_s: list[float] = field(default_factory=list)


def run_episode(
    env: Any,
    agent: Any,
    seed: int,
    *,
    agent_seed: int | None = None,
    deterministic: bool = True,
    on_step: Callable[[dict[str, Any]], None] | None = None,
) -> Episode:
    """Run one seeded episode of ``agent`` in ``env``.

    Args:
        env: a Gymnasium env (single, not vectorised).
        agent: anything with ``reset(env)`` and SB3's ``predict(obs, state, episode_start, deterministic)``;
            optional ``seed(int)`` and ``done`` (see :mod:`electroloc_gym.baselines.agent`). Its ``reset``
            receives the env's agent view, built after ``env.reset``.
        seed: the ``env.reset`` seed.
        agent_seed: re-seeds the agent's own generator before the episode (ignored when None or when
            the agent has no ``seed`` method).
        deterministic: passed to ``predict``.
        on_step: called with the ``info`` of ``env.reset`` and then of every ``env.step``, right after
            it (the env is in that state: for snapshots and rendered frames).

    Returns:
        The :class:`Episode`.
    """
    obs, info = env.reset(seed=int(seed))
    if agent_seed is not None and hasattr(agent, "seed"):
        call_agent("seed", agent.seed, int(agent_seed))
    view = agent_view(env)
    call_agent("reset", agent.reset, view)
    episode = Episode(start_info=info, info=info)
    if on_step is not None:
        on_step(info)
    state = None
    episode_start = np.ones((1,), dtype=bool)
    while True:
        t0 = time.perf_counter()
        action, state = call_agent(
            "predict", agent.predict, obs, state=state, episode_start=episode_start, deterministic=deterministic
        )
        episode.decision_s.append(time.perf_counter() - t0)
        episode_start = np.zeros((1,), dtype=bool)
        if getattr(agent, "done", False):
            episode.ended_by = "agent"
            return episode
        obs, _, terminated, truncated, episode.info = env.step(action)
        if on_step is not None:
            on_step(episode.info)
        if terminated or truncated:
            episode.terminated, episode.truncated = bool(terminated), bool(truncated)
            episode.ended_by = "success" if terminated else "cap"
            return episode


def run_agent(
    agent: Any,
    env_id: str = PAPER_ENV_ID,
    seeds: int | Sequence[int] = 0,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    agent_seed: int | None = None,
    deterministic: bool = True,
) -> Episode | list[Episode]:
    """Run an agent for one seeded episode, or for each of a batch of seeds, in a new env of ``env_id``.

    The env is ``gym.make(env_id, **agent.env_kwargs, **env_kwargs)``: what the agent needs of its env (its
    ``env_kwargs``, e.g. zero-crossing's own budget of readings or a learned policy's observation mode)
    applied, so an episode is the one ``electroloc bench`` runs. An episode ends when the env terminates or
    truncates, or when the agent says it is done (``agent.done``: an agent that ends the trial itself).

    Args:
        agent: an agent object (``reset(env)`` and SB3's ``predict``), or the spec of a built-in controller
            or the name of a shipped policy (:func:`electroloc_gym.baselines.make_agent`: ``"min-var"``,
            ``"zero-crossing"``, ``"ppo-belief"``).
        env_id: a registered env id.
        seeds: an ``env.reset`` seed (one :class:`Episode`), or a sequence of them (a list, in order).
        env_kwargs: more env arguments (the condition, ...); one that contradicts the agent's own is a
            ``ValueError`` naming it.
        agent_seed: re-seeds the agent's own generator before every episode; None: the episode's seed.
        deterministic: passed to ``predict``.

    Returns:
        The :class:`Episode` of an int seed, or the list of a sequence's episodes.

    Raises:
        ValueError: a bad seed, an unknown agent or env id, or env arguments the agent contradicts.
        AgentCallError: the agent's ``seed``, ``reset`` or ``predict`` raised (one line naming the method).
    """
    import gymnasium as gym

    from electroloc_gym.baselines.agent import make_agent
    from electroloc_gym.utils.checks import check_int

    one = not isinstance(seeds, Sequence) or isinstance(seeds, (str, bytes))
    seed_list: list[Any] = [seeds] if one else list(cast("Sequence[Any]", seeds))
    if not seed_list:
        raise ValueError("seeds must be an int ≥ 0 or a non-empty sequence of them, got an empty sequence")
    seed_list = [check_int("seeds", s, 0, 2**63 - 1) for s in seed_list]
    if agent_seed is not None:
        agent_seed = check_int("agent_seed", agent_seed, 0, 2**63 - 1)
    if isinstance(agent, str):
        agent = make_agent(agent)
    own = dict(getattr(agent, "env_kwargs", None) or {})
    extra = dict(env_kwargs or {})
    for key in sorted(set(own) & set(extra)):
        if extra[key] != own[key]:
            raise ValueError(
                f"env_kwargs[{key!r}]={extra[key]!r} contradicts the agent's own env_kwargs[{key!r}]={own[key]!r} "
                f"(what the agent needs of its env)"
            )
    env = gym.make(env_id, **{**own, **extra})
    try:
        episodes = [
            run_episode(env, agent, s, agent_seed=s if agent_seed is None else agent_seed, deterministic=deterministic)
            for s in seed_list
        ]
    finally:
        env.close()
    return episodes[0] if one else episodes
