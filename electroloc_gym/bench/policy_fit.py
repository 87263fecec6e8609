"""What a learned policy was trained on, and whether it fits a benchmark run.

A policy's ``policy.json`` records the env id, the env kwargs (gain levels, sensor layout, observation
mode) and the spaces it was trained with; the benchmark builds each trial's env from the run's settings
plus the agent's own env kwargs (:func:`bench_env_kwargs`) and refuses, before any trial, a policy
whose record does not fit that env (:func:`policy_env_problem`). Everything here reads plain JSON.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from electroloc_gym.models import shipped_models
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import user_path
from electroloc_gym.world.conditions import get_condition

# The bench owns these env kwargs; no agent's env_kwargs override them.
_BENCH_ONLY_KWARGS = (
    "condition",
    "signal",
    "randomize_target",
    "render_mode",
    "gain_levels",
    "sensor_layout",
    "distractors",
)
#: The env kwargs a plug-in agent (a user's factory or object, a learned policy) may set: how it observes and
#: acts. Everything else an env takes decides what a trial means (the protocol: cap, particles, success
#: criterion, sensor model, tank, target draw, ...) and is the run's alone; only the built-in controllers,
#: whose options are part of their spec, set more (zero-crossing: the paper's Table-1 protocol).
AGENT_ENV_KWARGS = ("observation", "action_type")


def agent_env_kwargs(env_id: str | None) -> tuple[str, ...]:
    """The env kwargs an agent may set on ``env_id``: :data:`AGENT_ENV_KWARGS`, then the options its task
    declares the agent's own (``EnvEntry.agent_arguments``); None: the first only.
    """
    return AGENT_ENV_KWARGS + (env_entry(env_id).agent_arguments if env_id is not None else ())


#: Hooks of the agent protocol that change what a trial is, honoured for the built-in controllers only.
BUILTIN_HOOKS = ("adapt_condition",)


def plug_in_problem(agent: Any, env_id: str | None = None) -> str | None:
    """Why a plug-in agent would change the run's protocol on ``env_id`` (None: it does not): ``env_kwargs``
    beyond :func:`agent_env_kwargs`, a :data:`BUILTIN_HOOKS` hook, or a table layout other than Table 4's.
    """
    kwargs = getattr(agent, "env_kwargs", None) or {}
    if not isinstance(kwargs, dict):
        return f"env_kwargs must be a dict, got {type(kwargs).__name__}"
    allowed = agent_env_kwargs(env_id)
    extra = sorted(str(k) for k in kwargs if k not in allowed)
    if extra:
        return (
            f"its env_kwargs set {extra[:6]}{' …' if len(extra) > 6 else ''}, which the benchmark fixes for "
            f"every agent (an agent's env_kwargs may set only {list(allowed)})"
        )
    hooks = [h for h in BUILTIN_HOOKS if callable(getattr(agent, h, None))]
    if hooks:
        return f"it defines {hooks}, a hook of the built-in controllers only (the benchmark fixes the workspace)"
    layout = getattr(agent, "table_layout", "table4")
    if layout != "table4":
        return (
            f"its layout is {str(layout)[:40]!r}; a plug-in agent is judged by the belief (Table-4 layout), "
            f"only the built-in zero-crossing reports to Table 1"
        )
    return None


def bench_env_kwargs(
    env_id: str,
    agent: Any,
    gain_levels: tuple[float, ...] | None,
    *,
    condition: str | None = None,
    signal: str | None = None,
    sensor_model: str | None = None,
    n_particles: int | None = None,
    max_observations: int | None = None,
    sensor_layout: str | None = None,
    distractors: int = 0,
    success_spread_mm: float | None = None,
    builtin: bool = False,
) -> dict[str, Any]:
    """The ``gym.make`` kwargs of a trial: the run's settings, then the agent's own ``env_kwargs`` (``agent``
    None: none). A plug-in agent (``builtin`` false) adds only :func:`agent_env_kwargs` and its hooks are not
    called; a built-in controller's ``env_kwargs`` and ``adapt_condition`` apply, never overriding what the
    bench owns (the tank, the layout, the distractors).
    """
    kwargs: dict[str, Any] = {
        k: v
        for k, v in (
            ("sensor_model", sensor_model),
            ("n_particles", n_particles),
            ("max_observations", max_observations),
            ("success_spread_mm", success_spread_mm),
        )
        if v is not None
    }
    entry = env_entry(env_id)
    if entry.takes("condition") and condition is not None:  # an env with one fixed map takes no condition
        if signal is None:
            raise ValueError(f"signal must be 'fitted', 'paper', 'coverage' or a positive float, got {signal!r}")
        cond = get_condition(condition, signal)
        adapt = getattr(agent, "adapt_condition", None) if builtin else None
        if callable(adapt):
            cond = adapt(cond)
        kwargs["condition"] = cond
    kwargs.update(entry.bench_kwargs)
    if gain_levels is not None:
        kwargs["gain_levels"] = tuple(gain_levels)
    if sensor_layout is not None:
        kwargs["sensor_layout"] = sensor_layout
    if distractors:
        kwargs["distractors"] = int(distractors)
    own = getattr(agent, "env_kwargs", None) or {}
    if isinstance(own, dict):
        allowed = agent_env_kwargs(env_id)
        kwargs.update({k: v for k, v in own.items() if k not in _BENCH_ONLY_KWARGS and (builtin or k in allowed)})
    return kwargs


def shipped_model_env(folder: Path) -> tuple[str, tuple[float, ...] | None] | None:
    """(env id, gain levels) a shipped policy was trained on (its policy.json's ``observation.env_id``
    and ``env_kwargs.gain_levels``), or None if the file does not say.
    """
    meta = _read_meta(folder)
    if meta is None:
        return None
    try:
        return meta["observation"]["env_id"], trained_gain_levels(meta)
    except ValueError:
        return None


def trained_gain_levels(meta: dict[str, Any]) -> tuple[float, ...] | None:
    """The dynamic-gain levels a policy was trained with (its policy.json's ``env_kwargs.gain_levels``; None: the
    preset gain).

    Raises:
        ValueError: a value that is not a list of numbers (``env_kwargs`` is the training run's record: plain
            data, which the format's schema does not type).
    """
    gains = (meta.get("env_kwargs") or {}).get("gain_levels")
    try:
        return None if gains is None else tuple(float(g) for g in gains)
    except (TypeError, ValueError):
        raise ValueError(f"env_kwargs.gain_levels must be a list of numbers, got {gains!r}") from None


def _read_meta(path: Path) -> dict[str, Any] | None:
    """The policy.json a policy path names (:func:`~electroloc_gym.policy.format.policy_folder`, as loading it
    does) read through its one schema (:func:`~electroloc_gym.policy.format.read_export`); None where it is
    missing or refused (loading the policy says why).
    """
    from electroloc_gym.policy.format import PolicyFormatError, policy_folder, read_export

    try:
        return read_export(policy_folder(path)).meta
    except (PolicyFormatError, OSError):
        return None


def trained_sensor_layout(meta: Any) -> str | None:
    """The named sensor layout a policy was trained with (its policy.json's ``env_kwargs.sensor_layout``;
    ``"single"``, the paper's one pair, when it records none), or None when it records something else
    (explicit offsets: the observation-frame check decides).
    """
    kwargs = meta.get("env_kwargs") if isinstance(meta, dict) else None
    layout = kwargs.get("sensor_layout", "single") if isinstance(kwargs, dict) else "single"
    return layout if isinstance(layout, str) else None


def policy_meta(spec: str) -> dict[str, Any] | None:
    """The ``policy.json`` of a shipped model or a policy path (None: none, or refused by its schema)."""
    return _read_meta(shipped_models().get(spec) or user_path(spec))


def _space_text(space: Any) -> str:
    shape = getattr(space, "shape", None)
    n = getattr(space, "n", None)
    return f"Discrete({int(n)})" if n is not None and not shape else f"{type(space).__name__}{tuple(shape or ())}"


def policy_env_problem(
    spec: str, agent: Any, env_id: str, gain_levels: tuple[float, ...] | None, sensor_layout: str | None = None
) -> str | None:
    """Why a learned policy cannot run on the run's env (None: it can, or it records nothing to check).

    Compares what the policy's ``policy.json`` records — the env id it was trained on, its dynamic-gain
    levels, sensor layout, observation frame (``observation.frame_dim``) and action space — with the run's env
    built with the policy's own ``env_kwargs``. A policy trained on one env gives meaningless numbers on
    another: there is no override. The record is read through its schema, so its keys are there.
    """
    meta = policy_meta(spec)
    if meta is None:
        return None
    obs, act = meta["observation"], meta["action"]
    if obs["env_id"] != env_id:
        return f"it was trained on {obs['env_id']}, this run is on {env_id}"
    try:
        recorded = trained_gain_levels(meta)
    except ValueError as exc:
        return f"its policy.json's {exc}"
    mine = None if gain_levels is None else [float(g) for g in gain_levels]
    theirs = None if recorded is None else list(recorded)
    if theirs != mine:
        return f"it was trained with gain_levels={theirs}, this run has gain_levels={mine}"
    layout, run_layout = trained_sensor_layout(meta), sensor_layout or "single"
    if layout is not None and layout != run_layout:
        return f"it was trained with sensor_layout={layout!r}, this run has sensor_layout={run_layout!r}"
    import gymnasium as gym

    try:
        env = gym.make(env_id, **bench_env_kwargs(env_id, agent, gain_levels, sensor_layout=sensor_layout))
    except (TypeError, ValueError) as exc:
        return f"its env_kwargs do not build {env_id}: {exc}"
    try:
        frame = obs["frame_dim"]
        env_frame = env.observation_space.shape[-1] if env.observation_space.shape else None
        if env_frame is not None and int(frame) != int(env_frame):
            return (
                f"its observation frame has {frame} entries, {env_id}'s "
                f"({getattr(agent, 'env_kwargs', {}).get('observation', 'default')} observation) has {env_frame}"
            )
        space = act["space"]  # the schema ties action_type "discrete" to a Discrete space, and gives a Box a shape
        if space["type"] == "Discrete":
            if getattr(env.action_space, "n", None) != space["n"]:
                return f"its action space is Discrete({space['n']}), {env_id}'s is {_space_text(env.action_space)}"
        elif tuple(space["shape"]) != tuple(env.action_space.shape or ()):
            return f"its action space has shape {tuple(space['shape'])}, {env_id}'s is {_space_text(env.action_space)}"
    finally:
        env.close()
    return None
