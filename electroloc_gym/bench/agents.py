"""The benchmark's agent registry: the paper's controllers, the shipped learned policies, policy paths.

An agent *spec* (what ``--agents`` takes, and the ``agent`` key of every trial record) is one of

* a built-in controller, optionally with options: ``min-var[n_voters=2500]``
  (:func:`electroloc_gym.baselines.make_agent`);
* the name of a shipped learned policy, ``ppo-belief`` (a folder of ``electroloc_gym.models``);
* a path to a model folder or a policy file (:func:`is_policy_path`);
* a user's factory, ``package.module:factory[key=value,...]``: the module is imported (installed, or on
  ``PYTHONPATH``; nothing is picked up from the working directory) and the factory called with the options.

A plug-in agent (a factory's object, or an object handed to the Python API) runs behind
:class:`PluginAgent`: every attribute the benchmark reads of it goes through one guard, so an exception in
its code (``SystemExit`` included) is one :class:`AgentAttributeError` naming the attribute, as a method
that raises is one :class:`~electroloc_gym.baselines.rollout.AgentCallError` naming the method. Every
failure to build an agent is one ``ValueError`` naming the spec, raised before any trial runs.

Learned policies load through :func:`electroloc_gym.policy.load.load_policy` (a bare SB3 ``.zip``, pickle
inside, only with ``trust_pickle=True``); the paper's controllers never import the training package.
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.agent import AGENT_NAMES, make_agent
from electroloc_gym.baselines.base import layout_problem  # the agents' layout rule (re-exported: the registry's API)
from electroloc_gym.baselines.rollout import AgentCallError, call_agent, exception_line
from electroloc_gym.bench.policy_fit import (  # what a policy was trained on (re-exported: the registry's API)
    AGENT_ENV_KWARGS,
    agent_env_kwargs,
    bench_env_kwargs,
    plug_in_problem,
    policy_env_problem,
    policy_meta,
    shipped_model_env,
    shipped_models,
    trained_sensor_layout,
)
from electroloc_gym.utils.agentspec import AgentSpec, is_path_like, parse_agent_spec, path_agent_name
from electroloc_gym.utils.fileio import user_path

__all__ = [
    "AgentAttributeError",
    "AgentRef",
    "PluginAgent",
    "call_agent",
    "resolve_agent",
    "builtin_agent",
    "plug_in_problem",
    "layout_problem",
    "decision_seconds",
    "AGENT_ENV_KWARGS",
    "agent_env_kwargs",
    "shipped_models",
    "is_policy_path",
    "agent_kind",
    "agent_display_name",
    "make_bench_agent",
    "make_factory_agent",
    "protocol_problem",
    "policy_env_problem",
    "policy_meta",
    "shipped_model_env",
    "trained_sensor_layout",
    "cached_agent",
    "register_object_agent",
    "bench_env_kwargs",
    "planner_memory_bytes",
    "TRAIN_EXTRA_HINT",
]

TRAIN_EXTRA_HINT = "pip install 'electroloc-gym[train]'"


def is_policy_path(spec: str) -> bool:
    """True when ``spec`` is written as a path (``/``, leading ``.`` or ``~``, ``.zip``) or is a folder."""
    return is_path_like(spec) or Path(spec).is_dir()


class AgentAttributeError(AgentCallError):
    """Reading an attribute of a plug-in agent raised: an ``AgentCallError`` whose ``method`` is the attribute."""

    def __init__(self, method: str, error: str) -> None:
        Exception.__init__(self, f"reading its {method} raised {error}")
        self.method, self.error = method, error

    def __reduce__(self) -> tuple[Any, ...]:  # picklable across worker processes
        return (AgentAttributeError, (self.method, self.error))


_ABSENT = object()


def _declared(agent: Any, name: str) -> bool:
    """``agent`` has ``name`` without running its code (an instance or class attribute, a property)."""
    try:
        return inspect.getattr_static(agent, name, _ABSENT) is not _ABSENT
    except Exception:  # noqa: BLE001 - a class that cannot even be inspected: nothing is declared
        return False


class PluginAgent:
    """A plug-in agent behind the benchmark's guard: attribute reads and writes forwarded to the agent.

    An absent attribute is an ``AttributeError`` as usual (so ``getattr(agent, "done", False)`` and
    ``hasattr`` keep their meaning); anything else the read raises — an ``AttributeError`` raised inside a
    declared property included — is one :class:`AgentAttributeError` (``KeyboardInterrupt`` passes).
    Methods are the agent's own bound methods: what they raise is reported where they are called.
    """

    __slots__ = ("_agent",)

    def __init__(self, agent: Any) -> None:
        object.__setattr__(self, "_agent", agent)

    def __getattr__(self, name: str) -> Any:
        agent = object.__getattribute__(self, "_agent")
        try:
            return getattr(agent, name)
        except KeyboardInterrupt:
            raise
        except AttributeError as exc:
            if _declared(agent, name):  # declared, yet reading it failed: the agent's code raised
                raise AgentAttributeError(name, exception_line(exc)) from None
            raise
        except BaseException as exc:  # noqa: BLE001 - the plug-in's failure, whatever it is, becomes one line
            raise AgentAttributeError(name, exception_line(exc)) from None

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(object.__getattribute__(self, "_agent"), name, value)

    def __repr__(self) -> str:
        return f"PluginAgent({type(object.__getattribute__(self, '_agent')).__name__})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (PluginAgent, (object.__getattribute__(self, "_agent"),))

    @property
    def wrapped(self) -> Any:
        """The agent object itself."""
        return object.__getattribute__(self, "_agent")


#: Agent objects handed to the Python API (:func:`electroloc_gym.bench.api.run`), by the name they run under.
_OBJECTS: dict[str, Any] = {}


@dataclass(frozen=True)
class AgentRef:
    """An agent spec resolved once: its ``text`` (stripped), its ``kind`` (``"baseline"``, a built-in
    controller, ``"factory"``, ``"object"``, ``"shipped"`` or ``"path"``) and its ``parsed`` form (None for a
    path or a shipped model).
    """

    text: str
    kind: str
    parsed: AgentSpec | None = None

    @property
    def builtin(self) -> bool:
        """A built-in controller (its options are in its spec; it may set its own protocol)."""
        return self.kind == "baseline"


_REFS: dict[str, AgentRef] = {}


def resolve_agent(spec: str | AgentRef) -> AgentRef:
    """The :class:`AgentRef` of a spec, parsed once per process (a ValueError names the choices)."""
    if isinstance(spec, AgentRef):
        return spec
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError(f"agent must be a non-empty string, got {spec!r}")
    if spec not in _REFS:
        _REFS[spec] = _resolve(spec.strip())
    return _REFS[spec]


def _resolve(spec: str) -> AgentRef:
    if is_path_like(spec):
        return AgentRef(spec, "path")
    try:
        parsed = parse_agent_spec(spec)
    except ValueError:
        if Path(spec).is_dir():  # a model folder whose name is no agent spec (``run.v2``)
            return AgentRef(spec, "path")
        raise
    if parsed.name in AGENT_NAMES:  # the paper's controllers, and ours
        return AgentRef(spec, "baseline", parsed)
    if parsed.is_factory:
        return AgentRef(spec, "factory", parsed)
    if spec in _OBJECTS:
        return AgentRef(spec, "object", parsed)
    if spec in shipped_models():
        return AgentRef(spec, "shipped")
    if is_policy_path(spec):
        return AgentRef(spec, "path")
    if parsed.name in shipped_models():  # make_agent's words
        raise ValueError(f"the shipped policy {parsed.name!r} takes no options, got {spec!r}")
    raise ValueError(
        f"unknown agent {parsed.name!r}; choose from {list(AGENT_NAMES)} (options "
        f"as NAME[key=value]), a shipped model {sorted(shipped_models())}, a path to a model folder / "
        f"policy file, or package.module:factory[key=value,...]"
    )


def register_object_agent(name: str, agent: Any) -> None:
    """Make ``agent`` (an object with the agent protocol) the agent named ``name`` in this process (a ValueError
    when ``name`` is not a plain, free agent name or the object lacks the protocol).
    """
    parsed = parse_agent_spec(name)
    if parsed.options or parsed.is_factory or parsed.name in AGENT_NAMES or name in shipped_models():
        raise ValueError(
            f"agent object name {name!r} must be a plain name other than the built-in agents' and shipped models'"
        )
    guarded = agent if isinstance(agent, PluginAgent) else PluginAgent(agent)
    where = f"agent object {name!r} ({type(guarded.wrapped).__name__})"
    _OBJECTS[name] = _checked(guarded, where, where)
    _REFS.pop(name, None)
    for key in [k for k in _CACHE if k[0] == name]:
        del _CACHE[key]


def agent_kind(spec: str | AgentRef) -> str:
    """The kind of :func:`resolve_agent`'s :class:`AgentRef`."""
    return resolve_agent(spec).kind


