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
training's seeded evaluation are the same episode. The agent is handed the env's agent view
(:func:`electroloc_gym.envs.agent_view.agent_view`: the documented agent accessors, never the ground
truth), not the env. Whatever an agent's ``seed``, ``reset`` or ``predict`` raises (any exception,
``SystemExit`` included) comes out as one :class:`AgentCallError` naming the method, so a caller can
tell the agent's failure from the env's.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from electroloc_gym.envs.agent_view import agent_view

__all__ = ["Episode", "run_episode", "AgentCallError"]


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


def _call(method: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
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
        _call("seed", agent.seed, int(agent_seed))
    view = agent_view(env)
    _call("reset", agent.reset, view)
    episode = Episode(start_info=info, info=info)
    if on_step is not None:
        on_step(info)
    state = None
    episode_start = np.ones((1,), dtype=bool)
    while True:
        t0 = time.perf_counter()
        action, state = _call(
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
