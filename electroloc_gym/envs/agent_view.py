"""The agent view: what an agent is handed of its env — the documented agent accessors, nothing else.

An agent binds to its env at the start of every episode (``agent.reset(env)``). The benchmark, the
datasets' rollout (:func:`electroloc_gym.baselines.rollout.run_episode`), the paper's controllers and the torch
backend's ``sub_env(i)`` hand it :func:`agent_view` of the env instead of the env itself: an object with
the read-only accessors an agent may use (docs/environments.md, "Accessors") and no route to the
episode's ground truth.

**What it shows** (each only where the env has it; :data:`AGENT_VALUES`, :data:`AGENT_METHODS`):
the belief (:data:`BELIEF_VALUES`, :data:`BELIEF_METHODS`), the agent's sensor model (its ``name``,
``mean_std`` and ``log_likelihood``), the condition's tank (:data:`TANK_FIELDS`), the carriage's
position, path, box and move bounds, the reading count and the last readings, the predicted readings
and hypotheses after a move, the dynamic-gain accessors, the sensor layout, the global env's map and
odometry, the env's settings (particles, cap, success spread, observation mode, …) and its spaces (those
of the env as given, wrappers included: what the agent's actions and observations are).

**What it hides**: the true target (``target_mm``, ``truth_mm``, ``hidden_state()``, ``hidden_keys``),
``params`` and ``spec`` (they hold the condition, whose ``target_xy_mm`` is the true target position),
``unwrapped``, ``np_random`` (the env's noise stream), ``step``/``reset``/``render``/``close``, and
everything private. The condition is shown through its own view: the tank always, never its
``target_xy_mm``, and its sphere (:data:`SPHERE_FIELDS`) only where the belief does not estimate it — on
``ElectroLocUnknownTarget-v0`` (hypotheses (x, y, radius, χ)) the sphere and the condition's name are
the hidden state. Where the belief is over the robot's own position (``belief_frame == "robot"``,
``ElectroLocGlobal-v0``) the carriage's true position and path (:data:`ROBOT_FRAME_TRUTH`) are that hidden
state, and the view leaves them out: the robot knows its ``odometry_mm``.

**How**: a view holds one private closure over the env that answers only the names above (and calls
only the methods above); nothing it returns is the env, a bound method of it or an object holding it —
the belief, the sensor model and the condition are views of their own (the condition's
``detection_distance_mm`` is a method of its view, not the condition's bound method), and the rest are
arrays, numbers and frozen records (``SensorLayout``, ``Scene``, Gymnasium spaces). There is no
``__dict__``, no ``unwrapped``/``env`` attribute and no ``__getattr__`` forwarding; a missing name is an
``AttributeError`` naming what the view does have. Every access reads the env's state at that moment.

**Nothing it returns can write the env** (:func:`read_only`): every value and every method's result
passes one gate on its way out. A numpy array that is read-only all the way down its ``.base`` chain
(ending in an array that owns its data) is handed out as it is; any other — writable, or a read-only
view of a writable array such as the belief's particles, a view of the engine's live cloud — is handed
out as a read-only copy of the same memory layout (the same values and the same arithmetic downstream).
Tuples, lists (as tuples) and mappings (read-only proxies) are gated item by item, records (dataclasses,
Gymnasium spaces) through the fields they hold: a record holding a writable array is handed out as a
copy holding read-only ones. The envs' own spaces are read-only at construction, so they pass as
themselves. One copy per read of the particles (M × 2 float32) and of each prediction; an array the env
already hands out read-only costs nothing.

**What it cannot guarantee**: an agent runs in the same Python process as its env, so deliberate
introspection (``gc.get_referrers``, stack frames, a closure's ``__closure__``) can still reach the env.
The view guards against accidental and innocent peeking and makes any peeking deliberate; it is not a
sandbox. Running untrusted agents safely needs a process boundary.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, cast

import numpy as np

__all__ = [
    "AgentView",
    "agent_view",
    "AGENT_VALUES",
    "AGENT_METHODS",
    "BELIEF_VALUES",
    "BELIEF_METHODS",
    "SENSOR_MODEL_VALUES",
    "SENSOR_MODEL_METHODS",
    "TANK_FIELDS",
    "SPHERE_FIELDS",
    "SPHERE_METHODS",
    "read_only",
    "ROBOT_FRAME_TRUTH",
]

#: The env's read-only values an agent may read (properties of ``env.unwrapped``), where the env has them.
AGENT_VALUES: tuple[str, ...] = (
    # the belief, the sensor model, the episode's tank
    "belief",
    "belief_frame",
    "sensor_model",
    "condition",
    # the carriage and the readings
    "position_mm",
    "path_mm",
    "allowed_box_mm",
    "move_bounds_mm",
    "odometry_mm",
    "n_observations",
    "last_reading_V",
    "last_readings_V",
    "gain_index",
    # the apparatus and the map
    "sensor_layout",
    "scene",
    # the env's settings
    "n_particles",
    "max_observations",
    "success_spread_mm",
    "observation_mode",
    "sensor_model_name",
    "action_type",
    "gain_levels",
    "preset_gain_level",
    "calibration_seed",
    "randomize_target",
    "fixed_carriage",
    "target_draw",
    "radius_range_mm",
    "contrast",
    "layout",
    "position_blur_mm",
    "action_space",
    "observation_space",
)
#: The env's methods an agent may call (predictions from its own sensor model; the gain action).
AGENT_METHODS: tuple[str, ...] = ("predicted_reading_model", "predicted_particles_mm", "gain_action")
#: On an env whose belief is over the robot's own position: its true position and path (the hidden state).
ROBOT_FRAME_TRUTH: tuple[str, ...] = ("position_mm", "path_mm")
#: What the belief's view shows.
BELIEF_VALUES: tuple[str, ...] = ("particles", "weights", "n_particles", "uniform_weights")
BELIEF_METHODS: tuple[str, ...] = ("mean", "covariance", "spread")
#: What the sensor model's view shows.
SENSOR_MODEL_VALUES: tuple[str, ...] = ("name",)
SENSOR_MODEL_METHODS: tuple[str, ...] = ("mean_std", "log_likelihood")
#: The condition's tank: water, amplifier, carriage geometry, signal scale and boxes (always shown).
TANK_FIELDS: tuple[str, ...] = (
    "water",
    "amplifier",
    "geometry",
    "signal_scale",
    "start_half_width_mm",
    "allowed_half_width_mm",
    "noise_std_V",
    "saturation_V",
)
#: The condition's sphere and name: shown unless the belief estimates the sphere (its hypotheses carry it).
SPHERE_FIELDS: tuple[str, ...] = ("name", "target", "chi", "depth_mm")
#: The condition's sphere's methods, shown with :data:`SPHERE_FIELDS` (called by the view: its result, never
#: the condition's bound method, which holds the condition and its ``target_xy_mm``).
SPHERE_METHODS: tuple[str, ...] = ("detection_distance_mm",)

#: Values read from the env as given (its wrappers' spaces), not from its core.
_OUTER_VALUES: tuple[str, ...] = ("action_space", "observation_space")

_Access = Callable[..., Any]


class AgentView:
    """A read-only view of an object through a fixed set of names (:func:`agent_view` builds them).

    Its one slot holds a closure that answers those names only; the view has no ``__dict__`` and cannot
    be written to.
    """

    __slots__ = ("__access",)
    #: What the view shows, for messages.
    _what = "agent view"
    #: The names it has (values, then methods).
    _names: tuple[str, ...] = ()

    def __init__(self, access: _Access) -> None:
        object.__setattr__(self, "_AgentView__access", access)

    def __getattr__(self, name: str) -> Any:  # only for names the view does not have: an error, never a lookup
        raise AttributeError(
            f"the {self._what} has no attribute {name!r}: an agent sees only {list(self._names)} "
            f"(electroloc_gym.envs.agent_view)"
        )

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"the {self._what} is read-only (cannot set {name!r})")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"the {self._what} is read-only (cannot delete {name!r})")

    def __dir__(self) -> list[str]:
        return sorted(self._names)

    def __copy__(self) -> AgentView:
        return self  # a view of a live env: a copy would be the same view

    def __deepcopy__(self, memo: dict[int, Any]) -> AgentView:
        return self

    def __reduce__(self) -> Any:
        raise TypeError(f"the {self._what} cannot be pickled (it reads a live env)")

    def __repr__(self) -> str:
        return f"<{self._what}: {', '.join(self._names)}>"


_ACCESS = AgentView.__dict__["_AgentView__access"]  # the slot's descriptor: the generated accessors read it

#: Values with nothing to write: handed out as they are.
_IMMUTABLE = (str, bytes, int, float, complex, type(None), np.generic, np.dtype, range, frozenset)
#: How deep :func:`read_only` follows records and containers (the envs' records are two levels deep).
_MAX_DEPTH = 8


def _has_no_write_route(a: np.ndarray) -> bool:
    """``a`` and every array of its ``.base`` chain are read-only, and the chain ends in an array that owns its
    data (or in immutable ``bytes``), not in another buffer (a torch tensor, a memoryview, a mmap).
    """
    x: Any = a
    while isinstance(x, np.ndarray):
        if x.flags.writeable:
            return False
        x = x.base
    return x is None or isinstance(x, bytes)


def _record_fields(obj: Any) -> dict[str, Any]:
    """The fields a record holds: its ``__dict__`` and its ``__slots__`` (by their stored names)."""
    fields = dict(getattr(obj, "__dict__", None) or {})
    for cls in type(obj).__mro__:
        slots = getattr(cls, "__slots__", ())
        for slot in (slots,) if isinstance(slots, str) else slots:
            if slot in ("__dict__", "__weakref__"):
                continue
            stored = f"_{cls.__name__.lstrip('_')}{slot}" if slot.startswith("__") else slot
            if stored not in fields and hasattr(obj, stored):
                fields[stored] = getattr(obj, stored)
    return fields


def read_only(value: Any, _depth: int = 0) -> Any:
    """``value`` with no route to write an array it reaches (module docstring, "Nothing it returns can write the
    env"): itself where it has none, else a copy that has none.

    An array read-only down its ``.base`` chain is itself; any other array is a read-only copy in the same
    memory layout (``order="K"``: the same values, and the same results of any arithmetic on them). Tuples
    (named ones as their type), lists (as tuples) and mappings (as read-only proxies) are gated item by
    item; agent views, numbers, strings and callables are themselves; any other object is a record: where a
    field it holds (``__dict__``, ``__slots__``) changes, a shallow copy holding the gated fields.
    """
    if isinstance(value, (AgentView, *_IMMUTABLE)):
        return value
    if isinstance(value, np.ndarray):
        if _has_no_write_route(value):
            return value
        out = np.array(value, copy=True, order="K")
        out.flags.writeable = False
        return out
    if _depth >= _MAX_DEPTH:
        return value
    if isinstance(value, (tuple, list)):
        items = [read_only(v, _depth + 1) for v in value]
        if isinstance(value, tuple) and all(a is b for a, b in zip(items, value, strict=True)):
            return value
        return type(value)(*items) if isinstance(value, tuple) and hasattr(value, "_fields") else tuple(items)
    if isinstance(value, Mapping):
        return MappingProxyType({k: read_only(v, _depth + 1) for k, v in value.items()})
    if isinstance(value, type) or callable(value):
        return value
    fields = _record_fields(value)
    gated = {k: read_only(v, _depth + 1) for k, v in fields.items()}
    changed = {k: v for k, v in gated.items() if v is not fields[k]}
    if not changed:
        return value
    out = copy.copy(value)
    for k, v in changed.items():
        object.__setattr__(out, k, v)
    return out


def _value(name: str) -> property:
    def get(self: AgentView) -> Any:
        return _ACCESS.__get__(self)(name)

    get.__name__ = name
    return property(get, doc=f"The env's ``{name}`` (docs/environments.md, Accessors).")


def _method(name: str) -> Callable[..., Any]:
    def call(self: AgentView, *args: Any, **kwargs: Any) -> Any:
        return _ACCESS.__get__(self)(name, args, kwargs)

    call.__name__ = name
    call.__doc__ = f"The env's ``{name}(...)`` (docs/environments.md, Accessors)."
    return call


@functools.cache
def _view_class(what: str, values: tuple[str, ...], methods: tuple[str, ...]) -> type[AgentView]:
    """The view class of one set of names (one per env kind: ``hasattr`` answers as on the env)."""
    namespace: dict[str, Any] = {"__slots__": (), "_what": what, "_names": values + methods}
    namespace.update({n: _value(n) for n in values})
    namespace.update({n: _method(n) for n in methods})
    title = "".join(w.capitalize() for w in what.split())
    return cast("type[AgentView]", type(title, (AgentView,), namespace))


def _has(obj: Any, name: str) -> bool:
    """Whether ``obj`` has ``name`` without evaluating a property (one may need a reset first)."""
    return hasattr(type(obj), name) or name in getattr(obj, "__dict__", {})


def _view(
    what: str,
    source: Any,
    values: tuple[str, ...],
    methods: tuple[str, ...],
    wrap: Callable[[str, Any], Any] | None = None,
    outer: dict[str, Any] | None = None,
) -> AgentView:
    """A view of ``source`` through the ``values`` and ``methods`` it has (``wrap`` filters the values;
    ``outer`` maps a value's name to the object it is read from instead).
    """
    outer = outer or {}
    shown = tuple(n for n in values if (hasattr(outer[n], n) if n in outer else _has(source, n)))
    callable_ = tuple(n for n in methods if _has(source, n))
    allowed_values, allowed_methods = frozenset(shown), frozenset(callable_)

    def access(name: str, args: tuple[Any, ...] | None = None, kwargs: dict[str, Any] | None = None) -> Any:
        if args is None:
            if name not in allowed_values:
                raise AttributeError(name)
            value = getattr(outer.get(name, source), name)
            return read_only(value if wrap is None else wrap(name, value))
        if name not in allowed_methods:
            raise AttributeError(name)
        return read_only(getattr(source, name)(*args, **(kwargs or {})))

    return _view_class(what, shown, callable_)(access)


def _condition_view(condition: Any, sphere_hidden: bool) -> AgentView:
    fields = TANK_FIELDS if sphere_hidden else SPHERE_FIELDS + TANK_FIELDS
    return _view("agent view of the condition", condition, fields, () if sphere_hidden else SPHERE_METHODS)


def agent_view(env: Any) -> AgentView:
    """The agent view of ``env`` (module docstring): a Gymnasium env (any wrappers), its ``unwrapped`` core, a
    torch backend's sub-env, or an agent view (returned as it is).

    Build it after ``env.reset``; it reads the env's state at every access, so one view serves a whole
    episode (and the next ones).
    """
    if isinstance(env, AgentView):
        return env
    core = env.unwrapped if hasattr(env, "unwrapped") else env
    robot_frame = getattr(core, "belief_frame", "target") == "robot"
    values = tuple(n for n in AGENT_VALUES if not (robot_frame and n in ROBOT_FRAME_TRUTH))
    belief_view: list[tuple[Any, AgentView]] = []  # (the env's belief object, its view): built once

    def sphere_hidden() -> bool:
        """The belief estimates the sphere: the env's task says so (``hides_sphere``), or, for a core that
        declares nothing, its hypotheses carry more than (x, y). (The moving target's swimmer filter carries a
        velocity beside (x, y), not the sphere, and declares it shown.)
        """
        hides = getattr(core, "hides_sphere", None)
        if hides is not None:
            return bool(hides)
        return bool(np.shape(core.belief.particles)[-1] > 2) if _has(core, "belief") else False

    def wrap(name: str, value: Any) -> Any:
        if name == "belief":
            if not belief_view or belief_view[0][0] is not value:
                belief_view[:] = [(value, _view("agent view of the belief", value, BELIEF_VALUES, BELIEF_METHODS))]
            return belief_view[0][1]
        if name == "sensor_model":
            return _view("agent view of the sensor model", value, SENSOR_MODEL_VALUES, SENSOR_MODEL_METHODS)
        if name == "condition":
            return _condition_view(value, sphere_hidden())
        return value

    # the spaces are those of the env the rollout steps (a wrapper may change them), the rest the core's
    return _view("agent view", core, values, AGENT_METHODS, wrap, outer={n: env for n in _OUTER_VALUES})
