"""The table of import paths that left their place, and the import hook that says where each one went.

:data:`MOVED` is the CHANGELOG's "Moved" tables written out one path a row (``tests/test_imports.py`` checks
that they agree): a module, or a name in a module that still exists.

* Importing an old module path raises :class:`MovedModuleError` naming the new one. :class:`MovedPathFinder`
  sits at the end of ``sys.meta_path``, so it is asked only about modules no other finder found. Python
  imports a package before its module, so an old package whose modules went to several places
  (``electroloc_gym.core``) raises, at the package, where each of them went.
* An old name in a module that still exists is refused by that module's ``__getattr__``
  (:func:`moved_name_error`) with an ``ImportError``, so that ``from module import name`` reports it too
  (Python replaces an ``AttributeError`` there with its own message).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from importlib.machinery import ModuleSpec
from types import ModuleType

__all__ = [
    "MOVED",
    "MOVED_IN",
    "MOVES_BY_RELEASE",
    "UNRELEASED",
    "MovedModuleError",
    "MovedNameError",
    "MovedPathFinder",
    "install",
    "moved_module_error",
    "moved_name_error",
]

#: The release whose tree made the first moves (0.3.0's "Moved" table); later moves name their own section.
MOVED_IN = "0.3.0"
#: The CHANGELOG section of moves not yet in a release.
UNRELEASED = "Unreleased"

_P = "electroloc_gym"

#: Old path → new path of 0.3.0's moves, one row per module or name (its "Moved" table, expanded).
_MOVED_0_3_0: dict[str, str] = {
    **{f"{_P}.{m}": f"{_P}.utils.{m}" for m in ("checks", "fileio", "markdown", "runtime", "agentspec")},
    **{
        f"{_P}.{m}": f"{_P}.world.{m}"
        for m in (
            "physics",
            "detection",
            "apparatus",
            "conditions",
            "sensor",
            "sensor_array",
            "scene",
            "distractors",
            "distractor_layout",
        )
    },
    f"{_P}.draws": f"{_P}.kernels.streams",
    f"{_P}.kernels.observation": f"{_P}.kernels.belief_rows",
    **{f"{_P}.core.{m}": f"{_P}.contract.{m}" for m in ("params", "observation", "capabilities")},
    **{
        f"{_P}.core.{m}": f"{_P}.engines.numba_core.{m}"
        for m in ("step", "state", "task", "worlds", "array", "electroloc", "global_task", "unknown")
    },
    f"{_P}.core.localize": f"{_P}.engines.numba_core.localize_task",
    f"{_P}.core.distractors": f"{_P}.engines.numba_core.distractor_task",
    **{
        f"{_P}.torch_core.{m}": f"{_P}.engines.torch_core.{m}"
        for m in ("consts", "rng", "calibration", "sim", "device")
    },
    f"{_P}.torch_core.filter": f"{_P}.engines.torch_core.belief_update",
    f"{_P}.torch_core.vector_env": f"{_P}.envs.torch_vector",
    f"{_P}.torch_core.sub_env": f"{_P}.envs.torch_sub_env",
    f"{_P}.torch_core.sb3": f"{_P}.envs.torch_sb3",
    **{f"{_P}.{m}": f"{_P}.views.{m}" for m in ("belief", "render", "eev_maps")},
    f"{_P}.privileged": f"{_P}.envs.privileged",
    f"{_P}.rollout": f"{_P}.baselines.rollout",
    f"{_P}.rllib": f"{_P}.train.rllib",
    f"{_P}.bench.cli": f"{_P}.bench.bench_command",
    f"{_P}.dataset.cli": f"{_P}.dataset.dataset_command",
    f"{_P}.dataset.protocol": f"{_P}.dataset.seed_protocol",
    f"{_P}.envs.adapter.condition_index": f"{_P}.contract.observation.condition_index",
}

#: The names a task took with its options, and the calibration helpers both engines share (the Unreleased
#: section's "Moved" table, expanded).
_MOVED_UNRELEASED: dict[str, str] = {
    **{
        f"{_P}.contract.params.{n}": f"{_P}.engines.numba_core.track_task.{n}"
        for n in ("TARGET_MOTIONS", "MOTION_MODELS", "MAX_TARGET_SPEED_MM", "MOTION_OPTION_SCOPES")
    },
    **{
        f"{_P}.contract.params.{n}": f"{_P}.engines.numba_core.unknown.{n}"
        for n in ("TARGET_DRAWS", "CONTRASTS", "DEFAULT_RADIUS_RANGE_MM", "RADIUS_LIMITS_MM")
    },
    **{
        f"{_P}.contract.params.{n}": f"{_P}.engines.numba_core.global_task.{n}"
        for n in ("LAYOUTS", "MAX_POSITION_BLUR_MM")
    },
    **{
        f"{_P}.engines.numba_core.worlds.{n}": f"{_P}.sensor_models.calibrated.{n}"
        for n in ("fixed_coefficients", "grid_points_bound")
    },
    f"{_P}.engines.numba_core.worlds.cells": f"{_P}.sensor_models.calibrated.coefficient_rows",
    **{f"{_P}.envs.{m}": f"{_P}.envs" for m in ("global_env", "unknown_target", "track_env")},
}

#: The moves of each CHANGELOG section that has a "Moved" table.
MOVES_BY_RELEASE: dict[str, dict[str, str]] = {MOVED_IN: _MOVED_0_3_0, UNRELEASED: _MOVED_UNRELEASED}
#: Old path → new path, one row per module or name (every "Moved" table of the CHANGELOG, expanded).
MOVED: dict[str, str] = {old: new for moves in MOVES_BY_RELEASE.values() for old, new in moves.items()}


def _when(old: str) -> str:
    """When ``old`` (a path or an old package's prefix) moved, with where it is said."""
    release = next(
        (r for r, m in MOVES_BY_RELEASE.items() if any(k == old or k.startswith(old + ".") for k in m)), MOVED_IN
    )
    if release == UNRELEASED:
        return f'after electroloc-gym {MOVED_IN} (the CHANGELOG\'s "Moved" table of {UNRELEASED})'
    return f'in electroloc-gym {release} (the CHANGELOG\'s "Moved" table)'


class MovedModuleError(ModuleNotFoundError):
    """An import of a module path that moved; the message names the new path."""


class MovedNameError(ImportError):
    """A name read from a module it moved out of; the message names its new place."""


def _package_text(package: str) -> str | None:
    """Where the modules of an old package went (None: ``package`` holds no moved module)."""
    moves = {old.removeprefix(package + "."): new for old, new in MOVED.items() if old.startswith(package + ".")}
    if not moves:
        return None
    same: dict[str, list[str]] = {}  # new package → the module names kept there
    renamed: list[str] = []
    for leaf, new in moves.items():
        parent, _, new_leaf = new.rpartition(".")
        if new_leaf == leaf:
            same.setdefault(parent, []).append(leaf)
        else:
            renamed.append(f"{leaf} to {new}")
    kept = [f"{', '.join(leaves)} to {parent} (the same names)" for parent, leaves in same.items()]
    return f"its modules moved {_when(package)}: {'; '.join(kept + renamed)}"


def moved_module_error(fullname: str) -> MovedModuleError | None:
    """The error for importing ``fullname`` when no module of that name exists (None: it never moved)."""
    text = f"it moved to {MOVED[fullname]} {_when(fullname)}" if fullname in MOVED else _package_text(fullname)
    if text is None:
        return None
    return MovedModuleError(f"No module named {fullname!r}: {text}", name=fullname)


def moved_name_error(module: str, name: str) -> ImportError | AttributeError:
    """What a module's ``__getattr__`` raises for ``name``: :class:`MovedNameError` naming the new place of a
    name that moved out of ``module``, else Python's own ``AttributeError``.
    """
    new = MOVED.get(f"{module}.{name}")
    if new is None:
        return AttributeError(f"module {module!r} has no attribute {name!r}")
    return MovedNameError(
        f"{module}.{name} moved to {new} {_when(f'{module}.{name}')}; import it from there", name=module
    )


class MovedPathFinder:
    """A ``sys.meta_path`` finder that raises :class:`MovedModuleError` for an old module path of the package
    and finds nothing itself.
    """

    @classmethod
    def find_spec(
        cls, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> ModuleSpec | None:
        error = moved_module_error(fullname) if fullname.startswith(_P + ".") else None
        if error is not None:
            raise error
        return None

    @classmethod
    def invalidate_caches(cls) -> None:
        """Nothing cached (``importlib.invalidate_caches`` calls this on every finder)."""


def install() -> None:
    """Put :class:`MovedPathFinder` at the end of ``sys.meta_path`` (once)."""
    if MovedPathFinder not in sys.meta_path:
        sys.meta_path.append(MovedPathFinder)
