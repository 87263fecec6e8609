"""electroloc-gym: the active-electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008) as Gymnasium envs.

Importing the package registers the environment ids of the env table (:mod:`electroloc_gym.registry`;
idempotent); :func:`register_env` adds another:

* ``ElectroLoc-v0`` — localise a target sphere with a particle-filter belief.
* ``ElectroLocGlobal-v0`` — the robot localises itself in a mapped tank of six cylinders (§6.5).
* ``ElectroLocUnknownTarget-v0`` — localise a sphere of unknown size and material (§7).
* ``ElectroLocTrack-v0`` — follow a target sphere that swims during the episode (the prey-capture task).

An import of a module path that moved (the CHANGELOG's "Moved" table, :mod:`electroloc_gym.utils.moved_paths`)
raises a ``ModuleNotFoundError`` naming the new path.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from gymnasium.envs import registration

from electroloc_gym.utils.moved_paths import install as _install_moved_paths
from electroloc_gym.utils.runtime import use_user_numba_cache

_install_moved_paths()  # an old module path names its new one
use_user_numba_cache()  # before the first numba import (below): the compiled kernels are cached once per user

from electroloc_gym.registry import ENV_IDS, EnvEntry, add_entry, class_path  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, Condition, get_condition  # noqa: E402

try:  # the version is declared once, in pyproject.toml
    __version__ = version("electroloc-gym")
except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["PRESET_NAMES", "Condition", "get_condition", "ENV_IDS", "EnvEntry", "register_env", "__version__"]


def register_env(entry: EnvEntry) -> EnvEntry:
    """Add ``entry`` to the env table and register its id with Gymnasium (``gym.make``, ``gym.make_vec``);
    idempotent for the same entry. An entry without ``env_class``/``vector_class`` gets generic ones
    (:func:`electroloc_gym.envs.generic.env_classes`: the family's single env and the native vector env,
    one pair per entry). A researcher's module calls this at import (:mod:`electroloc_gym.tasks`).

    Returns:
        the entry as the table holds it (with its env classes).

    Raises:
        ValueError: not an ``EnvEntry``, or another entry with the same id, task, env class or bench name.
    """
    if not isinstance(entry, EnvEntry):
        raise ValueError(f"entry must be an EnvEntry, got {type(entry).__name__}")
    if entry.env_class is None or entry.vector_class is None:
        entry = _with_env_classes(entry)
    add_entry(entry)
    if entry.env_id not in registration.registry:
        assert entry.env_class is not None and entry.vector_class is not None  # completed above
        registration.register(
            id=entry.env_id, entry_point=class_path(entry.env_class), vector_entry_point=class_path(entry.vector_class)
        )
    return entry


def _with_env_classes(entry: EnvEntry) -> EnvEntry:
    """``entry`` with generic env classes where it names none; the table's own entry when it holds this one."""
    import dataclasses

    from electroloc_gym.registry import ENVS

    for e in ENVS:  # registered before (a module imported twice, or the same entry again)
        if (
            e.env_id == entry.env_id
            and dataclasses.replace(e, env_class=entry.env_class, vector_class=entry.vector_class) == entry
        ):
            return e
    from electroloc_gym.envs.generic import env_classes

    single, vector = env_classes(entry.env_id, entry.task_class)
    return dataclasses.replace(entry, env_class=entry.env_class or single, vector_class=entry.vector_class or vector)


def _register_builtin() -> None:
    from electroloc_gym.envs.table import BUILTIN_ENVS

    for entry in BUILTIN_ENVS:
        register_env(entry)


_register_builtin()
