"""The benchmark's agent registry: the paper's controllers, the shipped learned policies, policy paths.

An agent *spec* (what ``--agents`` takes, and the ``agent`` key of every trial record) is one of

* a controller of the paper, optionally with options: ``rnd-wlk``, ``min-var``, ``zero-crossing``,
  ``min-var[n_voters=2500]`` — built by :func:`electroloc_gym.baselines.make_agent`;
* the name of a shipped learned policy, ``ppo-belief`` — a folder of ``electroloc_gym.models``
  (the repository's ``models/``, installed with the package);
* a path to a model folder or a policy file (anything with a ``/``, starting with ``.`` or ``~``,
  ending in ``.zip``, or an existing folder);
* a user's factory, ``package.module:factory[key=value,...]``: the module is imported (it must be
  importable: installed, or on ``PYTHONPATH`` — nothing is picked up from the working directory), the
  factory called with the options, and the object it returns must have the agent protocol
  (:func:`protocol_problem`). Importing the module runs its code, as ``import`` would.

Specs are parsed by the package's one parser (:mod:`electroloc_gym.agentspec`). Every failure —
an unknown name, a bad option, a module that does not import, a factory that raises or returns
something without ``reset``/``predict``, a policy recorded for another env, observation layout or
action space (:func:`policy_env_problem`) — is one ``ValueError`` naming the spec, raised before any
trial runs.

Learned policies load through :func:`electroloc_gym.policy.load.load_policy`, which reads the
project's pickle-free policy files; a bare SB3 ``.zip`` (pickle inside) loads only with
``trust_pickle=True`` (``--trust-pickle``). The paper's controllers never import the training package.
Nothing is picked up from the working directory: a default run uses the shipped models only.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from electroloc_gym.agentspec import AgentSpec, is_path_like, parse_agent_spec
from electroloc_gym.baselines.agent import AGENT_REGISTRY, EXTRA_AGENTS, make_agent
from electroloc_gym.bench.config import GLOBAL_ENV_ID, UNKNOWN_ENV_ID
from electroloc_gym.conditions import get_condition

__all__ = [
    "AgentChoice",
    "shipped_models",
    "is_policy_path",
    "agent_kind",
    "agent_display_name",
    "make_bench_agent",
    "make_factory_agent",
    "protocol_problem",
    "policy_env_problem",
    "cached_agent",
    "register_object_agent",
    "bench_env_kwargs",
    "planner_memory_bytes",
    "default_agents",
    "TRAIN_EXTRA_HINT",
]

TRAIN_EXTRA_HINT = "pip install 'electroloc-gym[train]'"


@dataclass(frozen=True)
class AgentChoice:
    """An agent a default run considered: its spec, and why it was skipped (None: it runs)."""

    spec: str
    skipped: str | None = None


def shipped_models() -> dict[str, Path]:
    """Name → folder of every shipped learned policy (a folder of ``electroloc_gym.models``)."""
    from electroloc_gym.models import MODELS_DIR

    return {p.name: p for p in sorted(MODELS_DIR.iterdir())
            if p.is_dir() and not p.name.startswith((".", "_")) and any(p.iterdir())}


def is_policy_path(spec: str) -> bool:
    """True when ``spec`` is written as a path (``/``, leading ``.`` or ``~``, ``.zip``) or is a folder."""
    return is_path_like(spec) or Path(spec).is_dir()


#: Agent objects handed to the Python API (:func:`electroloc_gym.bench.api.run`), by the name they run under.
_OBJECTS: dict[str, Any] = {}


def register_object_agent(name: str, agent: Any) -> None:
    """Make ``agent`` (an object with the agent protocol) the agent named ``name`` in this process.

    Raises:
        ValueError: ``name`` not a plain agent name, taken by a built-in agent or shipped model, or the
            object lacks the protocol.
    """
    parsed = parse_agent_spec(name)
    if parsed.options or parsed.is_factory or parsed.name in AGENT_REGISTRY + EXTRA_AGENTS or name in shipped_models():
        raise ValueError(f"agent object name {name!r} must be a plain name other than the built-in agents' and "
                         f"shipped models'")
    why = protocol_problem(agent)
    if why is not None:
        raise ValueError(f"agent object {name!r} ({type(agent).__name__}) is not an agent: it lacks {why}")
    _OBJECTS[name] = agent
    for key in [k for k in _CACHE if k[0] == name]:
        del _CACHE[key]


def agent_kind(spec: str) -> str:
    """``"baseline"``, ``"factory"``, ``"object"``, ``"shipped"`` or ``"path"``.

    Raises:
        ValueError: a spec that is none of them (the message lists the choices), or a malformed one.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"agent must be a non-empty string, got {spec!r}")
    spec = spec.strip()
    if is_path_like(spec):
        return "path"
    parsed = parse_agent_spec(spec)
    if parsed.name in AGENT_REGISTRY or parsed.name in EXTRA_AGENTS:  # the paper's controllers, and ours
        return "baseline"
    if parsed.is_factory:
        return "factory"
    if spec in _OBJECTS:
        return "object"
    if spec in shipped_models():
        return "shipped"
    if is_policy_path(spec):
        return "path"
    raise ValueError(f"unknown agent {parsed.name!r}; choose from {list(AGENT_REGISTRY + EXTRA_AGENTS)} (options "
                     f"as NAME[key=value]), a shipped model {sorted(shipped_models())}, a path to a model folder / "
                     f"policy file, or package.module:factory[key=value,...]")


