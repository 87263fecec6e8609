"""The env table: every fact about an environment, declared once in one :class:`EnvEntry`.

:data:`ENVS` is the one table that the rest of the package reads:

* :func:`electroloc_gym.register_env` adds an entry and registers its id with Gymnasium (the built-in
  entries are in :mod:`electroloc_gym.envs.table`);
* the simulation core builds an entry's task from ``task_class`` (:func:`task_entry`) and validates its
  arguments against ``arguments`` (the fields of the task class's ``Options``) and ``sensor_models``
  (:mod:`electroloc_gym.contract.params`);
* the single and native vector envs find their entry by class (:func:`entry_of_class`);
* ``electroloc bench`` takes its ``--env`` names, conditions, default particle counts, sensor models,
  default agents and table layout from the entries (:mod:`electroloc_gym.bench.config`); RLlib's creator
  and the dataset collector accept every id of the table.

Adding an environment is one :class:`EnvEntry` plus its task module (docs/design.md, "How to add an
environment"). This module is data: it imports nothing of the package, so every layer may read it; the
table's views (:data:`ENVS`, :data:`ENV_IDS`, :data:`TASKS`, :data:`BENCH_ENVS`) are live, so an entry
added later is seen by every reader.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, TypeVar, cast, overload

__all__ = [
    "EnvEntry",
    "BenchEnv",
    "ENVS",
    "env_class_named",
    "ENV_IDS",
    "TASKS",
    "BENCH_ENVS",
    "COMMON_ARGUMENTS",
    "PAPER_TABLES",
    "PAPER_ENV_ID",
    "env_entry",
    "task_entry",
    "bench_env",
    "entry_of_class",
    "add_entry",
    "class_path",
    "frozen",
    "LiveMapping",
    "LiveSequence",
    "resolve_env_name",
    "plugin_modules",
    "import_plugin_modules",
]

#: The arguments every env takes (the fields of ``EnvParams`` shared by all tasks).
COMMON_ARGUMENTS = (
    "observation",
    "sensor_model",
    "n_particles",
    "max_observations",
    "success_spread_mm",
    "action_type",
    "calibration_seed",
    "calibration",
    "max_episode_steps",
)
#: The paper's result tables a benchmark's table.md is laid out like: Table 4 (the target's position per
#: condition and agent) or Table 2 (global self-localisation on one map).
PAPER_TABLES = ("table4", "table2")
#: The paper's env (the target's position, Tables 4 and 1): its row in the table
#: (:mod:`electroloc_gym.envs.table`) and the default env of the benchmark, training and the policy tools.
PAPER_ENV_ID = "ElectroLoc-v0"

_T = TypeVar("_T")


def frozen(d: Mapping[str, Any] | None = None) -> Mapping[str, Any]:
    """A read-only copy of ``d`` (an entry's mappings)."""
    return MappingProxyType(dict(d or {}))


def class_path(cls: type) -> str:
    """``"module:QualName"`` of ``cls`` (Gymnasium's entry-point string)."""
    return f"{cls.__module__}:{cls.__qualname__}"


@dataclass(frozen=True)
class BenchEnv:
    """One ``electroloc bench --env NAME`` choice: an env id with fixed extra arguments.

    Attributes:
        name: the ``--env`` name.
        env_kwargs: arguments the benchmark passes to every trial's env (e.g. ``gain_levels``).
        agents: the default agents' names, or None: every registered controller (then the shipped models
            trained on this env).
        summary: what the choice runs (``electroloc bench --help``).
    """

    name: str
    env_kwargs: Mapping[str, Any] = field(default_factory=frozen)
    agents: tuple[str, ...] | None = None
    summary: str = ""


@dataclass(frozen=True)
class EnvEntry:
    """One registered environment.

    Attributes:
        env_id: the Gymnasium id.
        task: the core's task name (``EnvParams.task``).
        task_class: the task (a :class:`electroloc_gym.engines.numba_core.task.Task` subclass, built with the params;
            its ``Options`` declare the env's own arguments, :attr:`arguments`).
        sensor_models: the sensor models the task implements (the first is the env's and the benchmark's
            default).
        env_class: the single env (a ``CoreEnv`` subclass; Gymnasium's ``entry_point``), or None:
            :func:`electroloc_gym.register_env` builds a generic one for the entry
            (:mod:`electroloc_gym.envs.generic`).
        vector_class: the native vector env (a ``CoreVectorEnv`` subclass; ``vector_entry_point``), or None:
            built as ``env_class`` is.
        defaults: the env's defaults that differ from ``EnvParams``' (the benchmark's too: its particle
            count and sensor model).
        bench: the ``electroloc bench --env`` choices on this env.
        map_condition: the one condition of an env without ``condition`` presets (its fixed map's name, =
            ``env.unwrapped.condition.name``; its trial seeds use condition index 8), or None: the paper's eight
            presets.
        paper_table: the paper's table the benchmark's results are laid out like (:data:`PAPER_TABLES`).
        bench_kwargs: arguments every benchmark trial on this env passes (part of the benchmark's protocol
            there, e.g. the unknown target drawn from the condition's sphere).
        backends: other simulation backends of the native vector env: name → ``"module:Class"`` (imported
            only when asked for, so an optional dependency such as torch stays optional).
        summary: one line for the package docstring and the docs.
    """

    env_id: str
    task: str
    task_class: type
    sensor_models: tuple[str, ...]
    env_class: type | None = None
    vector_class: type | None = None
    defaults: Mapping[str, Any] = field(default_factory=frozen)
    bench: tuple[BenchEnv, ...] = ()
    map_condition: str | None = None
    paper_table: str = "table4"
    bench_kwargs: Mapping[str, Any] = field(default_factory=frozen)
    backends: Mapping[str, str] = field(default_factory=frozen)
    summary: str = ""

    def __post_init__(self) -> None:
        options = getattr(self.task_class, "Options", None)
        if not (isinstance(options, type) and dataclasses.is_dataclass(options)):
            raise ValueError(
                f"task_class must be a Task subclass whose Options is a TaskOptions dataclass, got {self.task_class!r}"
            )
        if self.paper_table not in PAPER_TABLES:
            raise ValueError(f"paper_table must be one of {list(PAPER_TABLES)}, got {self.paper_table!r}")
        if (self.map_condition is None) != ("condition" in self.arguments):
            raise ValueError(
                "an env takes either the 'condition' argument (map_condition=None) or one fixed map "
                f"(map_condition names it); {self.env_id} has arguments {list(self.arguments)} and "
                f"map_condition={self.map_condition!r}"
            )
        for name in ("defaults", "bench_kwargs", "backends"):
            object.__setattr__(self, name, frozen(getattr(self, name)))

    @property
    def options_class(self) -> type[Any]:
        """The task class's ``Options``: the dataclass of the env's own arguments (a ``TaskOptions``)."""
        return cast("type[Any]", getattr(self.task_class, "Options", None))  # a dataclass: checked on construction

    @property
    def arguments(self) -> tuple[str, ...]:
        """The task's own arguments: the fields of its task class's ``Options`` (the env also takes
        :data:`COMMON_ARGUMENTS`).
        """
        return tuple(f.name for f in dataclasses.fields(self.options_class))

    @property
    def agent_arguments(self) -> tuple[str, ...]:
        """The task's arguments declared the agent's own (``option(..., agent=True)``: how the agent observes,
        e.g. the filter's model of the target), which an agent's ``env_kwargs`` may set where the benchmark
        fixes the others.
        """
        return tuple(f.name for f in dataclasses.fields(self.options_class) if f.metadata.get("agent"))

    @property
    def record_keys(self) -> tuple[str, ...]:
        """The task's info keys a benchmark record keeps under ``"shape"`` (empty: none): the record fields its
        task class's ``metrics`` declare (:class:`~electroloc_gym.contract.task_spec.TaskMetrics`).
        """
        return tuple(cast("Any", self.task_class).metrics.record_keys)

    @property
    def all_arguments(self) -> tuple[str, ...]:
        """Every keyword argument of the env (its own, then the common ones)."""
        return self.arguments + COMMON_ARGUMENTS

    def takes(self, argument: str) -> bool:
        """Whether the env takes the keyword argument ``argument``."""
        return argument in self.all_arguments


_TABLE: list[EnvEntry] = []


class LiveSequence(Sequence[_T]):
    """A read-only sequence recomputed from the table on every use (an entry added later is in it)."""

    def __init__(self, compute: Callable[[], Sequence[_T]]) -> None:
        self._compute = compute

    @overload
    def __getitem__(self, i: int) -> _T: ...
    @overload
    def __getitem__(self, i: slice) -> Sequence[_T]: ...
    def __getitem__(self, i: int | slice) -> _T | Sequence[_T]:
        return tuple(self._compute())[i]

    def __len__(self) -> int:
        return len(self._compute())

    def __eq__(self, other: object) -> bool:
        """Equal to a tuple or list with the same items (as the tuple it stands for)."""
        if isinstance(other, (LiveSequence, tuple, list)):
            items = cast("Sequence[object]", other)  # isinstance: a LiveSequence, tuple or list (of anything)
            return tuple(self) == tuple(items)
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # it changes when the table does

    def __add__(self, other: Sequence[_T]) -> tuple[_T, ...]:
        return (*self, *other)

    def __repr__(self) -> str:
        return repr(tuple(self._compute()))


class LiveMapping(Mapping[str, _T]):
    """A read-only mapping recomputed from the table on every use (an entry added later is in it)."""

    def __init__(self, compute: Callable[[], Mapping[str, _T]]) -> None:
        self._compute = compute

    def __getitem__(self, key: str) -> _T:
        return self._compute()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._compute())

    def __len__(self) -> int:
        return len(self._compute())

    def __repr__(self) -> str:
        return repr(dict(self._compute()))


