"""The envs' action spaces and the parsing of actions into the core's commanded moves (mm) and gain levels.

Continuous actions: ``Box(-1, 1, (2,))`` scaled to a move of at most
:data:`~electroloc_gym.protocol.MAX_STEP_MM` per axis (finite values outside [−1, 1] are clipped).
Discrete: ``Discrete(9)``, stay or one of the 8 king moves
(:data:`~electroloc_gym.contract.params.DISCRETE_MOVES_MM`). Dynamic gain (``gain_levels``) adds the gain
in the two forms SB3 trains (it has no Dict or Tuple actions): a third Box coordinate cut into K equal
bins (level ⌊(g + 1)/2·K⌋), or ``MultiDiscrete([9, K])``.

Every action is checked before it reaches the core; anything else is one ValueError naming the
action and what is allowed (never a traceback from inside numpy). The checked action becomes its move
by the rule both engines share (:func:`electroloc_gym.contract.motion.commanded_moves_mm`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from electroloc_gym.contract.motion import commanded_moves_mm
from electroloc_gym.contract.params import DISCRETE_MOVES_MM, EnvParams

__all__ = ["ActionParser", "spaces_of"]


def spaces_of(params: EnvParams, obs_dim: int) -> tuple[spaces.Space[Any], spaces.Box]:
    """(action space, observation space) of one env (module docstring), their arrays (bounds, ``nvec``)
    read-only: the spaces are the env's, and an agent reads them (:mod:`electroloc_gym.envs.agent_view`).
    """
    k = len(params.gains)
    if params.action_type == "continuous":
        dims = 3 if params.gain_levels is not None else 2
        action: spaces.Space[Any] = spaces.Box(-1.0, 1.0, shape=(dims,), dtype=np.float32)
    elif params.gain_levels is not None:
        action = spaces.MultiDiscrete([len(DISCRETE_MOVES_MM), k])
    else:
        action = spaces.Discrete(len(DISCRETE_MOVES_MM))
    observation = spaces.Box(-1.0, 1.0, shape=(obs_dim,), dtype=np.float32)
    for space in (action, observation):
        for value in vars(space).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
    return action, observation


def _as_real_array(actions: Any, what: str, shape: tuple[int, ...]) -> NDArray:
    """``actions`` as a numeric (integer or real) numpy array, or a ValueError: strings, bytes, objects,
    complex numbers and dicts are not actions.
    """
    if type(actions) is np.ndarray and actions.dtype.kind in "fiu":  # the common case, at no cost
        return actions
    if isinstance(actions, (str, bytes, dict)):
        raise ValueError(f"{what} must be a number array of shape {shape}, got {actions!r}")
    try:
        a = np.asarray(actions)
    except (ValueError, TypeError) as exc:  # ragged sequences
        raise ValueError(f"{what} must be a number array of shape {shape}, got {actions!r}") from exc
    if a.dtype == np.bool_ or not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        raise ValueError(
            f"{what} must be a number array of shape {shape} (integers or reals), got {actions!r} of dtype {a.dtype}"
        )
    return a


class ActionParser:
    """Actions of one env (``single``) or of N envs → (commanded moves (N, 2) mm, gain levels (N,) or None).

    Args:
        params: the env's parameters (action type, dynamic gain).
        num_envs: N.
    """

    def __init__(self, params: EnvParams, num_envs: int) -> None:
        self.discrete = params.action_type == "discrete"
        self.n_gains = len(params.gains)
        self.dynamic_gain = params.gain_levels is not None
        self.num_envs = num_envs

    def __call__(self, actions: Any, single: bool = False) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
        """(moves (N, 2) mm, gain levels (N,) or None without dynamic gain) of a batch of actions (or of
        one action with ``single``).
        """
        if self.dynamic_gain:
            return self._split_gain_actions(actions, single)
        return self._moves(actions, single), None

    def _split_gain_actions(self, actions: Any, single: bool) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Dynamic gain: continuous (dx, dy, g), g ∈ [−1, 1] cut into K equal bins (level ⌊(g + 1)/2·K⌋);
        discrete (move index, level) of MultiDiscrete([9, K]).
        """
        n, k = self.num_envs, self.n_gains
        if self.discrete:
            shape = (2,) if single else (n, 2)
            what = "action" if single else f"actions of {n} envs"
            a = _as_real_array(actions, what, shape)
            if a.shape != shape or not np.issubdtype(a.dtype, np.integer) or np.any((a[..., 1] < 0) | (a[..., 1] >= k)):
                raise ValueError(
                    f"{what} must be (move index in [0, 8], gain level in [0, {k - 1}]) integers, got {actions!r}"
                )
            a = a.reshape(n, 2)
            return self._moves(a[:, 0], False), a[:, 1].astype(np.int64)
        shape = (3,) if single else (n, 3)
        what = "action" if single else "actions"
        a = np.asarray(_as_real_array(actions, what, shape), dtype=np.float64)
        if a.shape != shape or not np.all(np.isfinite(a)):
            raise ValueError(f"{what} must be finite with shape {shape} (dx, dy, gain in [-1, 1]), got {actions!r}")
        a = a.reshape(n, 3)
        g = np.minimum(np.maximum(a[:, 2], -1.0), 1.0)
        levels = np.minimum(np.floor((g + 1.0) * 0.5 * k), k - 1).astype(np.int64)
        return self._moves(a[:, :2], False), levels

    def _moves(self, actions: Any, single: bool) -> NDArray[np.float64]:
        n = self.num_envs
        if self.discrete:
            what = "action must be an integer" if single else f"actions must be {n} integers"
            a = _as_real_array(actions, "action" if single else "actions", () if single else (n,))
            ok = (a.size == 1 if single else a.shape == (n,)) and np.issubdtype(a.dtype, np.integer)
            if not (ok and np.all((a >= 0) & (a < len(DISCRETE_MOVES_MM)))):
                raise ValueError(f"{what} in [0, {len(DISCRETE_MOVES_MM) - 1}], got {actions!r}")
            return commanded_moves_mm(np, a.reshape(n), True)
        shape = (2,) if single else (n, 2)
        what = "action" if single else "actions"
        a = np.asarray(_as_real_array(actions, what, shape), dtype=np.float64)
        if a.shape != shape:
            raise ValueError(f"{what} must have shape {shape} (dx, dy in [-1, 1]), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what} must be finite (dx, dy in [-1, 1]), got {actions!r}")
        return commanded_moves_mm(np, a.reshape(n, 2), False)