def protocol_problem(agent: Any) -> str | None:
    """What ``agent`` lacks of the agent protocol of :mod:`electroloc_gym.baselines.base` (None: nothing)."""
    missing = []
    for name, args, kwargs in (
        ("reset", (None,), {}),
        ("predict", (None,), {"state": None, "episode_start": None, "deterministic": True}),
    ):
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
    """Import ``package.module``, call ``factory(**options)`` and check the agent protocol: the object behind
    the guard (:class:`PluginAgent`), or one ValueError naming the spec.
    """
    parsed = spec if isinstance(spec, AgentSpec) else parse_agent_spec(spec)
    try:
        module = importlib.import_module(parsed.module)
    except Exception as exc:  # noqa: BLE001 - any import failure is the user's module's, reported in one line
        raise ValueError(
            f"agent {parsed.text!r}: cannot import module {parsed.module!r} "
            f"({exception_line(exc)}); it must be installed or on PYTHONPATH"
        ) from None
    factory = getattr(module, parsed.factory, None)
    if not callable(factory):
        raise ValueError(f"agent {parsed.text!r}: module {parsed.module!r} has no callable {parsed.factory!r}")
    try:
        agent = factory(**parsed.options)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - the user's factory: any failure is reported in one line
        call = f"{parsed.name}({', '.join(f'{k}={v!r}' for k, v in parsed.options.items())})"
        raise ValueError(f"agent {parsed.text!r}: {call} raised {exception_line(exc)}") from None
    what = f"agent {parsed.text!r}: the {type(agent).__name__} object {parsed.name} returned"
    return _checked(PluginAgent(agent), f"agent {parsed.text!r}", what)


