"""electroloc-gym: the active-electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008) as Gymnasium envs.

Importing the package registers the environment ids of the env table (:mod:`electroloc_gym.registry`;
idempotent):

* ``ElectroLoc-v0`` — localise a target sphere with a particle-filter belief.
* ``ElectroLocGlobal-v0`` — the robot localises itself in a mapped tank of six cylinders (§6.5).
* ``ElectroLocUnknownTarget-v0`` — localise a sphere of unknown size and material (§7).
"""

from __future__ import annotations

from gymnasium.envs import registration

from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition
from electroloc_gym.registry import ENV_IDS, ENVS

__version__ = "0.1.0"

__all__ = ["PRESET_NAMES", "Condition", "get_condition", "ENV_IDS", "__version__"]


def _register() -> None:
    for entry in ENVS:
        if entry.env_id not in registration.registry:
            registration.register(id=entry.env_id, entry_point=entry.entry_point,
                                  vector_entry_point=entry.vector_entry_point)


_register()
