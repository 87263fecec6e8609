"""Gymnasium environments of electroloc-gym: thin adapters over the simulation engines.

Each env of the table (:mod:`electroloc_gym.registry`) is a :class:`~.adapter.CoreEnv` (single) and a
:class:`~.vector.CoreVectorEnv` (native vector) with its id; :mod:`.actions` parses the actions.
"""

from __future__ import annotations

from electroloc_gym.envs.global_env import GlobalEnv
from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.envs.unknown_target import UnknownTargetEnv
from electroloc_gym.envs.vector import ElectroLocVectorEnv, GlobalVectorEnv, UnknownTargetVectorEnv

__all__ = [
    "ElectroLocEnv",
    "GlobalEnv",
    "UnknownTargetEnv",
    "ElectroLocVectorEnv",
    "GlobalVectorEnv",
    "UnknownTargetVectorEnv",
]