def _checked(guarded: PluginAgent, where: str, what: str) -> PluginAgent:
    """``guarded`` if it has the agent protocol, else a ValueError of ``where`` (reading it raised) or ``what``."""
    try:
        why = protocol_problem(guarded)
    except AgentCallError as exc:
        raise ValueError(f"{where}: {exc}") from None
    if why is not None:
        raise ValueError(f"{what} is not an agent: it lacks {why}")
    return guarded


def agent_display_name(spec: str) -> str:
    """A short name for progress bars and logs: the spec itself, or a path's folder (the folder of its
    ``model.zip`` or ``policy.json``) or file name.
    """
    # the one rule of a path spec (``ppo.zip`` and ``./ppo.zip`` alike), and of the name it runs under
    return path_agent_name(spec) if is_path_like(spec) else spec


def make_bench_agent(spec: str | AgentRef, *, seed: int | None = None, trust_pickle: bool = False) -> Any:
    """Build the agent ``spec`` names (module docstring; one ValueError when it cannot): ``seed`` seeds a
    controller's own generator (the runner re-seeds before each trial anyway); ``trust_pickle`` is
    ``--trust-pickle`` (a learned policy stored as a bare SB3 zip: unpickling runs its code).
    """
    ref = resolve_agent(spec)
    kind, spec = ref.kind, ref.text
    if kind == "baseline":
        assert ref.parsed is not None
        try:
            return make_agent(ref.parsed, seed=seed)
        except ValueError as exc:
            raise ValueError(str(exc) if repr(spec) in str(exc) else f"agent {spec!r}: {exc}") from None
    if kind == "factory":
        assert ref.parsed is not None
        return make_factory_agent(ref.parsed)
    if kind == "object":
        return _OBJECTS[spec]
    path = shipped_models()[spec] if kind == "shipped" else user_path(spec)
    if kind == "path" and not path.exists():
        raise ValueError(f"agent path {spec!r} does not exist (expected a model folder or a policy file)")
    try:
        from electroloc_gym.policy import load_policy
    except ImportError as exc:
        raise ValueError(
            f"cannot load policy {str(path)!r}: the training extra is not installed ({TRAIN_EXTRA_HINT}): {exc}"
        ) from exc
    try:
        agent = load_policy(path, trust_pickle=trust_pickle)
    except ValueError as exc:
        raise ValueError(f"cannot load policy {spec!r}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - any loader failure is reported with the path
        raise ValueError(f"cannot load policy {spec!r} ({path}): {type(exc).__name__}: {exc}") from exc
    if kind == "shipped":
        agent.name = spec
    return agent


def planner_memory_bytes(agent: Any, n_particles: int) -> int:
    """Estimated peak memory of one decision, bytes (0 for agents that plan nothing large).

    An agent may say itself (``memory_bytes(n_particles)``); a look-ahead planner (``depth`` T,
    ``n_options`` K, ``continuations`` C, ``branches`` B, ``n_particles`` attributes) holds its T·C·K·S
    predicted readings (float32 (x, y) pairs, float64 means and deviations: ≈ 24 bytes each) and about
    four (C·K, B, S) float64 arrays of the futures' weights (``lookahead_objectives.sequence_costs``),
    with S its subsample of the run's particles. What the agent's code raises is an ``AgentCallError``.
    """
    own = getattr(agent, "memory_bytes", None)
    if callable(own):
        return int(call_agent("memory_bytes", own, n_particles))  # the agent's own figure, any int-like
    try:
        depth, k, c, b = int(agent.depth), int(agent.n_options), int(agent.continuations), int(agent.branches)
        s = min(int(agent.n_particles), int(n_particles))
    except (AttributeError, TypeError, ValueError):
        return 0
    return k * c * s * (24 * depth + 32 * b)


_CACHE: dict[tuple[str, bool], Any] = {}


def cached_agent(spec: str | AgentRef, *, trust_pickle: bool = False) -> Any:
    """:func:`make_bench_agent`, built once per process (the runner re-seeds and resets it every trial)."""
    ref = resolve_agent(spec)
    key = (ref.text, bool(trust_pickle))
    if key not in _CACHE:
        _CACHE[key] = make_bench_agent(ref, trust_pickle=trust_pickle)
    return _CACHE[key]


def builtin_agent(spec: str) -> Any | None:
    """The built agent when ``spec`` names a built-in controller, else None (a plug-in agent, a learned
    policy, or a spec that does not resolve here: none of them sets its own protocol).
    """
    try:
        ref = resolve_agent(spec)
        return cached_agent(ref) if ref.builtin else None
    except ValueError:
        return None


def decision_seconds(agent: Any, n_particles: int) -> float:
    """The agent's own estimate of one decision's time, s (``decision_seconds(n_particles)``; 0: none, or
    not a number). What the agent's code raises is an ``AgentCallError``.
    """
    own = getattr(agent, "decision_seconds", None)
    seconds: Any = call_agent("decision_seconds", own, n_particles) if callable(own) else 0.0
    try:
        return float(seconds)  # the agent's own figure, any float-like
    except (TypeError, ValueError, OverflowError):
        return 0.0
