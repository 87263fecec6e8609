"""Helpers the tasks share about worlds (an episode's ``Condition`` or ``Scene``).

Grouping envs by world, and the cached per-world values (descriptors, calibration coefficients, a
condition at another gain).

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
from electroloc_gym.sensor_models import CalibrationProtocol, calibration_coefficients, calibration_grid_for
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.scene import Scene

__all__ = [
    "group_by_world",
    "descriptor",
    "fixed_coefficients",
    "with_gain_factor",
    "scene_condition",
    "cells",
    "grid_points_bound",
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


def cells(grid_mm: NDArray[np.float64]) -> int:
    """Coefficient rows of a calibration grid (its cells plus one)."""
    return (grid_mm.size - 1) ** 2 + 1


@functools.lru_cache(maxsize=64)
def fixed_coefficients(condition: Condition, seed: int, protocol: CalibrationProtocol) -> NDArray[np.float32]:
    """The (read-only) bilinear coefficients of a fixed calibration seed (cached)."""
    n = cells(calibration_grid_for(condition, protocol))
    coef = calibration_coefficients(condition, seed, protocol, out=np.empty((n, 8), dtype=np.float32))
    coef.flags.writeable = False
    return coef


@functools.lru_cache(maxsize=256)
def with_gain_factor(condition: Condition, factor: float) -> Condition:
    """``condition`` with its amplifier gain G times ``factor`` (cached)."""
    return condition.replace(amplifier=condition.amplifier.with_gain(condition.amplifier.gain * factor))


@functools.lru_cache(maxsize=64)
def scene_condition(scene: Scene) -> Condition:
    """The scene's amplifier, water and boxes as a ``Condition`` (cached)."""
    return scene.as_condition()


def grid_points_bound(protocol: CalibrationProtocol, allowed_half_width_mm: float) -> int:
    """An upper bound of a calibration grid's points per axis, computed without building the grid (any
    ``grid_extent`` covers at most twice the allowed box).
    """
    half = 2.0 * allowed_half_width_mm if protocol.half_span_mm is None else protocol.half_span_mm
    return int(min(2.0 * half / protocol.grid_step_mm, 2.0**62)) + 2
