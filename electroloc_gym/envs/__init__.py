"""Gymnasium environments of electroloc-gym: thin adapters over the simulation engines.

Each env of the table (:mod:`electroloc_gym.registry`) is a :class:`~.adapter.CoreEnv` (single) and a
:class:`~.vector.CoreVectorEnv` (native vector) of its task's family (:mod:`.localize`, :mod:`.self_localize`),
built for its entry (:mod:`.generic`); :mod:`.actions` parses the actions. Every entry's classes are this
package's attributes by name (``from electroloc_gym.envs import <Stem>Env``, :mod:`.generic`).
"""

from __future__ import annotations

from typing import Any

from electroloc_gym.registry import env_class_named

__all__: list[str] = []


def __getattr__(name: str) -> Any:
    """An entry's single or native vector env class by its name (the table's, registered at import)."""
    return env_class_named(__name__, name)
