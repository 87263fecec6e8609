"""electroloc-gym: the active-electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008) as Gymnasium envs.

Importing the package registers the environment ids of the env table (:mod:`electroloc_gym.registry`;
idempotent):

* ``ElectroLoc-v0`` — localise a target sphere with a particle-filter belief.
* ``ElectroLocGlobal-v0`` — the robot localises itself in a mapped tank of six cylinders (§6.5).
* ``ElectroLocUnknownTarget-v0`` — localise a sphere of unknown size and material (§7).
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from gymnasium.envs import registration

from electroloc_gym.runtime import use_user_numba_cache

use_user_numba_cache()  # before the first numba import (below): the compiled kernels are cached once per user

from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition  # noqa: E402
from electroloc_gym.registry import ENV_IDS, ENVS  # noqa: E402

try:  # the version is declared once, in pyproject.toml
    __version__ = version("electroloc-gym")
except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["PRESET_NAMES", "Condition", "get_condition", "ENV_IDS", "__version__"]


def _register() -> None:
    for entry in ENVS:
        if entry.env_id not in registration.registry:
            registration.register(id=entry.env_id, entry_point=entry.entry_point,
                                  vector_entry_point=entry.vector_entry_point)


_register()
