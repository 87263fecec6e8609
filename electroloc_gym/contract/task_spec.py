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

* **its metrics** — a :class:`TaskMetrics` (the class attribute ``Task.metrics``): the fields of a benchmark
  record's task results (:class:`RecordField`), the statistics over a group of records, the benchmark
  table's columns (:class:`Column`, :class:`Table`), the score that ranks agents (:class:`Score`), an
  episode's outcome in words and the learning curves' panels (:class:`CurvePanel`).

A check is a small declarative spec (:class:`Choice`, :class:`Real`, :class:`Integer`, :class:`Boolean`,
:class:`Numbers`, :class:`Optional`) or any callable ``(name, value) -> normalised value`` that raises
``ValueError``. This module imports nothing above :mod:`electroloc_gym.contract`.
"""

from __future__ import annotations

import dataclasses
import math
import string
from collections.abc import Callable, Iterable, Mapping, Sequence
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
    "DIRECTIONS",
    "RecordField",
    "Column",
    "Table",
    "format_config_text",
    "Score",
    "CurvePanel",
    "TaskMetrics",
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


def option(default: Any, *, doc: str, check: Check | None = None, unit: str = "", agent: bool = False) -> Any:
    """A field of a :class:`TaskOptions` dataclass: its default, its doc (one line), its check (None: any
    value) and its unit (``"mm"``; empty for none).

    ``agent`` true declares the option the agent's own: it says how the agent observes (the filter's model of
    the target, say), not what a trial is, so an agent may set it in its ``env_kwargs`` (a learned policy
    keeps what it was trained with, a controller takes it in its spec, ``min-var[motion_model=swimmer]``)
    while the benchmark fixes every other option for every agent.
    """
    return dataclasses.field(default=default, metadata={"doc": doc, "check": check, "unit": unit, "agent": agent})


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
    def agent_names(cls) -> tuple[str, ...]:
        """The options declared the agent's own (:func:`option`'s ``agent``), in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls) if f.metadata.get("agent"))

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


# ---- metrics: what the layers above the engine report of a task ----------------------------------------
#
# A task declares its metrics once (:class:`TaskMetrics`, the class attribute ``Task.metrics``); the
# benchmark's record schema, statistics and table, the training callback's validation score and checkpoint
# rule, the datasets' reference scores, the learning curves and the episode pictures read the declaration
# and never name a task's fields. The default, the paper's localisation metrics (readings to success,
# success rate), is declared beside the shared ``Task`` base.

#: The word of a direction: which way of a number is better.
DIRECTIONS = ("lower", "higher")


