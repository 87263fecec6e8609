"""The reset contract: which options an env's ``reset`` takes, and that a full reset comes first.

One check, with one message per case, for every env class of both engines:

* **A single env** (``gym.make``, :class:`~electroloc_gym.envs.adapter.CoreEnv` and every env of the table)
  takes no reset options (:data:`SINGLE_RESET_OPTIONS`): ``options`` is ``None`` or an empty dict — what
  Gymnasium's ``SyncVectorEnv``/``AsyncVectorEnv`` hand their sub-envs once they have taken ``reset_mask``
  for themselves. Any key is one ``ValueError`` naming ``options`` and the allowed keys (none).
* **A vector env** (the numba engine's :class:`~electroloc_gym.envs.vector.CoreVectorEnv` and its per-id
  classes, the torch engine's :class:`~electroloc_gym.envs.torch_vector.TorchElectroLocVectorEnv`) takes
  :data:`VECTOR_RESET_OPTIONS`: ``reset_mask``, a bool (N,) array with a True entry (the torch engine: or a
  bool tensor), the sub-envs to reset. Anything else — not a dict, an unknown key such as the typo
  ``"resetmask"`` (which would otherwise reset every sub-env), a bad mask — is one ``ValueError`` naming
  ``options`` (and the allowed keys) or ``options['reset_mask']``, before any sub-env changes.
* **A full reset first**: a partial reset (a ``reset_mask`` with a False entry) before the env's first full
  reset is one ``ValueError`` naming ``options['reset_mask']`` (:func:`check_first_reset`): the masked-out
  sub-envs would have no episode (no target, no belief), and a step would read them. A mask of all True
  is a full reset.
* **No step before a reset**: every env's ``step`` before its first reset is a ``RuntimeError`` ("call
  reset() before step()"; a single env made by ``gym.make`` refuses it first with Gymnasium's ``ResetNeeded``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from electroloc_gym.utils.checks import check_options

__all__ = [
    "SINGLE_RESET_OPTIONS",
    "VECTOR_RESET_OPTIONS",
    "check_reset_options",
    "reset_mask_error",
    "check_first_reset",
]

#: A single env's reset options: none.
SINGLE_RESET_OPTIONS: tuple[str, ...] = ()
#: A vector env's reset options (both engines).
VECTOR_RESET_OPTIONS: tuple[str, ...] = ("reset_mask",)


def check_reset_options(options: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    """``reset``'s ``options`` as a dict (``{}`` for None), its keys among ``allowed``; else one ValueError
    naming ``options`` and the allowed keys (the module docstring).
    """
    if allowed:
        return check_options("options", options, allowed)
    why = "a single env's reset takes no options; reset_mask is a vector env's"
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"options must be None or an empty dict ({why}), got {options!r}")
    if options:
        raise ValueError(f"options has unknown key(s) {list(options)}; allowed: none ({why})")  # pyright: ignore[reportUnknownArgumentType]  # a Mapping of anything: its keys listed as given
    return {}


def reset_mask_error(num_envs: int) -> str:
    """The message of a bad ``options['reset_mask']`` for ``num_envs`` sub-envs (both engines)."""
    return f"options['reset_mask'] must be a bool array of shape ({num_envs},) with a True entry"


def check_first_reset(started: bool, partial: bool) -> None:
    """A partial reset (``partial``: the mask has a False entry) before the first full reset (``started``
    False) is one ValueError naming ``options['reset_mask']``.
    """
    if partial and not started:
        raise ValueError(
            "options['reset_mask'] resets only some sub-envs, and it cannot come before the first full reset: "
            "call reset() without options['reset_mask'] first (every sub-env must have begun an episode)"
        )
