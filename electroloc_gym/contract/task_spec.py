"""The declaration types of a task: what a task declares of its own, in its module, for every layer to read.

A task (:class:`electroloc_gym.engines.numba_core.task.Task`) declares next to its class:

* **its options** — a frozen dataclass subclassing :class:`TaskOptions`, one field per keyword argument
  of its env, each declared with :func:`option` (default, doc, unit and a check). Constructing it
  validates and normalises every field from its check (one ``ValueError`` naming the argument and what
  is allowed, the wording of :mod:`electroloc_gym.utils.checks`), then runs the class's own
  :meth:`TaskOptions.check` hook for rules between fields. ``EnvParams.options`` holds the instance; the
  env table's ``arguments`` are its field names.
* **its per-env state** — a dataclass subclassing :class:`TaskState`, one (N, …) array per field, each
  declared with :func:`state_array` (dtype, shape after N, fill); :meth:`TaskState.empty` allocates it
  and the engine's generic code copies, gathers and resets rows over :func:`dataclasses.fields` without
  naming them.

A check is a small declarative spec (:class:`Choice`, :class:`Real`, :class:`Integer`, :class:`Boolean`,
:class:`Numbers`, :class:`Optional`) or any callable ``(name, value) -> normalised value`` that raises
``ValueError``. This module imports nothing above :mod:`electroloc_gym.contract`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from electroloc_gym.utils.checks import check_bool, check_choice, check_float, check_int

__all__ = [
    "TaskOptions",
    "option",
    "option_fields",
    "Check",
    "Choice",
    "Real",
    "Integer",
    "Boolean",
    "Numbers",
    "Optional",
    "TaskState",
    "state_array",
]

#: A check: ``(name, value) -> normalised value``, raising one ``ValueError`` naming ``name``.
Check = Callable[[str, Any], Any]

_T = TypeVar("_T", bound="TaskState")


@dataclass(frozen=True)
class Choice:
    """One of the strings ``values``."""

    values: tuple[str, ...]

    def __call__(self, name: str, value: Any) -> str:
        return check_choice(name, value, self.values)

    @property
    def range(self) -> str:
        """The allowed values, for the docs."""
        return ", ".join(f"`{v!r}`" for v in self.values)


@dataclass(frozen=True)
class Real:
    """A finite real above ``low`` (at or above it when ``inclusive``; None: no bound) and at most ``high``."""

    low: float | None = None
    high: float | None = None
    inclusive: bool = False

    def __call__(self, name: str, value: Any) -> float:
        return check_float(name, value, self.low, inclusive=self.inclusive, high=self.high)

    @property
    def range(self) -> str:
        """The allowed interval, for the docs."""
        lo = "(−∞" if self.low is None else f"{'[' if self.inclusive else '('}{self.low:g}"
        hi = "∞)" if self.high is None else f"{self.high:g}]"
        return f"{lo}, {hi}"


@dataclass(frozen=True)
class Integer:
    """An integer in [low, high] (or ≥ low)."""

    low: int
    high: int | None = None

    def __call__(self, name: str, value: Any) -> int:
        return check_int(name, value, self.low, self.high)

    @property
    def range(self) -> str:
        """The allowed integers, for the docs."""
        return f"≥ {self.low}" if self.high is None else f"[{self.low}, {self.high}]"


@dataclass(frozen=True)
class Boolean:
    """``True`` or ``False`` (a numpy bool taken as the bool it is)."""

    def __call__(self, name: str, value: Any) -> bool:
        return check_bool(name, value)

    @property
    def range(self) -> str:
        """The allowed values, for the docs."""
        return "True, False"


@dataclass(frozen=True)
class Numbers:
    """A tuple of finite numbers in [low, high]: ``count`` of them (None: one or more), given as a tuple, a
    list or a 1-d array; ``unit`` is written after the range in the error (``" mm"``).
    """

    count: int | None
    low: float
    high: float
    unit: str = ""

    def __call__(self, name: str, value: Any) -> tuple[float, ...]:
        items = None
        if isinstance(value, (tuple, list)) or (isinstance(value, np.ndarray) and value.ndim == 1):
            items = tuple(value)
        want = f"{self.count}" if self.count is not None else "one or more"
        if items is None or not items or (self.count is not None and len(items) != self.count):
            raise ValueError(
                f"{name} must be a tuple of {want} numbers in [{self.low:g}, {self.high:g}]{self.unit}, got {value!r}"
            )
        return tuple(check_float(name, v, self.low, inclusive=True, high=self.high) for v in items)

    @property
    def range(self) -> str:
        """The allowed tuples, for the docs."""
        want = f"{self.count}" if self.count is not None else "one or more"
        return f"{want} numbers in [{self.low:g}, {self.high:g}]{self.unit}"


@dataclass(frozen=True)
class Optional:
    """None, or a value ``spec`` takes."""

    spec: Check

    def __call__(self, name: str, value: Any) -> Any:
        return None if value is None else self.spec(name, value)

    @property
    def range(self) -> str:
        """The allowed values, for the docs."""
        return f"None or {getattr(self.spec, 'range', 'a valid value')}"


def option(default: Any, *, doc: str, check: Check | None = None, unit: str = "") -> Any:
    """A field of a :class:`TaskOptions` dataclass: its default, its doc (one line), its check (None: any
    value) and its unit (``"mm"``; empty for none).
    """
    return dataclasses.field(default=default, metadata={"doc": doc, "check": check, "unit": unit})


def option_fields(options: type[TaskOptions] | TaskOptions) -> tuple[dataclasses.Field[Any], ...]:
    """The option fields of an options class or instance, in declaration order."""
    return dataclasses.fields(options)


@dataclass(frozen=True)
class TaskOptions:
    """The base of a task's options (frozen; every field validated on construction, module docstring).

    A subclass is a ``@dataclass(frozen=True)`` whose fields are declared with :func:`option`; its
    :meth:`check` hook refuses combinations of values (one ``ValueError`` naming both options).
    """

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            check = f.metadata.get("check")
            if check is not None:
                object.__setattr__(self, f.name, check(f.name, getattr(self, f.name)))
        self.check()

    def check(self) -> None:
        """Rules between fields (a subclass's hook; the fields are already checked one by one)."""

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The options' names (the env's own keyword arguments), in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def describe(cls) -> list[tuple[str, Any, str, str, str]]:
        """One row per option: (name, default, unit, allowed range, doc), for the docs' argument tables."""
        rows = []
        for f in dataclasses.fields(cls):
            check = f.metadata.get("check")
            rng = getattr(check, "range", "") if check is not None else ""
            rows.append((f.name, f.default, f.metadata.get("unit", ""), rng, f.metadata.get("doc", "")))
        return rows

    def replace(self, **changes: Any) -> TaskOptions:
        """A copy with some options changed (validated again)."""
        return dataclasses.replace(self, **changes)


def state_array(dtype: Any, shape_tail: tuple[int, ...] = (), fill: Any = 0) -> Any:
    """A field of a :class:`TaskState` dataclass: an (N, *shape_tail) array of ``dtype`` filled with ``fill``."""
    return dataclasses.field(metadata={"dtype": np.dtype(dtype), "shape_tail": tuple(shape_tail), "fill": fill})


@dataclass
class TaskState:
    """The base of a task's per-env arrays (module docstring): every field is an (N, …) array, row i env i's.

    The base has no field: a task without arrays of its own keeps it.
    """

    @classmethod
    def empty(cls: type[_T], num_envs: int, params: Any = None) -> _T:
        """The arrays of ``num_envs`` envs, each (N, *shape_tail) of its dtype filled with its fill value
        (``params``: the env's parameters, for a subclass whose shapes depend on them).
        """
        arrays = {}
        for f in dataclasses.fields(cls):
            m = f.metadata
            arrays[f.name] = np.full((int(num_envs), *m["shape_tail"]), m["fill"], dtype=m["dtype"])
        return cls(**arrays)

    @classmethod
    def of(cls: type[_T], state: Any) -> _T:
        """``state.task`` (the engine's state's task arrays) as this class."""
        own = state.task
        if not isinstance(own, cls):
            raise TypeError(f"the state's task arrays are a {type(own).__name__}, not a {cls.__name__}")
        return own

    def arrays(self) -> Iterable[tuple[str, np.ndarray]]:
        """(name, array) of every field, in declaration order."""
        return ((f.name, getattr(self, f.name)) for f in dataclasses.fields(self))

    def take(self: _T, rows: Any) -> _T:
        """A copy of rows ``rows`` (an index array, a slice or a list) of every array."""
        return type(self)(**{name: np.array(a[rows], copy=True) for name, a in self.arrays()})

    def put(self, rows: Any, other: TaskState) -> None:
        """Rows ``rows`` of every array set from ``other``'s arrays (of the same class, as many rows)."""
        for name, a in self.arrays():
            a[rows] = getattr(other, name)

    def reset_rows(self, rows: Any) -> None:
        """Rows ``rows`` of every array set back to the field's fill value."""
        for f in dataclasses.fields(self):
            getattr(self, f.name)[rows] = f.metadata["fill"]
