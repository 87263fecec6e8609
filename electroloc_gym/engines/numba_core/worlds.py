"""Helpers the tasks share about worlds (an episode's ``Condition`` or ``Scene``).

Grouping envs by world, and the cached per-world values (descriptors, a condition at another gain; the
calibration's coefficient tables are :mod:`electroloc_gym.sensor_models.calibrated`'s, which both engines read).

Batched numpy work is grouped by world (one call for all envs sharing a condition or map) and uses
only exact operations, so every env's values are those it would get alone (docs/design.md).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.observation import condition_descriptor
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.utils.moved_paths import moved_name_error
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.scene import Scene

__all__ = [
    "group_by_world",
    "descriptor",
    "with_gain_factor",
    "scene_condition",
    "SEED_BOUND",
]

#: Calibration seeds are drawn in [0, 2**31 − 1).
SEED_BOUND = 2**31 - 1


def group_by_world(state: State, ids: NDArray[np.intp], by_gain: bool = False) -> list[tuple[Any, NDArray[np.intp]]]:
    """``[(world, positions in ids)]``: the envs of ``ids`` sharing one world (and, ``by_gain``, one gain
    level), in order of the keys.
    """
    keys = state.world_key[ids]
    if by_gain:  # (world, level) as one key: world · (levels in use) + level
        levels = state.gain_index[ids]
        keys = keys * (int(levels.max()) + 1) + levels
    if len(ids) == 1 or (keys == keys[0]).all():
        return [(state.world[int(ids[0])], np.arange(len(ids)))]
    out = []
    for key in np.unique(keys):
        rows = np.flatnonzero(keys == key)
        out.append((state.world[int(ids[rows[0]])], rows))
    return out


@functools.lru_cache(maxsize=256)
def descriptor(condition: Condition) -> NDArray[np.float32]:
    """The observation's condition descriptor of ``condition`` (cached)."""
    return condition_descriptor(condition)


@functools.lru_cache(maxsize=256)
def with_gain_factor(condition: Condition, factor: float) -> Condition:
    """``condition`` with its amplifier gain G times ``factor`` (cached)."""
    return condition.replace(amplifier=condition.amplifier.with_gain(condition.amplifier.gain * factor))


@functools.lru_cache(maxsize=64)
def scene_condition(scene: Scene) -> Condition:
    """The scene's amplifier, water and boxes as a ``Condition`` (cached)."""
    return scene.as_condition()


def __getattr__(name: str) -> Any:
    """A name that moved out of this module: one ImportError naming its new place (``utils.moved_paths``)."""
    raise moved_name_error(__name__, name)
