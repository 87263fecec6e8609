"""The worker side of a benchmark: one trial spec → one trial record.

A worker builds (and caches) its agents and envs itself from the spec, runs the seeded episode
(:func:`electroloc_gym.baselines.rollout.run_episode`, which hands the agent the env's agent view, never the env) and
returns the record written to trials.jsonl; only here, after the episode, are the env's evaluation
accessors read (the true target or position, the hidden shape).

Steps-to-localize is the number of observations fused (``info["n_observations"]``, the first
reading taken by ``reset`` included), as the paper counts. A trial succeeds when the env terminates
with √trace Σ ≤ 10 mm within the observation cap; an agent that ends trials itself (zero-crossing)
succeeds when it reports an estimate within its observation budget.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from electroloc_gym.baselines.rollout import AgentCallError, exception_line, run_episode
from electroloc_gym.bench.agents import cached_agent, resolve_agent
from electroloc_gym.bench.config import TrialSpec
from electroloc_gym.bench.schema import TrialRecord
from electroloc_gym.contract.task_spec import RecordField
from electroloc_gym.utils.fileio import to_json_data

__all__ = ["run_trial", "TrialFailed", "describe_trial"]


class TrialFailed(ValueError):
    """A trial that could not finish: one line naming the agent, the trial and the exception."""


def describe_trial(spec: TrialSpec) -> str:
    """``agent 'X' in trial K of CONDITION`` (the words of every failure message)."""
    return f"agent {spec.agent!r} in trial {spec.trial} of {spec.condition}"


_ENVS: dict[tuple[Any, ...], Any] = {}


def _env(spec: TrialSpec, agent: Any) -> Any:
    import gymnasium as gym

    kwargs = spec.env_kwargs(agent, builtin=resolve_agent(spec.agent).builtin)
    key = (spec.env_id, spec.condition, spec.signal, spec.agent, repr(sorted(kwargs.items(), key=lambda kv: kv[0])))
    if key not in _ENVS:
        if len(_ENVS) > 16:
            for env in _ENVS.values():
                env.close()
            _ENVS.clear()
        _ENVS[key] = gym.make(spec.env_id, **kwargs)
    return _ENVS[key]


def run_trial(spec: TrialSpec) -> dict[str, Any]:
    """Run one trial and return its record (the worker function of every backend), checked by its schema.

    Raises:
        TrialFailed: the agent's ``seed``, ``reset`` or ``predict`` raised (any exception, ``SystemExit``
            and ``MemoryError`` included), the agent did not build in this worker, or the trial failed
            otherwise — one line naming the agent, the trial and the exception.
    """
    try:
        return _run_trial(spec)
    except KeyboardInterrupt:
        raise
    except AgentCallError as exc:
        raise TrialFailed(f"{describe_trial(spec)}: {exc}") from None
    except BaseException as exc:  # noqa: BLE001 - any failure of a trial is reported in one line
        raise TrialFailed(f"{describe_trial(spec)} failed: {exception_line(exc)}") from None


def _run_trial(spec: TrialSpec) -> dict[str, Any]:
    t_start = time.perf_counter()
    agent = cached_agent(spec.agent, trust_pickle=spec.trust_pickle)
    env = _env(spec, agent)
    ep = run_episode(env, agent, spec.env_seed, agent_seed=spec.agent_seed)
    info = ep.info
    start = ep.start_info["position_mm"]
    core = env.unwrapped
    target = core.truth_mm  # evaluation only: what the belief estimates (the target, or the robot's own position)
    table_layout = str(getattr(agent, "table_layout", "table4"))
    if ep.ended_by == "agent" or table_layout == "table1":  # an agent that ends trials itself reports its estimate
        est = getattr(agent, "estimate_mm", None)
        success = bool(ep.ended_by == "agent" and est is not None)
        estimate = None if est is None else [float(est[0]), float(est[1])]
    else:
        success = bool(ep.terminated and info["success"])
        estimate = [float(info["estimate_mm"][0]), float(info["estimate_mm"][1])]
    err_xy = None if estimate is None else np.asarray(estimate) - target
    error = None if err_xy is None else float(np.hypot(*err_xy))
    dms = np.asarray(ep.decision_s) * 1e3
    return TrialRecord.from_json(
        {
            "condition": spec.condition,
            "agent": spec.agent,
            "agent_label": str(getattr(agent, "name", spec.agent)),
            "table_layout": table_layout,
            "trial": spec.trial,
            "seed": spec.env_seed,
            "agent_seed": spec.agent_seed,
            "success": success,
            "ended_by": ep.ended_by,
            "readings": int(info["n_observations"]),
            "error_mm": to_json_data(error),
            "error_x_mm": to_json_data(None if err_xy is None else float(err_xy[0])),
            "error_y_mm": to_json_data(None if err_xy is None else float(err_xy[1])),
            "estimate": estimate,
            "target": [float(target[0]), float(target[1])],
            "start": [float(start[0]), float(start[1])],
            "spread_mm": to_json_data(info.get("spread_mm")),
            "decisions": int(dms.size),
            "decision_ms_median": float(np.median(dms)) if dms.size else None,
            "decision_ms_mean": float(np.mean(dms)) if dms.size else None,
            "wall_s": time.perf_counter() - t_start,
            "shape": _shape_record(info, core.entry().task_class.metrics.record) or None,
            **spec.config.record_settings(),
        }
    ).to_json()


def _shape_record(info: dict[str, Any], fields: tuple[RecordField, ...]) -> dict[str, Any]:
    """The task's own results (its declared record fields, ``Task.metrics.record``) of the final info, as JSON
    values (a choice by its string).
    """
    out: dict[str, Any] = {}
    for f in fields:
        v = f.from_info(info)
        out[f.name] = str(v) if isinstance(v, str) else to_json_data(v if isinstance(v, (bool, np.bool_)) else float(v))
    return out
