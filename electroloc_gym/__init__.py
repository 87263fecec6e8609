"""electroloc-gym: the active-electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008) as Gymnasium envs.

Importing the package registers the environment ids (idempotent):

* ``ElectroLoc-v0`` — localise a target sphere with a particle-filter belief.
* ``ElectroLocGlobal-v0`` — the robot localises itself in a mapped tank of six cylinders (§6.5).
* ``ElectroLocUnknownTarget-v0`` — localise a sphere of unknown size and material (§7).
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition

__version__ = "0.1.0"

__all__ = ["PRESET_NAMES", "Condition", "get_condition", "ENV_IDS", "__version__"]

ENV_IDS: tuple[str, ...] = ("ElectroLoc-v0", "ElectroLocGlobal-v0", "ElectroLocUnknownTarget-v0")


def _register() -> None:
    if "ElectroLoc-v0" not in registry:
        register(id="ElectroLoc-v0", entry_point="electroloc_gym.envs.localize:ElectroLocEnv",
                 vector_entry_point="electroloc_gym.envs.vector:make_electroloc_vector_env")
    if "ElectroLocGlobal-v0" not in registry:
        register(id="ElectroLocGlobal-v0", entry_point="electroloc_gym.envs.self_localize:GlobalLocalizationEnv",
                 vector_entry_point="electroloc_gym.envs.vector:make_global_vector_env")
    if "ElectroLocUnknownTarget-v0" not in registry:
        register(id="ElectroLocUnknownTarget-v0", entry_point="electroloc_gym.envs.unknown_target:UnknownTargetEnv",
                 vector_entry_point="electroloc_gym.envs.vector:make_unknown_target_vector_env")


_register()
