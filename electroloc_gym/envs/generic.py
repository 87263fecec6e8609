"""Generic env classes: the single and native vector env of an env-table entry that names none.

A researcher's task (:mod:`electroloc_gym.tasks`) needs no env class of its own: every env of the package is
the simulation core behind :class:`~electroloc_gym.envs.adapter.CoreEnv` (single) and
:class:`~electroloc_gym.envs.vector.CoreVectorEnv` (native vector), and what differs between envs is the
task. :func:`env_classes` builds the two for an entry: subclasses of the family's env (the localise family's
:class:`~electroloc_gym.envs.localize.ElectroLocEnv`, with its target, move bounds and renderer; the global
family's :class:`~electroloc_gym.envs.global_env.GlobalEnv`; else ``CoreEnv``) and of ``CoreVectorEnv``,
one pair per entry (the env table finds an entry by its classes).

The classes are set as attributes of the task class's module (``MyTask_v0Env`` for ``MyTask-v0``), so
that Gymnasium's entry-point strings and pickling find them by name wherever that module imports (a worker
process, a subprocess vector env).
"""

from __future__ import annotations

import re
import sys
from typing import Any, cast

from electroloc_gym.engines.numba_core.global_task import GlobalTask
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.envs.global_env import GlobalEnv
from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.envs.vector import CoreVectorEnv

__all__ = ["env_classes", "single_base"]

#: Marks a class built here (its env id), so that building again for the same id reuses the name.
_GENERATED = "__electroloc_generated_for__"


def single_base(task_class: type) -> type[CoreEnv]:
    """The single env a generic env of ``task_class`` subclasses: its family's (module docstring)."""
    if issubclass(task_class, LocalizeTask):
        return ElectroLocEnv
    if issubclass(task_class, GlobalTask):
        return GlobalEnv
    return CoreEnv


def _class_name(env_id: str, suffix: str) -> str:
    stem = re.sub(r"\W", "_", env_id)
    return ("_" + stem if stem[:1].isdigit() else stem) + suffix


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


def env_classes(env_id: str, task_class: type) -> tuple[type[CoreEnv], type[CoreVectorEnv]]:
    """(single, native vector) env classes of the entry ``env_id`` of ``task_class`` (module docstring)."""
    module = task_class.__module__
    doc = (task_class.__doc__ or "").strip()
    base = single_base(task_class)
    attrs: dict[str, Any] = {"__module__": module, _GENERATED: env_id}
    single = type(  # a subclass of ``base`` (a CoreEnv)
        _class_name(env_id, "Env"),
        (base,),
        {**attrs, "__doc__": f"{env_id}: the single env of the task {task_class.__qualname__}. {doc}".strip()},
    )
    vector = type(
        _class_name(env_id, "VectorEnv"),
        (CoreVectorEnv,),
        {**attrs, "__doc__": f"{env_id}: ``num_envs`` envs of {task_class.__qualname__} stepped as one core."},
    )
    for cls in (single, vector):
        cls.__qualname__ = cls.__name__
        _place(cls, module)
    return cast("type[CoreEnv]", single), cast("type[CoreVectorEnv]", vector)