def protocol_problem(agent: Any) -> str | None:
    """What ``agent`` lacks of the agent protocol (None: nothing).

    The protocol (:mod:`electroloc_gym.baselines.base`): ``reset(env)`` and
    ``predict(observation, state=..., episode_start=..., deterministic=...)`` returning ``(action, state)``;
    optional ``env_kwargs``, ``seed(int)``, ``done``/``estimate_mm``.
    """
    missing = []
    for name, args, kwargs in (("reset", (None,), {}),
                               ("predict", (None,), {"state": None, "episode_start": None, "deterministic": True})):
        method = getattr(agent, name, None)
        if not callable(method):
            missing.append(f"a {name}() method")
            continue
        try:
            inspect.signature(method).bind(*args, **kwargs)
        except TypeError as exc:
            call = "reset(env)" if name == "reset" else "predict(obs, state=, episode_start=, deterministic=)"
            missing.append(f"{name}() callable as {call} ({exc})")
        except ValueError:  # no signature (a builtin): trust it
            pass
    kwargs_attr = getattr(agent, "env_kwargs", {})
    if kwargs_attr is not None and not isinstance(kwargs_attr, dict):
        missing.append(f"env_kwargs as a dict (got {type(kwargs_attr).__name__})")
    return None if not missing else "; ".join(missing)


def make_factory_agent(spec: str | AgentSpec) -> Any:
    """Import ``package.module``, call ``factory(**options)`` and check the agent protocol.

    Raises:
        ValueError: the module does not import, has no such callable, the factory raises, or its
            object lacks the protocol — one line naming the spec.
    """
    parsed = spec if isinstance(spec, AgentSpec) else parse_agent_spec(spec)
    try:
        module = importlib.import_module(parsed.module)
    except Exception as exc:  # noqa: BLE001 - any import failure is the user's module's, reported in one line
        raise ValueError(f"agent {parsed.text!r}: cannot import module {parsed.module!r} "
                         f"({type(exc).__name__}: {exc}); it must be installed or on PYTHONPATH") from None
    factory = getattr(module, parsed.factory, None)
    if not callable(factory):
        raise ValueError(f"agent {parsed.text!r}: module {parsed.module!r} has no callable {parsed.factory!r}")
    try:
        agent = factory(**parsed.options)
    except Exception as exc:  # noqa: BLE001 - the user's factory: any failure is reported in one line
        call = f"{parsed.name}({', '.join(f'{k}={v!r}' for k, v in parsed.options.items())})"
        raise ValueError(f"agent {parsed.text!r}: {call} raised {type(exc).__name__}: {exc}") from None
    why = protocol_problem(agent)
    if why is not None:
        raise ValueError(f"agent {parsed.text!r}: the {type(agent).__name__} object {parsed.name} returned is not an "
                         f"agent: it lacks {why}")
    return agent


def agent_display_name(spec: str) -> str:
    """A short name for progress bars and logs: the spec itself, or a path's folder / file name."""
    if "/" not in spec and "\\" not in spec:
        return spec
    p = Path(spec.rstrip("/\\"))
    return p.parent.name if p.name == "model.zip" and p.parent.name else (p.stem if p.suffix == ".zip" else p.name)