#: The entries, in the order they were added.
ENVS: Sequence[EnvEntry] = LiveSequence(lambda: _TABLE)
#: The registered ids, in table order.
ENV_IDS: Sequence[str] = LiveSequence(lambda: [e.env_id for e in _TABLE])
#: The core's task names, in table order.
TASKS: Sequence[str] = LiveSequence(lambda: [e.task for e in _TABLE])
#: ``electroloc bench --env`` names → (entry, bench row).
BENCH_ENVS: Mapping[str, tuple[EnvEntry, BenchEnv]] = LiveMapping(
    lambda: {b.name: (e, b) for e in _TABLE for b in e.bench}
)


def _check_is_entry(entry: object) -> None:
    """``add_entry``'s argument: an :class:`EnvEntry`, else a ValueError."""
    if not isinstance(entry, EnvEntry):
        raise ValueError(f"entry must be an EnvEntry, got {type(entry).__name__}")


def add_entry(entry: EnvEntry) -> bool:
    """Add ``entry`` to the table (False if the same entry is there already).

    Raises:
        ValueError: another entry with the same id, task, class or bench name.
    """
    _check_is_entry(entry)
    if entry.env_class is None or entry.vector_class is None:
        raise ValueError(
            f"{entry.env_id}: env_class and vector_class must be env classes here "
            "(electroloc_gym.register_env builds generic ones for an entry without them)"
        )
    if entry in _TABLE:
        return False
    for e in _TABLE:
        for what, a, b in (
            ("env_id", e.env_id, entry.env_id),
            ("task", e.task, entry.task),
            ("env_class", e.env_class, entry.env_class),
            ("vector_class", e.vector_class, entry.vector_class),
        ):
            if a == b:
                raise ValueError(f"{what} {b!r} is already in the env table ({e.env_id})")
        taken = {r.name for r in e.bench} & {r.name for r in entry.bench}
        if taken:
            raise ValueError(f"bench name(s) {sorted(taken)} already belong to {e.env_id}")
    _TABLE.append(entry)
    return True