@dataclass(frozen=True)
class RecordField:
    """One entry of a benchmark record's task results (the record's ``shape`` object), copied from the episode's
    final info under the same name.

    Attributes:
        name: the final info's key and the record's.
        doc: what it is (one line).
        unit: its unit (``"mm"``; empty for none).
        kind: ``"real"`` (a finite number in [low, high]), ``"bool"`` (true or false) or ``"choice"`` (one of
            ``choices``).
        low, high: a real's range.
        choices: a choice's strings.
        nullable: null is accepted too (an estimate the belief could not make).
        info_key: the final info's key when it is not ``name`` (empty: ``name``). A choice's info value is the
            index of its choice (the info holds numbers only); the record holds the choice's string.
    """

    name: str
    doc: str = ""
    unit: str = ""
    kind: str = "real"
    low: float = -math.inf
    high: float = math.inf
    choices: tuple[str, ...] = ()
    nullable: bool = False
    info_key: str = ""

    def from_info(self, info: Mapping[str, Any]) -> Any:
        """This field's value in a final info, as the record holds it (a choice: its string)."""
        value = info[self.info_key or self.name]
        if self.kind == "choice" and not isinstance(value, str):
            return self.choices[int(value)]
        return value

    def __post_init__(self) -> None:
        if self.kind not in ("real", "bool", "choice"):
            raise ValueError(f"kind must be one of ['real', 'bool', 'choice'], got {self.kind!r}")

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` (a JSON value read back) is one this field may hold."""
        if value is None:
            return self.nullable
        if self.kind == "bool":
            return isinstance(value, bool)
        if self.kind == "choice":
            return isinstance(value, str) and value in self.choices
        return (
            isinstance(value, (int, float))
            and not isinstance(value, bool)
            and math.isfinite(value)
            and self.low <= value <= self.high
        )

    @property
    def what(self) -> str:
        """What a value must be, for messages."""
        if self.kind == "bool":
            text = "true or false"
        elif self.kind == "choice":
            text = f"one of {list(self.choices)}"
        else:
            text = f"a number in [{self.low:g}, {self.high:g}]" + (f" {self.unit}" if self.unit else "")
        return text + (" or null" if self.nullable and self.kind != "bool" else "")


class _CellFormatter(string.Formatter):
    """``str.format`` over a statistics row: a missing or null value is ``–``; ``!p`` a fraction as a percentage."""

    def get_value(self, key: int | str, args: Any, kwargs: Any) -> Any:
        return kwargs.get(key) if isinstance(key, str) else args[key]

    def convert_field(self, value: Any, conversion: str | None) -> Any:
        if conversion == "p":
            return None if value is None else 100 * value
        return super().convert_field(value, conversion)

    def format_field(self, value: Any, format_spec: str) -> str:
        return "–" if value is None else format(value, format_spec)


_CELLS = _CellFormatter()


@dataclass(frozen=True)
class Column:
    """One column of the benchmark table of a task's own statistics.

    Attributes:
        key: the statistic the column shows (a key of the statistics row).
        header: the column's title.
        better: ``"lower"``, ``"higher"`` or None (a count, no direction).
        format: the cell, a ``str.format`` string over the row's keys (``"{key:.1f}"`` when empty); a null
            value is written ``–``; ``{key!p:.0f}`` writes a fraction as a percentage.
        interval: the keys of the statistic's interval (lo, hi), where it has one.
    """

    key: str
    header: str
    better: str | None = None
    format: str = ""
    interval: tuple[str, str] | None = None

    def __post_init__(self) -> None:
        if self.better is not None and self.better not in DIRECTIONS:
            raise ValueError(f"better must be one of {list(DIRECTIONS)} or None, got {self.better!r}")

    def cell(self, row: Mapping[str, Any]) -> str:
        """The column's cell of a statistics row."""
        return _CELLS.vformat(self.format or "{" + self.key + ":.1f}", (), row)

    def keys(self) -> tuple[str, ...]:
        """The row keys the cell reads."""
        return tuple(dict.fromkeys(f for _, f, _, _ in _CELLS.parse(self.format or "{" + self.key + "}") if f))


@dataclass(frozen=True)
class Table:
    """How a task's columns are laid out in the benchmark's table.md.

    Attributes:
        title: the section's title (``replaces``: the document is titled by the env id instead).
        text: the paragraph under the title; ``{name}`` fields are the run's config entries (``{trials}``).
        count: the statistic that says a row holds the task's results (rows without it are left out).
        replaces: the task's table replaces the localisation tables (a task without a success criterion);
            otherwise it follows the Table-4 layout, over its rows.
        pooled: what follows the aggregate row's label (``" (pooled)"``).
    """

    title: str
    text: str
    count: str
    replaces: bool = False
    pooled: str = ""


def _trial_config(config: Mapping[str, Any]) -> dict[str, Any]:
    class _Missing(dict):  # a config entry it lacks reads None, as ``config.get`` does
        def __missing__(self, key: str) -> None:
            return None

    return _Missing(config)


def format_config_text(text: str, config: Mapping[str, Any]) -> str:
    """``text`` with its ``{name}`` fields set from a run's config (a missing entry: ``None``)."""
    return text.format_map(_trial_config(config))


@dataclass(frozen=True)
class Score:
    """A per-episode number that ranks agents: the validation score of training and its checkpoint rule, the
    datasets' reference scores, the offline trainers' checkpoint choice, the learned report's score.

    Attributes:
        key: the value's name: a key of the episode's final info or of a benchmark record (top level or its
            task results, ``shape``).
        better: ``"lower"`` or ``"higher"``.
        label: a few words for it (``"tracking error"``).
        unit: its unit (``"mm"``; empty for none).
        name: its short name in reports' statistics (default: ``key``).
        episode: the value from an episode's final info, or None: ``float(info[key])``.
        record: the value from a benchmark record, or None: ``float(record[key])`` (the record's top level),
            else ``float(record["shape"][key])`` (the task's results).
        best: the words of the best checkpoint's choice (``"fewest mean readings …"``; default: lowest or
            highest mean ``label`` (``key``, ``unit``)), followed by "on the validation episodes".
        reference: a value on the datasets' normalised-score scale (Minari's ``ref_min_score`` and
            ``ref_max_score``, higher better), or None: the value itself when higher is better, its negative
            when lower is.
    """

    key: str
    better: str
    label: str
    unit: str = ""
    name: str = ""
    episode: Callable[[Mapping[str, Any]], float] | None = None
    record: Callable[[Mapping[str, Any]], float] | None = None
    best: str = ""
    reference: Callable[[float], float] | None = None

    def __post_init__(self) -> None:
        if self.better not in DIRECTIONS:
            raise ValueError(f"better must be one of {list(DIRECTIONS)}, got {self.better!r}")
        if not self.name:
            object.__setattr__(self, "name", self.key)
        if not self.best:
            what = f"{self.key}, {self.unit}" if self.unit else self.key
            words = "lowest" if self.better == "lower" else "highest"
            object.__setattr__(self, "best", f"{words} mean {self.label} ({what})")

    def of_info(self, info: Mapping[str, Any]) -> float:
        """The score of an episode from its final info."""
        return float(self.episode(info)) if self.episode is not None else float(info[self.key])

    def on_reference_scale(self, value: float) -> float:
        """``value`` on the datasets' normalised-score scale (higher better; :attr:`reference`)."""
        if self.reference is not None:
            return float(self.reference(value))
        return float(value) if self.better == "higher" else -float(value)

    def of_record(self, record: Mapping[str, Any]) -> float:
        """The score of a benchmark trial from its record."""
        if self.record is not None:
            return float(self.record(record))
        return float(record[self.key] if self.key in record else record["shape"][self.key])

    def beats(self, a: float, b: float) -> bool:
        """Whether ``a`` is strictly better than ``b``."""
        return a < b if self.better == "lower" else a > b

    @property
    def title(self) -> str:
        """The label with its unit (``"tracking error (mm)"``)."""
        return f"{self.label} ({self.unit})" if self.unit else self.label


@dataclass(frozen=True)
class CurvePanel:
    """One panel of a training run's learning curves: an evaluation column (``eval.csv``) over timesteps.

    Attributes:
        key: the column plotted.
        label: the panel's y label.
        ylim: the y axis's limits, or None: automatic.
        percent: the column is a fraction, plotted as a percentage.
    """

    key: str
    label: str
    ylim: tuple[float, float] | None = None
    percent: bool = False


def _no_statistics(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class TaskMetrics:
    """What a task reports (the section comment above): declared once, read by every layer above the engine.

    Attributes:
        record: the fields of a benchmark record's task results (empty: the record has none, ``shape`` null).
        statistics: a group of trial records (one condition and agent, or an agent's pooled trials) → the
            task's own statistics (keys :attr:`statistic_keys`; an empty dict when the records hold no task
            results), added to the benchmark's Appendix-B row.
        statistic_keys: the keys ``statistics`` returns.
        columns: the benchmark table's columns of the task's statistics.
        table: their layout in table.md (None: no table of the task's own).
        score: what ranks agents on the task (:class:`Score`).
        rate: the per-episode yes/no rate reported beside it (success; a capture), a :class:`Score` with
            ``better="higher"``.
        outcome: an episode's final info → the words of how it ended (``"success"``).
        curves: the panels of the learning curves, beside the return.
        eval_columns: the training evaluation's columns of the task's own, beside the shared ones: name →
            a function of the evaluation episodes' final infos (their mean, rate, median).
        success_criterion: the task's episodes end on a success criterion (False: every episode runs to its
            cap, and the records' success is false).
        dataset_info: final-info keys a dataset keeps per step (float64) beside the shared ones.
    """

    score: Score
    rate: Score
    outcome: Callable[[Mapping[str, Any]], str]
    record: tuple[RecordField, ...] = ()
    statistics: Callable[[Sequence[Mapping[str, Any]]], dict[str, Any]] = _no_statistics
    statistic_keys: tuple[str, ...] = ()
    columns: tuple[Column, ...] = ()
    table: Table | None = None
    curves: tuple[CurvePanel, ...] = ()
    eval_columns: Mapping[str, Callable[[Sequence[Mapping[str, Any]]], float]] = dataclasses.field(default_factory=dict)
    success_criterion: bool = True
    dataset_info: tuple[str, ...] = ()

    @property
    def record_keys(self) -> tuple[str, ...]:
        """The names of the record's task results, in declaration order."""
        return tuple(f.name for f in self.record)

    def record_field(self, name: str) -> RecordField:
        """The record field ``name`` (KeyError when the task has none)."""
        for f in self.record:
            if f.name == name:
                return f
        raise KeyError(name)

    def accepts_record(self, results: Any) -> bool:
        """Whether a record's task results (its ``shape`` object) hold exactly :attr:`record_keys`, each in range."""
        return (
            isinstance(results, dict)
            and set(results) == set(self.record_keys)
            and all(f.accepts(results[f.name]) for f in self.record)
        )

    def metric_keys(self) -> tuple[str, ...]:
        """Every name the task owns: record fields, statistics, its score's and rate's keys and curves' columns."""
        names = [*self.record_keys, *self.statistic_keys, *self.eval_columns, *(p.key for p in self.curves)]
        names += [self.score.key, self.rate.key]
        return tuple(dict.fromkeys(names))