def _policy_path(spec: str) -> Path:
    if spec in shipped_models():
        return shipped_models()[spec]
    path = Path(spec).expanduser()
    if not path.exists():
        raise ValueError(f"agent path {spec!r} does not exist (expected a model folder or a policy file)")
    return path


def make_bench_agent(spec: str, *, seed: int | None = None, trust_pickle: bool = False) -> Any:
    """Build the agent a spec names.

    Args:
        spec: see the module docstring.
        seed: seed of a controller's own generator (the runner re-seeds before each trial anyway).
        trust_pickle: allow a learned policy whose files need unpickling (SB3's bare zip). Only for
            files you trust: unpickling runs code.

    Raises:
        ValueError: an unknown name, bad options, a missing path, the training extra not installed, or
            a policy that does not load (the message names the path).
    """
    kind = agent_kind(spec)
    spec = spec.strip()
    if kind == "baseline":
        try:
            return make_agent(spec, seed=seed)
        except ValueError as exc:
            raise ValueError(str(exc) if repr(spec) in str(exc) else f"agent {spec!r}: {exc}") from None
    if kind == "factory":
        return make_factory_agent(spec)
    if kind == "object":
        return _OBJECTS[spec]
    path = _policy_path(spec)
    try:
        from electroloc_gym.policy import load_policy
    except ImportError as exc:
        raise ValueError(f"cannot load policy {str(path)!r}: the training extra is not installed "
                         f"({TRAIN_EXTRA_HINT}): {exc}") from exc
    try:
        agent = load_policy(path, trust_pickle=trust_pickle)
    except ValueError as exc:
        raise ValueError(f"cannot load policy {spec!r}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - any loader failure is reported with the path
        raise ValueError(f"cannot load policy {spec!r} ({path}): {type(exc).__name__}: {exc}") from exc
    if kind == "shipped":
        agent.name = spec
    return agent


# The bench owns these env kwargs; an agent's env_kwargs cannot override them.
_BENCH_ONLY_KWARGS = ("condition", "signal", "randomize_target", "render_mode", "gain_levels", "sensor_layout",
                      "distractors")
def bench_env_kwargs(env_id: str, agent: Any, gain_levels: tuple[float, ...] | None, *, condition: str | None = None,
                     signal: str | None = None, sensor_model: str | None = None, n_particles: int | None = None,
                     max_observations: int | None = None, sensor_layout: str | None = None,
                     distractors: int = 0) -> dict[str, Any]:
    """The ``gym.make`` kwargs of a trial: the run's settings, then the agent's own ``env_kwargs``
    (never overriding what the bench owns, e.g. the distractors a policy was trained with).
    """
    kwargs: dict[str, Any] = {k: v for k, v in (("sensor_model", sensor_model), ("n_particles", n_particles),
                                                ("max_observations", max_observations)) if v is not None}
    if env_id != GLOBAL_ENV_ID and condition is not None:  # the global env has one fixed map, no condition kwarg
        cond = get_condition(condition, signal)
        adapt = getattr(agent, "adapt_condition", None)
        if callable(adapt):
            cond = adapt(cond)
        kwargs["condition"] = cond
    if env_id == UNKNOWN_ENV_ID:  # the paper's sphere/water pairs, the sphere hidden from the agent
        kwargs["target_draw"] = "condition"
    if gain_levels is not None:
        kwargs["gain_levels"] = tuple(gain_levels)
    if sensor_layout is not None:
        kwargs["sensor_layout"] = sensor_layout
    if distractors:
        kwargs["distractors"] = int(distractors)
    kwargs.update({k: v for k, v in dict(getattr(agent, "env_kwargs", {}) or {}).items()
                   if k not in _BENCH_ONLY_KWARGS})
    return kwargs


def planner_memory_bytes(agent: Any, n_particles: int) -> int:
    """Estimated peak memory of one decision, bytes (0 for agents that plan nothing large).

    An agent may say itself (``memory_bytes(n_particles)``); a look-ahead planner (``depth`` T,
    ``n_options`` K, ``continuations`` C, ``branches`` B, ``n_particles`` attributes) holds its T·C·K·S
    predicted readings (float32 (x, y) pairs, float64 means and deviations: ≈ 24 bytes each) and about
    four (C·K, B, S) float64 arrays of the futures' weights (``lookahead_objectives.sequence_costs``),
    with S its subsample of the run's particles.
    """
    own = getattr(agent, "memory_bytes", None)
    if callable(own):
        return int(own(n_particles))
    try:
        depth, k, c, b = int(agent.depth), int(agent.n_options), int(agent.continuations), int(agent.branches)
        s = min(int(agent.n_particles), int(n_particles))
    except (AttributeError, TypeError, ValueError):
        return 0
    return k * c * s * (24 * depth + 32 * b)


_CACHE: dict[tuple[str, bool], Any] = {}


def cached_agent(spec: str, *, trust_pickle: bool = False) -> Any:
    """:func:`make_bench_agent`, built once per process (the runner re-seeds and resets it every trial)."""
    key = (spec, bool(trust_pickle))
    if key not in _CACHE:
        _CACHE[key] = make_bench_agent(spec, trust_pickle=trust_pickle)
    return _CACHE[key]


def _training_extra_missing() -> str | None:
    """Why learned policies cannot run here (None: they can)."""
    for module in ("electroloc_gym.policy",):
        try:
            if importlib.util.find_spec(module) is None:
                return f"the training extra is not installed ({module} missing; {TRAIN_EXTRA_HINT})"
        except (ImportError, ValueError) as exc:
            return f"the training extra is not importable ({module}: {exc})"
    return None


def shipped_model_env(folder: Path) -> tuple[str, tuple[float, ...] | None] | None:
    """(env id, gain levels) a shipped policy was trained on (its policy.json's ``observation.env_id``
    and ``env_kwargs.gain_levels``; plain JSON), or None if the file does not say.
    """
    try:
        with open(folder / "policy.json", encoding="utf-8") as f:
            meta = json.load(f)
        env_id = meta["observation"]["env_id"]
        gains = (meta.get("env_kwargs") or {}).get("gain_levels")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    if not isinstance(env_id, str):
        return None
    return env_id, None if gains is None else tuple(float(g) for g in gains)


def trained_sensor_layout(meta: Any) -> str | None:
    """The named sensor layout a policy was trained with (its policy.json's ``env_kwargs.sensor_layout``;
    ``"single"``, the paper's one pair, when it records none), or None when it records something else
    (explicit offsets: the observation-frame check decides).
    """
    kwargs = meta.get("env_kwargs") if isinstance(meta, dict) else None
    layout = kwargs.get("sensor_layout", "single") if isinstance(kwargs, dict) else "single"
    return layout if isinstance(layout, str) else None


def policy_meta(spec: str) -> dict[str, Any] | None:
    """The ``policy.json`` of a shipped model or a policy path (None: none, or not readable as JSON)."""
    if spec in shipped_models():
        path = shipped_models()[spec]
    else:
        path = Path(spec).expanduser()
    if path.is_file():
        path = path if path.name == "policy.json" else path.parent
    try:
        with open(path / "policy.json", encoding="utf-8") as f:
            meta = json.load(f)
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def _space_text(space: Any) -> str:
    shape = getattr(space, "shape", None)
    n = getattr(space, "n", None)
    return f"Discrete({int(n)})" if n is not None and not shape else f"{type(space).__name__}{tuple(shape or ())}"


def policy_env_problem(spec: str, agent: Any, env_id: str, gain_levels: tuple[float, ...] | None,
                       sensor_layout: str | None = None) -> str | None:
    """Why a learned policy cannot run on the run's env (None: it can, or it records nothing to check).

    Compares what the policy's ``policy.json`` records — the env id it was trained on, its dynamic-gain
    levels, its observation frame (``observation.frame_dim``, else the last axis of ``observation.shape``)
    and its action space — with the run's env built with the policy's own ``env_kwargs`` (its
    observation mode). A policy trained on one env and benchmarked on another gives meaningless numbers,
    so this is refused before any trial; there is no override.
    """
    meta = policy_meta(spec)
    if meta is None:
        return None
    obs = meta.get("observation") if isinstance(meta.get("observation"), dict) else {}
    act = meta.get("action") if isinstance(meta.get("action"), dict) else {}
    trained = obs.get("env_id")
    if isinstance(trained, str) and trained != env_id:
        return f"it was trained on {trained}, this run is on {env_id}"
    recorded = (meta.get("env_kwargs") or {}).get("gain_levels") if isinstance(meta.get("env_kwargs"), dict) else None
    mine = None if gain_levels is None else [float(g) for g in gain_levels]
    theirs = None if recorded is None else [float(g) for g in recorded]
    if theirs != mine:
        return f"it was trained with gain_levels={theirs}, this run has gain_levels={mine}"
    layout, run_layout = trained_sensor_layout(meta), sensor_layout or "single"
    if layout is not None and layout != run_layout:
        return f"it was trained with sensor_layout={layout!r}, this run has sensor_layout={run_layout!r}"
    import gymnasium as gym

    import electroloc_gym  # noqa: F401  (registers the ids)

    try:
        env = gym.make(env_id, **bench_env_kwargs(env_id, agent, gain_levels, sensor_layout=sensor_layout))
    except (TypeError, ValueError) as exc:
        return f"its env_kwargs do not build {env_id}: {exc}"
    try:
        frame = obs.get("frame_dim") or (obs.get("shape") or [None])[-1]
        env_frame = env.observation_space.shape[-1] if env.observation_space.shape else None
        if frame is not None and env_frame is not None and int(frame) != int(env_frame):
            return (f"its observation frame has {frame} entries, {env_id}'s "
                    f"({getattr(agent, 'env_kwargs', {}).get('observation', 'default')} observation) has {env_frame}")
        space = act.get("space") if isinstance(act.get("space"), dict) else {}
        want = space.get("shape")
        have = env.action_space.shape
        if space.get("type") == "Discrete" or act.get("action_type") == "discrete":
            n = space.get("n")
            if getattr(env.action_space, "n", None) != n:
                return f"its action space is Discrete({n}), {env_id}'s is {_space_text(env.action_space)}"
        elif want is not None and tuple(want) != tuple(have or ()):
            return f"its action space has shape {tuple(want)}, {env_id}'s is {_space_text(env.action_space)}"
    finally:
        env.close()
    return None


def default_agents(*, table4_only: bool = False, trust_pickle: bool = False, env_id: str = "ElectroLoc-v0",
                   gain_levels: tuple[float, ...] | None = None, sensor_layout: str | None = None) -> list[AgentChoice]:
    """What a run without ``--agents`` considers: the paper's controllers, then every shipped model
    trained on ``env_id``.

    A shipped model that cannot run here is listed with the reason it is skipped (the training
    extra missing, its files not loading, or another env).

    Args:
        table4_only: only particle-filter controllers (the global env: rnd-wlk, min-var), then the
            shipped models trained on ``env_id``.
        trust_pickle: passed to the policy loader.
        env_id: the run's env.
        gain_levels: the run's dynamic-gain levels (then min-var runs twice: choosing the gain, and at the
            preset gain).
        sensor_layout: the run's named sensor layout (None: the paper's single pair); a shipped model
            trained with another layout is skipped.
    """
    choices = [AgentChoice("rnd-wlk"), AgentChoice("min-var")] if table4_only else \
        [AgentChoice(name) for name in AGENT_REGISTRY]
    if gain_levels is not None:
        choices.insert(2, AgentChoice("min-var[gain=preset]"))
    models = shipped_models()
    missing = _training_extra_missing() if models else None
    for name, folder in models.items():
        trained_on = shipped_model_env(folder)
        if trained_on is not None and trained_on != (env_id, gain_levels):
            what = trained_on[0] + ("" if trained_on[1] is None else f" with gain_levels={list(trained_on[1])}")
            here = env_id + ("" if gain_levels is None else f" with gain_levels={list(gain_levels)}")
            choices.append(AgentChoice(name, skipped=f"trained on {what}, not {here}"))
            continue
        layout = trained_sensor_layout(policy_meta(name))
        if layout is not None and layout != (sensor_layout or "single"):
            choices.append(AgentChoice(name, skipped=f"trained with sensor_layout={layout!r}, "
                                                     f"not {sensor_layout or 'single'!r}"))
            continue
        if missing:
            choices.append(AgentChoice(name, skipped=missing))
            continue
        try:
            cached_agent(name, trust_pickle=trust_pickle)
        except ValueError as exc:
            choices.append(AgentChoice(name, skipped=str(exc)))
        else:
            choices.append(AgentChoice(name))
    return choices