def env_entry(env_id: str) -> EnvEntry:
    """The entry of ``env_id`` (a ValueError listing the ids otherwise)."""
    for e in _TABLE:
        if e.env_id == env_id:
            return e
    raise ValueError(f"env_id must be one of {list(ENV_IDS)}, got {env_id!r}")


def task_entry(task: str) -> EnvEntry:
    """The entry of the core's task ``task`` (a ValueError listing the tasks otherwise)."""
    for e in _TABLE:
        if e.task == task:
            return e
    raise ValueError(f"task must be one of {list(TASKS)}, got {task!r}")


def entry_of_class(cls: type) -> EnvEntry:
    """The entry whose single or vector env class is ``cls`` or one of its bases (a user's subclass of a
    registered env is that env).
    """
    for base in cls.__mro__:
        for e in _TABLE:
            if base is e.env_class or base is e.vector_class:
                return e
    raise ValueError(
        f"{cls.__qualname__} is no env of the env table; its entry's env_class or vector_class "
        f"names the class (ids: {list(ENV_IDS)})"
    )


def env_class_named(module: str, name: str) -> type:
    """The single or native vector env class of an entry by its class name: the module attribute ``name`` of
    :mod:`electroloc_gym.envs` and of the modules that recorded entry points name (a Minari dataset's spec or a
    pickle may say ``electroloc_gym.envs.localize:<Stem>Env`` or ``electroloc_gym.envs.vector:<Stem>VectorEnv``),
    so that every such entry point resolves to the entry's class.

    Raises:
        ImportError: no entry's class, and ``name`` moved out of ``module``: one line naming its new place.
        AttributeError: no entry's class, and never ``module``'s.
    """
    for e in _TABLE:
        for cls in (e.env_class, e.vector_class):
            if cls is not None and cls.__name__ == name:
                return cls
    from electroloc_gym.utils.moved_paths import moved_name_error

    raise moved_name_error(module, name)


