"""The package's argument checks: one clear ValueError naming the argument and the allowed range.

Every parameter dataclass and agent option checks its numbers here, so a bad value reads the same wherever
it is given: ``radius_mm must be a finite number > 0, got -1.0``. Booleans are refused where a number is
asked for (``True`` is an ``int`` to Python); numpy scalars are accepted. It imports nothing of the package.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "check_int",
    "check_float",
    "check_bool",
    "check_choice",
    "check_options",
    "check_seeds",
    "check_prediction_args",
]


def _is_int(value: Any) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def check_int(name: str, value: Any, low: int, high: int | None = None) -> int:
    """``value`` as an int in [low, high] (or ≥ low), else a ValueError naming ``name`` and the range."""
    if not _is_int(value) or value < low or (high is not None and value > high):
        rng = f"in [{low}, {high}]" if high is not None else f"≥ {low}"
        raise ValueError(f"{name} must be an integer {rng}, got {value!r}")
    return int(value)


def check_float(
    name: str, value: Any, low: float | None = None, *, inclusive: bool = False, high: float | None = None
) -> float:
    """A finite real ``value`` above ``low`` (at or above it when ``inclusive``) and at most ``high``, as a
    float; else a ValueError naming ``name`` and the range. ``low=None``: no lower bound.
    """
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if (
        not ok
        or not math.isfinite(value)
        or (low is not None and (value < low or (value == low and not inclusive)))
        or (high is not None and value > high)
    ):
        parts = [] if low is None else [f"{'≥' if inclusive else '>'} {low:g}"]
        parts += [] if high is None else [f"≤ {high:g}"]
        rng = (" " + " and ".join(parts)) if parts else ""
        raise ValueError(f"{name} must be a finite number{rng}, got {value!r}")
    return float(value)


def check_bool(name: str, value: Any) -> bool:
    """``value`` if it is a real boolean (``True``/``False`` or a numpy bool), else a ValueError."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def check_choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` if it is one of the strings ``choices``, else a ValueError listing them."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")
    return value


def check_options(name: str, value: Any, allowed: Sequence[str]) -> dict[str, Any]:
    """``value`` as a dict: None (no options) or a mapping whose keys are among ``allowed``; else one
    ValueError naming ``name`` and the allowed keys (a reset's ``options``).
    """
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{name} must be None or a dict with keys among {list(allowed)}, got {value!r}")
    unknown = [k for k in value if k not in allowed]
    if unknown:
        raise ValueError(f"{name} has unknown key(s) {unknown}; allowed: {list(allowed)}")
    return dict(value)


def _is_seed(value: Any) -> bool:
    return _is_int(value) and bool(value >= 0)


def check_seeds(seed: Any, n: int) -> None:
    """A vector env's ``reset`` ``seed``: None, an integer ≥ 0, or a sequence (or 1-d array) of ``n``
    entries each None or an integer ≥ 0; anything else is one ValueError naming it.
    """
    if seed is None or _is_seed(seed):
        return
    what = f"seed must be None, an integer ≥ 0 or a sequence of {n} seeds (each None or an integer ≥ 0)"
    if (
        isinstance(seed, (str, bytes, Mapping))
        or not isinstance(seed, (Sequence, np.ndarray))
        or (isinstance(seed, np.ndarray) and seed.ndim != 1)
    ):
        raise ValueError(f"{what}, got {seed!r}")
    seq = cast("Sequence[Any] | NDArray[Any]", seed)
    if len(seq) != n:
        raise ValueError(f"{what}, got {len(seq)} seeds")
    bad = [s for s in seq if not (s is None or _is_seed(s))]
    if bad:
        raise ValueError(f"{what}, got {list(seq)!r} (bad: {bad!r})")


def check_prediction_args(
    particles_mm: Any, moves_mm: Any, particle_dims: int, max_step_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """The arguments of the envs' ``predicted_*`` accessors: (M, ``particle_dims``) hypotheses (float32 kept,
    other dtypes as float64) and (2,) or (C, 2) moves, clipped to ±``max_step_mm`` as a step clips them
    (float64); else one ValueError naming the argument.
    """
    p = _real_array("particles_mm", particles_mm, f"(M, {particle_dims})", 2, particle_dims)
    if p.dtype not in (np.float32, np.float64):
        p = p.astype(np.float64)
    u = _real_array("moves_mm", moves_mm, "(2,) or (C, 2)", 1, 2).astype(np.float64)
    return p, np.clip(u, -max_step_mm, max_step_mm)


def _real_array(name: str, value: Any, shape: str, min_ndim: int, last: int) -> np.ndarray:
    """``value`` as a finite numpy array of real numbers of ``shape`` (``min_ndim`` to 2 axes, the last of
    ``last`` entries), else one ValueError naming ``name``.
    """
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        arr = None
    if arr is None or arr.dtype.kind not in "iuf":
        kind = "no array" if arr is None else f"dtype {arr.dtype}"
        shown = " ".join(repr(value).split())
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise ValueError(f"{name} must be a real number array of shape {shape}, got {kind}: {shown}")
    if not min_ndim <= arr.ndim <= 2 or arr.shape[-1] != last:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr
