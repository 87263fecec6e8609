"""How an action becomes the carriage's move and how the tank's walls stop it, the rule both engines follow.

The carriage moves at most :data:`~electroloc_gym.protocol.MAX_STEP_MM` per axis per step (paper §4.1.3):
a continuous action ``a`` in [−1, 1]² moves it by ``clip(a, −1, 1)·MAX_STEP_MM`` mm, a discrete one by its
row of :data:`~electroloc_gym.contract.params.DISCRETE_MOVES_MM` (stay or one of the 8 king moves). The
carriage is then kept inside the allowed box ``|x|, |y| ≤ H`` (the condition's allowed half-width, mm): a
move that would cross a wall stops at it, each axis on its own.

Each function takes the arrays' namespace ``xp`` — numpy for the numba engine, torch for the torch
engine's tensors — and uses only indexing, ``+``, ``*`` and ``clip``, which both have with the same
meaning, in the inputs' precision (float64 in both engines; float32 for the hypotheses an agent moves).
The callers keep what is theirs: the numba engine's checks of an action's values
(:mod:`electroloc_gym.envs.actions`), the torch engine's dtype casts and device-side checks.
"""

from __future__ import annotations

from typing import Any

from electroloc_gym.contract.params import DISCRETE_MOVES_MM
from electroloc_gym.protocol import MAX_STEP_MM

__all__ = ["commanded_moves_mm", "within_walls_mm", "carriage_after_move_mm"]


def commanded_moves_mm(xp: Any, actions: Any, discrete: bool, moves_table_mm: Any = DISCRETE_MOVES_MM) -> Any:
    """(…, 2) commanded moves, mm, of checked actions.

    Args:
        xp: the arrays' namespace (numpy or torch).
        actions: continuous: (…, 2) reals (float64; finite values outside [−1, 1] are clipped);
            discrete: (…,) integer indices into ``moves_table_mm`` (in range: the caller checks them).
        discrete: whether the actions are discrete.
        moves_table_mm: the (9, 2) discrete moves, mm, in the actions' namespace
            (:data:`~electroloc_gym.contract.params.DISCRETE_MOVES_MM`; the torch engine passes its copy
            on the device).
    """
    if discrete:
        return moves_table_mm[actions]
    return xp.clip(actions, -1.0, 1.0) * MAX_STEP_MM


def within_walls_mm(xp: Any, points_mm: Any, half_mm: Any) -> Any:
    """``clip(points_mm, −H, H)``: positions (the carriage, or hypotheses of it) kept inside the allowed box,
    each axis truncated at its wall; ``half_mm`` the allowed half-width H, mm, broadcastable against
    ``points_mm`` (e.g. (k, 1) for (k, 2) points).
    """
    return xp.clip(points_mm, -half_mm, half_mm)


def carriage_after_move_mm(xp: Any, position_mm: Any, moves_mm: Any, half_mm: Any) -> Any:
    """The carriage after commanded moves: ``clip(position + move, −H, H)`` (mm; shapes broadcast, ``half_mm``
    as :func:`within_walls_mm`).
    """
    return within_walls_mm(xp, position_mm + moves_mm, half_mm)
