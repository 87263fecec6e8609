"""The env classes of an env-table entry: its family's single and vector env, its task's documentation and options.

Every env of the package is the simulation core behind :class:`~electroloc_gym.envs.adapter.CoreEnv` (single)
and :class:`~electroloc_gym.envs.vector.CoreVectorEnv` (native vector); what differs between envs is the task.
So no task writes an env class: :func:`env_classes` builds the two for an entry, built-in or a researcher's
(:mod:`electroloc_gym.tasks`).

* **The family** gives the bases, read from what the task class declares: a task of the localise family
  (:class:`~electroloc_gym.engines.numba_core.localize_task.LocalizeTask`) gets
  :class:`~electroloc_gym.envs.localize.LocalizeEnv` / :class:`~electroloc_gym.envs.localize.LocalizeVectorEnv`
  (its target, move bounds and renderer), a task whose belief is over the robot's own position
  (``belief_frame == "robot"``) gets :class:`~electroloc_gym.envs.self_localize.SelfLocalizeEnv` /
  :class:`~electroloc_gym.envs.self_localize.SelfLocalizeVectorEnv` (its map and odometry), any other task the two
  core classes.
* **The task** gives the rest: the class's docstring is the task class's (the env's documentation lives with
  the task), and every field of its ``Options`` that the base does not already show is a read-only property of
  the single env (``env.unwrapped.target_speed_mm``: the option as the env was made with it).
* **The names**: ``<Stem>Env`` and ``<Stem>VectorEnv`` for a task class ``<Stem>Task`` (``FooTask`` →
  ``FooEnv``), else from the env id (``MyTask_v0Env`` for ``MyTask-v0``). The classes are set as attributes of
  the task class's module, so that Gymnasium's entry-point strings and pickling find them by name wherever that
  module imports (a worker process, a subprocess vector env); :mod:`electroloc_gym.envs` gives every entry's
  classes by name (``from electroloc_gym.envs import FooEnv``).
"""

from __future__ import annotations

import dataclasses
import re
import sys
from typing import Any, cast

from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.task import Task
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.envs.localize import LocalizeEnv, LocalizeVectorEnv
from electroloc_gym.envs.self_localize import SelfLocalizeEnv, SelfLocalizeVectorEnv
from electroloc_gym.envs.vector import CoreVectorEnv

__all__ = ["env_classes", "family_bases"]

#: Marks a class built here (its env id), so that building again for the same id reuses the name.
_GENERATED = "__electroloc_generated_for__"


def family_bases(task_class: type[Task]) -> tuple[type[CoreEnv], type[CoreVectorEnv]]:
    """The (single, vector) env classes a task's env classes subclass: its family's (module docstring)."""
    if issubclass(task_class, LocalizeTask):
        return LocalizeEnv, LocalizeVectorEnv
    if task_class.belief_frame == "robot":
        return SelfLocalizeEnv, SelfLocalizeVectorEnv
    return CoreEnv, CoreVectorEnv


def _names(env_id: str, task_class: type[Task]) -> tuple[str, str]:
    """(single, vector) class names (module docstring): from the task class, else from the env id."""
    stem = task_class.__name__.removesuffix("Task")
    module = sys.modules.get(task_class.__module__)
    free = all(
        getattr(present, _GENERATED, None) == env_id
        for present in (getattr(module, stem + suffix, None) for suffix in ("Env", "VectorEnv"))
        if present is not None
    )
    if stem and stem != task_class.__name__ and free:  # one entry per task class takes its name
        return stem + "Env", stem + "VectorEnv"
    stem = re.sub(r"\W", "_", env_id)
    stem = "_" + stem if stem[:1].isdigit() else stem
    return stem + "Env", stem + "VectorEnv"


def _option_property(options: type, name: str, doc: str) -> property:
    def read(self: Any) -> Any:
        return getattr(self.params.options_as(options), name)

    read.__name__ = name
    return property(read, doc=doc)


def _option_properties(task_class: type[Task], base: type) -> dict[str, property]:
    """A read-only property per field of the task's options that ``base`` does not already have."""
    options = task_class.Options
    out: dict[str, property] = {}
    for f in dataclasses.fields(options):
        if f.name.startswith("_") or hasattr(base, f.name):
            continue
        doc = f.metadata.get("doc") if f.metadata else None
        out[f.name] = _option_property(
            options, f.name, f"The option ``{f.name}`` the env was made with: {doc or 'see Options'}."
        )
    return out


def _place(cls: type, module_name: str) -> None:
    """Set ``cls`` as its module's attribute (refusing to replace an attribute the module defined itself)."""
    module = sys.modules.get(module_name)
    if module is None:
        return
    name = cls.__name__
    present = getattr(module, name, None)
    if present is not None and getattr(present, _GENERATED, None) != getattr(cls, _GENERATED):
        raise ValueError(
            f"module {module_name!r} already has an attribute {name!r}; the generic env of "
            f"{getattr(cls, _GENERATED)} would replace it (name the entry's env_class yourself)"
        )
    setattr(module, name, cls)


def env_classes(env_id: str, task_class: type[Task]) -> tuple[type[CoreEnv], type[CoreVectorEnv]]:
    """(single, native vector) env classes of the entry ``env_id`` of ``task_class`` (module docstring)."""
    module = task_class.__module__
    doc = task_class.__doc__ if (task_class.__doc__ or "").strip() else None
    single_base, vector_base = family_bases(task_class)
    single_name, vector_name = _names(env_id, task_class)
    attrs: dict[str, Any] = {"__module__": module, _GENERATED: env_id}
    single = type(  # a subclass of the family's CoreEnv
        single_name,
        (single_base,),
        {
            **attrs,
            **_option_properties(task_class, single_base),
            "__doc__": doc or f"{env_id}: the single env of the task {task_class.__qualname__}.",
        },
    )
    vector = type(
        vector_name,
        (vector_base,),
        {
            **attrs,
            "__doc__": f"``num_envs`` envs of {env_id} stepped as one core (the task {task_class.__qualname__}; "
            f"the single env's arguments, plus ``num_envs`` and ``autoreset_mode``).",
        },
    )
    for cls in (single, vector):
        cls.__qualname__ = cls.__name__
        _place(cls, module)
    return cast("type[CoreEnv]", single), cast("type[CoreVectorEnv]", vector)
