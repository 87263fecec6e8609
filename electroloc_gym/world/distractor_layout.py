"""Where distractors go when rejection sampling gives up: the column construction (geometry only, mm).

:func:`column_layout` gives the most centres in the ±h box, pairwise ≥ S apart and ≥ T from a target, that
a family of column positions (and its transpose, rows) holds: columns at least S apart never conflict, and
in one column the greedy bottom-up sweep places the most centres spaced ≥ S that avoid the interval the
target's disc cuts from it (the 1-D interval argument). :func:`least_capacity` bounds it over a box of
targets, from a grid with the disc grown by the grid's half-diagonal (a layout valid for the grown disc
is valid for every target within the margin, and the count is monotone in the blocked set). No packing
library solves this per-target bound, so it is written here; :mod:`electroloc_gym.world.distractors` uses it.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["EDGE_MM", "MAX_COLUMN_SETS", "column_layout", "least_capacity"]

#: Column positions tried per column (shifts 0, slack/8, …, slack of the slack the box leaves).
_SHIFT_LEVELS = 8
#: The most column sets tried: with more columns than that family allows (small objects in a large box) every
#: column takes the same shift, which keeps the construction valid and its cost linear in the columns.
MAX_COLUMN_SETS = 250_000
#: Margin added to every clearance, mm: keeps a centre exactly on an edge clear under rounding.
EDGE_MM = 1e-9


def _column_counts(
    h: float, spacing: float, clearance: float, dx: NDArray[np.float64], ty: NDArray[np.float64] | np.float64
) -> NDArray[np.int64]:
    """Most centres spaced ≥ ``spacing`` in [−h, h] along a column ``dx`` from the target (target at height
    ``ty``), avoiding the open interval the target's disc of radius ``clearance`` cuts from it: the greedy
    bottom-up sweep (closed form; broadcasts over ``dx`` and ``ty``).
    """
    w = np.sqrt(np.maximum(clearance * clearance - dx * dx, 0.0))
    blocked = np.abs(dx) < clearance
    lo, hi = ty - w, ty + w
    free = np.floor(2.0 * h / spacing) + 1.0
    below = np.where(lo >= -h, np.floor((lo + h) / spacing) + 1.0, 0.0)
    nxt = np.maximum(hi, -h + below * spacing)
    above = np.where(nxt <= h, np.floor((h - nxt) / spacing) + 1.0, 0.0)
    return np.where(blocked, np.minimum(below + above, free), free).astype(np.int64)


def _every_rising_set(k: int) -> bool:
    """Whether the family of ``k`` columns is every non-decreasing sequence of shift levels (else: one
    shared shift, :data:`MAX_COLUMN_SETS`).
    """
    return math.comb(k + _SHIFT_LEVELS, _SHIFT_LEVELS) <= MAX_COLUMN_SETS


def _best_family_totals(counts: NDArray[np.int64], k: int) -> NDArray[np.int64]:
    """The most centres any column set of the family holds, per row of ``counts`` (rows, k·(levels+1)): the
    count of column j at shift level l in entry j·(levels+1) + l, as :func:`_columns` lays them out.

    Every non-decreasing sequence of levels is one dynamic programme over the columns (the best total of
    columns 0…j ending at level l is column j's count plus the best ending at a level ≤ l), so the bound
    over a grid of targets costs k·levels per target instead of a sum over every set; one shared shift is
    the best level's column sum.
    """
    c = counts.reshape(counts.shape[0], k, _SHIFT_LEVELS + 1)
    if not _every_rising_set(k):
        return c.sum(axis=1).max(axis=1)
    best = c[:, 0]
    for j in range(1, k):
        best = c[:, j] + np.maximum.accumulate(best, axis=1)
    return best.max(axis=1)


@functools.cache
def _columns(h: float, spacing: float) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The candidate column positions (u,) and the family of column sets as indices into them (F, k)."""
    k = int(math.floor(2.0 * h / spacing + 1e-12)) + 1
    slack = max(2.0 * h - (k - 1) * spacing, 0.0)
    shifts = np.linspace(0.0, slack, _SHIFT_LEVELS + 1)
    if _every_rising_set(k):
        combos = np.array(list(itertools.combinations_with_replacement(range(_SHIFT_LEVELS + 1), k)), dtype=np.intp)
    else:
        combos = np.repeat(np.arange(_SHIFT_LEVELS + 1, dtype=np.intp)[:, None], k, axis=1)
    xs = (-h + np.arange(k) * spacing)[:, None] + shifts[None, :]  # (k, levels+1)
    index = np.arange(k) * (_SHIFT_LEVELS + 1) + combos  # (F, k) into xs.ravel()
    return np.minimum(xs.ravel(), h), index


def column_layout(h: float, spacing: float, clearance: float, tx: float, ty: float) -> list[tuple[float, float]]:
    """The most centres (x, y) in the ±``h`` mm box, pairwise ≥ ``spacing`` apart and ≥ ``clearance`` from
    the target at (``tx``, ``ty``), that the column family (and its transpose, rows) holds (module
    docstring); the first best set in a fixed order, so the same target gives the same centres.
    """
    xs, index = _columns(h, spacing)
    best: tuple[int, int, bool] = (-1, 0, False)
    for transpose, (px, py) in ((False, (tx, ty)), (True, (ty, tx))):
        totals = _column_counts(h, spacing, clearance, xs - px, np.float64(py))[index].sum(axis=1)
        f = int(np.argmax(totals))
        if totals[f] > best[0]:
            best = (int(totals[f]), f, transpose)
    _, f, transpose = best
    px, py = (ty, tx) if transpose else (tx, ty)
    out = []
    for x in xs[index[f]].tolist():
        dx = x - px
        lo = hi = None
        if abs(dx) < clearance:
            w = math.sqrt(clearance * clearance - dx * dx)
            lo, hi = py - w, py + w
        y = -h
        while y <= h:
            if lo is not None and hi is not None and lo < y < hi:
                y = hi
                continue
            out.append((y, x) if transpose else (x, y))
            y += spacing
    return out


@functools.cache
def least_capacity(h: float, spacing: float, clearance: float, half_width: float, grid_mm: float = 0.5) -> int:
    """The fewest centres :func:`column_layout` places for any target in ±``half_width`` mm: the least over a
    grid of step ``grid_mm`` with the disc grown by the half-diagonal (module docstring).
    """
    margin = grid_mm / math.sqrt(2.0)
    g = np.linspace(-half_width, half_width, int(math.ceil(2.0 * half_width / grid_mm)) + 1)
    xs, index = _columns(h, spacing)
    k = index.shape[1]
    least = None
    col = np.reshape(g, (-1, 1))
    for ty in g.tolist():  # one row of the grid of targets at a time
        by_columns = _column_counts(h, spacing, clearance + margin, xs[None, :] - col, np.float64(ty))
        by_rows = _column_counts(h, spacing, clearance + margin, xs[None, :] - ty, col)  # the transpose
        best = np.maximum(_best_family_totals(by_columns, k), _best_family_totals(by_rows, k))
        least = int(best.min()) if least is None else min(least, int(best.min()))
    if least is None:
        raise ValueError(f"no grid of targets in ±{half_width!r} mm (half_width must be ≥ 0)")
    return int(least)
