"""The worker side of a benchmark: one trial spec → one trial record.

A worker builds (and caches) its agents and envs itself from the spec, runs the seeded episode
(:func:`electroloc_gym.bench.rollout.run_episode`) and returns the record written to trials.jsonl.

Steps-to-localize is the number of observations fused (``info["n_observations"]``, the first
reading taken by ``reset`` included), as the paper counts. A trial succeeds when the env terminates
with √trace Σ ≤ 10 mm within the observation cap; an agent that ends trials itself (zero-crossing)
succeeds when it reports an estimate within its observation budget.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from electroloc_gym.bench.agents import cached_agent
from electroloc_gym.bench.config import GLOBAL_ENV_ID, UNKNOWN_ENV_ID, TrialSpec
from electroloc_gym.bench.rollout import run_episode
from electroloc_gym.conditions import get_condition

__all__ = ["run_trial", "TIMING_KEYS", "RECORD_KEYS"]

#: Keys of a trial record that vary run to run (timings); everything else is deterministic.
TIMING_KEYS = ("decision_ms_median", "decision_ms_mean", "wall_s")
#: Every key of a trial record (what :func:`run_trial` writes; :mod:`electroloc_gym.bench.records` checks it).
RECORD_KEYS = ("condition", "agent", "agent_label", "layout", "trial", "seed", "agent_seed", "success", "ended_by",
               "observations", "error_mm", "error_x_mm", "error_y_mm", "estimate", "target", "start", "spread_mm",
               "decisions", "decision_ms_median", "decision_ms_mean", "sensor_model", "signal", "max_observations",
               "n_particles", "env_id", "wall_s", "shape", "gain_levels", "sensor_layout")
#: Keys a record may lack (records written before the key existed read as None).
OPTIONAL_RECORD_KEYS = ("shape", "gain_levels", "sensor_layout")
#: The unknown-target env's identification results in a record's ``"shape"`` (None elsewhere).
SHAPE_RECORD_KEYS = ("radius_estimate_mm", "radius_mean_mm", "radius_spread_mm", "target_radius_mm",
                     "radius_error_frac", "p_conductor", "material_estimate", "material_correct", "chi_estimate",
                     "target_chi")
# The bench owns these env kwargs; an agent's env_kwargs cannot override them.
_BENCH_ONLY_KWARGS = ("condition", "signal", "randomize_target", "render_mode", "gain_levels", "sensor_layout")
_ENVS: dict[tuple[Any, ...], Any] = {}


def _env(spec: TrialSpec, agent: Any) -> Any:
    import gymnasium as gym

    import electroloc_gym  # noqa: F401  (registers the ids in a fresh worker)

    kwargs: dict[str, Any] = {"sensor_model": spec.sensor_model, "n_particles": spec.n_particles,
                              "max_observations": spec.max_observations}
    if spec.env_id != GLOBAL_ENV_ID:  # the global env has one fixed map and no condition kwarg
        condition = get_condition(spec.condition, spec.signal)
        adapt = getattr(agent, "adapt_condition", None)
        if callable(adapt):
            condition = adapt(condition)
        kwargs["condition"] = condition
    if spec.env_id == UNKNOWN_ENV_ID:  # the paper's sphere/water pairs, the sphere hidden from the agent
        kwargs["target_draw"] = "condition"
    if spec.gain_levels is not None:
        kwargs["gain_levels"] = tuple(spec.gain_levels)
    if spec.sensor_layout is not None:
        kwargs["sensor_layout"] = spec.sensor_layout
    kwargs.update({k: v for k, v in dict(getattr(agent, "env_kwargs", {}) or {}).items()
                   if k not in _BENCH_ONLY_KWARGS})
    key = (spec.env_id, spec.condition, spec.signal, spec.agent, repr(sorted(kwargs.items(), key=lambda kv: kv[0])))
    if key not in _ENVS:
        if len(_ENVS) > 16:
            for env in _ENVS.values():
                env.close()
            _ENVS.clear()
        _ENVS[key] = gym.make(spec.env_id, **kwargs)
    return _ENVS[key]


def _finite_or_none(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def run_trial(spec: TrialSpec) -> dict[str, Any]:
    """Run one trial and return its record (the worker function of every backend)."""
    t_start = time.perf_counter()
    agent = cached_agent(spec.agent, trust_pickle=spec.trust_pickle)
    env = _env(spec, agent)
    ep = run_episode(env, agent, spec.env_seed, agent_seed=spec.agent_seed)
    info = ep.info
    start = ep.start_info["position_mm"]
    core = env.unwrapped
    if spec.env_id == GLOBAL_ENV_ID:  # the hidden state is the robot's own (final) position
        target = np.asarray(info["position_mm"], dtype=float)  # evaluation only
    else:
        target = np.asarray(core.target_mm, dtype=float)  # evaluation only (the documented ground-truth accessor)
    layout = str(getattr(agent, "layout", "table4"))
    if ep.ended_by == "agent" or layout == "table1":  # an agent that ends trials itself reports its estimate
        est = getattr(agent, "estimate_mm", None)
        success = bool(ep.ended_by == "agent" and est is not None)
        estimate = None if est is None else [float(est[0]), float(est[1])]
    else:
        success = bool(ep.terminated and info["success"])
        estimate = [float(info["estimate_mm"][0]), float(info["estimate_mm"][1])]
    if estimate is not None:
        err_xy = np.asarray(estimate) - target
        error: float | None = float(np.hypot(*err_xy))
        error_x: float | None = float(err_xy[0])
        error_y: float | None = float(err_xy[1])
    else:
        error = error_x = error_y = None
    dms = np.asarray(ep.decision_s) * 1e3
    return {
        "condition": spec.condition,
        "agent": spec.agent,
        "agent_label": str(getattr(agent, "name", spec.agent)),
        "layout": layout,
        "trial": spec.trial,
        "seed": spec.env_seed,
        "agent_seed": spec.agent_seed,
        "success": success,
        "ended_by": ep.ended_by,
        "observations": int(info["n_observations"]),
        "error_mm": _finite_or_none(error),
        "error_x_mm": _finite_or_none(error_x),
        "error_y_mm": _finite_or_none(error_y),
        "estimate": estimate,
        "target": [float(target[0]), float(target[1])],
        "start": [float(start[0]), float(start[1])],
        "spread_mm": _finite_or_none(info.get("spread_mm")),
        "decisions": int(dms.size),
        "decision_ms_median": float(np.median(dms)) if dms.size else None,
        "decision_ms_mean": float(np.mean(dms)) if dms.size else None,
        "sensor_model": spec.sensor_model,
        "signal": spec.signal,
        "max_observations": spec.max_observations,
        "n_particles": spec.n_particles,
        "env_id": spec.env_id,
        "wall_s": time.perf_counter() - t_start,
        "shape": _shape_record(info) if spec.env_id == UNKNOWN_ENV_ID else None,
        "gain_levels": None if spec.gain_levels is None else list(spec.gain_levels),
        "sensor_layout": spec.sensor_layout,
    }


def _shape_record(info: dict[str, Any]) -> dict[str, Any]:
    """The unknown-target env's final size and material estimates and their truth (JSON values)."""
    out: dict[str, Any] = {}
    for k in SHAPE_RECORD_KEYS:
        v = info[k]
        out[k] = str(v) if isinstance(v, str) else (bool(v) if isinstance(v, (bool, np.bool_)) else _finite_or_none(v))
    return out