def bench_env(name: str) -> tuple[EnvEntry, BenchEnv]:
    """(entry, bench row) of ``electroloc bench --env NAME`` (a ValueError listing the names otherwise); a
    ``package.module:NAME`` imports the module first (:func:`resolve_env_name`), the row is then ``NAME``'s.
    """
    name = resolve_env_name(name, "--env")
    rows = dict(BENCH_ENVS)
    if name not in rows:
        raise ValueError(f"--env must be one of {list(rows)}, got {name!r}")
    return rows[name]


# ---- envs of a researcher's own module: ``MODULE:NAME`` -----------------------------------------------
# Gymnasium's convention: ``gym.make("my_module:MyTask-v0")`` imports ``my_module`` (whose import registers
# the id) and makes ``MyTask-v0``. The command lines take the same form wherever they take an env
# (``electroloc bench --env``, ``electroloc dataset --env``, ``electroloc train --env``); the modules
# imported so are remembered (:func:`plugin_modules`), so that a process that runs trials (the benchmark's
# spawned workers) imports them again before it makes the env.

_MODULE_RE = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")
_PLUGIN_MODULES: list[str] = []


def plugin_modules() -> tuple[str, ...]:
    """The modules imported for their envs so far (:func:`resolve_env_name`), in import order."""
    return tuple(_PLUGIN_MODULES)


def import_plugin_modules(modules: Sequence[str]) -> None:
    """Import ``modules`` (a worker process: the envs its parent's modules registered)."""
    for name in modules:
        importlib.import_module(name)


def resolve_env_name(name: Any, option: str = "--env") -> Any:
    """The env name ``name`` with its module imported: ``"my_module:NAME"`` imports ``my_module`` (running its
    code, which registers its envs, as Gymnasium's ``gym.make("my_module:Id")`` does) and returns ``NAME``; a
    name without a colon is returned as it is. ``NAME`` is an env id or a benchmark name, as the caller takes.

    Raises:
        ValueError: one line starting with ``option``: a malformed ``MODULE:NAME`` or a module that does not
            import (its exception in a few words).
    """
    if not isinstance(name, str) or ":" not in name:
        return name
    module, _, rest = name.partition(":")
    module, rest = module.strip(), rest.strip()
    if not _MODULE_RE.fullmatch(module) or not rest or ":" in rest:
        raise ValueError(f"{option} {name!r} is malformed: expected NAME or package.module:NAME")
    try:
        importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - any failure of the user's module is reported in one line
        what = f"{type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}".rstrip(": ")
        raise ValueError(
            f"{option} {name!r}: cannot import module {module!r} ({what}); it must be installed or on PYTHONPATH"
        ) from None
    if module not in _PLUGIN_MODULES:
        _PLUGIN_MODULES.append(module)
    return rest
