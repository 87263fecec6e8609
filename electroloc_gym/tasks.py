"""electroloc_gym.tasks: the public API of a task of your own, written in one file of your own package.

A task is one place: its class (what the simulation core calls: motion, readings, reward, episode end,
info) and the declarations next to it, which every layer above the core reads and none restates:

* ``Options`` — a frozen :class:`TaskOptions` dataclass, one :func:`option` per keyword argument of its env
  (default, doc, unit, a check such as :class:`Real` or :class:`Choice`: a bad value is one ``ValueError``
  naming the argument and what is allowed); ``gym.make`` validates them, ``electroloc bench`` and the docs
  list them;
* ``State`` — a :class:`TaskState` dataclass, one :func:`state_array` per per-env array (dtype, shape, fill),
  which the engine allocates, resets, copies and gathers for every env of a vector env;
* ``metrics`` — a :class:`TaskMetrics`: the benchmark record's fields (:class:`RecordField`, checked on
  ``--resume``), the statistics per condition, the table's columns (:class:`Column`, :class:`Table`), the
  :class:`Score` that ranks agents (training's validation score, datasets' reference, checkpoints), the
  outcome's words, the learning curves' panels (:class:`CurvePanel`).

Subclass :class:`LocalizeTask` (the localise family: a target sphere in a tank of the paper's conditions,
the carriage, the sensor and the particle-filter belief) or :class:`Task`, then register an
:class:`EnvEntry` with :func:`register_env` when your module is imported: no env class to write (a generic
single and native vector env are built for the entry). ``gym.make("my_module:MyTask-v0")`` imports
``my_module`` and makes the env (Gymnasium's convention), and the command lines take the same
``MODULE:NAME`` (``electroloc bench --env my_module:my-bench``, ``electroloc dataset --env
my_module:MyTask-v0``, ``electroloc train --env my_module:MyTask-v0``). The worked example is
``examples/own_task.py``; docs/design.md, "How to add an environment", says what stays shared.
"""

from __future__ import annotations

from electroloc_gym import register_env
from electroloc_gym.contract.params import EnvParams, LocalizeOptions
from electroloc_gym.contract.task_spec import (
    Boolean,
    Choice,
    Column,
    CurvePanel,
    Integer,
    Numbers,
    Optional,
    Real,
    RecordField,
    Score,
    Table,
    TaskMetrics,
    TaskOptions,
    TaskState,
    option,
    state_array,
)
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS, Task
from electroloc_gym.registry import BenchEnv, EnvEntry

__all__ = [
    # the task bases and what they are built with
    "Task",
    "LocalizeTask",
    "LocalizeOptions",
    "EnvParams",
    "State",
    # options
    "TaskOptions",
    "option",
    "Choice",
    "Real",
    "Integer",
    "Boolean",
    "Numbers",
    "Optional",
    # per-env state
    "TaskState",
    "state_array",
    # metrics
    "TaskMetrics",
    "RecordField",
    "Column",
    "Table",
    "Score",
    "CurvePanel",
    "LOCALIZATION_METRICS",
    # registration
    "EnvEntry",
    "BenchEnv",
    "register_env",
]
