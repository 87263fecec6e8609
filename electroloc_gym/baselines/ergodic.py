"""ergodic: the expected information density and the spectral-multiscale-coverage machinery behind ``eedi``.

**Ergodicity** (Mathew & Mezić, "Metrics for ergodicity and design of ergodic dynamics for multi-agent
systems", Physica D 240(4–5), 432–442, 2011). On the rectangle ``[low, high]`` (sides L₁, L₂, mm) the
cosine basis

    F_k(x) = (1/h_k) Π_i cos(k_i π (x_i − low_i)/L_i),   k ∈ {0, …, K−1}²,

with ``h_k`` making ``∫F_k² dx = 1``, has zero normal derivative on the walls. A density φ has
coefficients ``φ_k = ∫ φ F_k dx``; a trajectory x_1 … x_T has ``c_k = (1/T) Σ_t F_k(x_t)`` (its time
average: here the carriage positions where readings were taken). The ergodic metric is the Sobolev
norm of negative index ``s = (n + 1)/2 = 1.5`` (n = 2 dimensions) of their difference,

    ℰ = Σ_k Λ_k (c_k − φ_k)²,   Λ_k = (1 + |k|²)^(−s)   (k the integer index vector),

which goes to 0 exactly when the time average of every function converges to its spatial average
under φ. Mathew & Mezić's feedback law for first-order dynamics ``ẋ = u``, ``|u| ≤ u_max`` (spectral
multiscale coverage, SMC) moves along ``−B``,

    B = Σ_k Λ_k S_k ∇F_k(x_T),   S_k = T (c_k − φ_k) = Σ_t (F_k(x_t) − φ_k),

the direction in which ``d/dt Σ Λ_k S_k²`` is most negative; the metric then decays like 1/T.

**Expected information density** (Miller, Silverman, MacIver & Murphey, "Ergodic Exploration of
Distributed Information", IEEE T-RO 32(1), 36–52, 2016). The reading's mean μ(θ; q) and std σ(θ; q) for
a target at θ and the carriage at q give each hypothesis θ_s the Fisher information about the target's
position ``I_s(q) = ∇_θμ ∇_θμᵀ / σ²`` (2 × 2; the Gaussian reading's mean term). Averaged over the
belief, ``Ī(q) = (1/S) Σ_s I_s(q)``, and the EID is ``det Ī(q)`` (``criterion="det"``, D-optimality,
as Miller et al.) or ``trace Ī(q)`` (``"trace"``), normalised to integrate to 1 over the workspace. The
average is taken *before* the determinant: a scalar reading gives every single hypothesis a rank-one
I_s, whose determinant is 0 everywhere. The sensor models are functions of the offset θ − q, so
``∇_θμ = −∇_qμ``: the gradient comes from central differences in the carriage position (step
``step_mm``), one batched call of the reading function for all 4·G shifted positions.

The workspace is a grid of G cell centres covering the box (midpoint rule: Σ φ(q_g)·cell area = 1).
Everything is array arithmetic over (grid points × hypotheses × coefficients); no Python loop runs
over particles or grid points. No maintained library offers these pieces for numpy (the ergodic-control
code in public repositories is notebooks and research scripts), so they are written out here.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "CRITERIA",
    "SOBOLEV_INDEX",
    "CosineBasis",
    "workspace_grid",
    "belief_fisher_information",
    "information_density",
]

#: How the belief-averaged Fisher matrix becomes a density: determinant (D-optimal, Miller et al.) or trace.
CRITERIA = ("det", "trace")
#: s = (n + 1)/2 of the ergodic metric's Sobolev weights for n = 2 dimensions (Mathew & Mezić 2011).
SOBOLEV_INDEX = 1.5


@dataclass(frozen=True)
class CosineBasis:
    """The cosine basis of a rectangle, its coefficients, the ergodic metric and the SMC direction.

    Attributes:
        low_mm: (x, y) lower corner of the workspace, mm.
        high_mm: (x, y) upper corner, mm (> low).
        n_per_axis: K, coefficients per axis (K² in all), 1–64.
        sobolev_index: s of the weights Λ_k = (1 + |k|²)^(−s) (> 0; default 1.5 = (n + 1)/2).
    """

    low_mm: tuple[float, float]
    high_mm: tuple[float, float]
    n_per_axis: int
    sobolev_index: float = SOBOLEV_INDEX

    def __post_init__(self) -> None:
        low = tuple(float(v) for v in np.asarray(self.low_mm, dtype=np.float64).ravel())
        high = tuple(float(v) for v in np.asarray(self.high_mm, dtype=np.float64).ravel())
        if len(low) != 2 or len(high) != 2 or not all(map(math.isfinite, low + high)):
            raise ValueError(f"low_mm and high_mm must be finite (x, y) in mm, got {self.low_mm!r}, {self.high_mm!r}")
        if not (high[0] > low[0] and high[1] > low[1]):
            raise ValueError(f"high_mm must exceed low_mm on both axes, got {low} and {high}")
        n = self.n_per_axis
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 64:
            raise ValueError(f"n_per_axis must be an integer in [1, 64], got {n!r}")
        s = self.sobolev_index
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or s <= 0:
            raise ValueError(f"sobolev_index must be a number > 0, got {s!r}")
        object.__setattr__(self, "low_mm", low)
        object.__setattr__(self, "high_mm", high)
        object.__setattr__(self, "n_per_axis", int(n))
        object.__setattr__(self, "sobolev_index", float(s))

    @functools.cached_property
    def indices(self) -> NDArray[np.int64]:
        """(K², 2) integer index vectors k."""
        k = np.arange(self.n_per_axis)
        return np.stack(np.meshgrid(k, k, indexing="ij"), axis=-1).reshape(-1, 2)

    @functools.cached_property
    def _wavenumbers(self) -> NDArray[np.float64]:
        """(K², 2) k_i π / L_i, 1/mm."""
        side = np.subtract(self.high_mm, self.low_mm)
        return self.indices * (np.pi / side)

    @functools.cached_property
    def _inv_h(self) -> NDArray[np.float64]:
        """(K²,) 1/h_k: ∫ cos²(k π x/L) dx over a side is L (k = 0) or L/2."""
        side = np.subtract(self.high_mm, self.low_mm)
        h2 = np.prod(np.where(self.indices == 0, 1.0, 0.5) * side, axis=1)
        return 1.0 / np.sqrt(h2)

    @functools.cached_property
    def weights(self) -> NDArray[np.float64]:
        """(K²,) Sobolev weights Λ_k = (1 + |k|²)^(−s)."""
        return (1.0 + np.sum(self.indices**2, axis=1)) ** (-self.sobolev_index)

    def values(self, points_mm: ArrayLike) -> NDArray[np.float64]:
        """F_k at ``points_mm`` (..., 2): (..., K²)."""
        u = np.asarray(points_mm, dtype=np.float64) - np.asarray(self.low_mm)
        arg = u[..., None, :] * self._wavenumbers  # (..., K², 2)
        c = np.cos(arg)
        return c[..., 0] * c[..., 1] * self._inv_h

    def gradients(self, points_mm: ArrayLike) -> NDArray[np.float64]:
        """∇F_k at ``points_mm`` (..., 2): (..., K², 2), 1/mm per unit of F."""
        u = np.asarray(points_mm, dtype=np.float64) - np.asarray(self.low_mm)
        arg = u[..., None, :] * self._wavenumbers
        c, s = np.cos(arg), np.sin(arg)
        kw = self._wavenumbers * self._inv_h[:, None]
        gx = -kw[:, 0] * s[..., 0] * c[..., 1]
        gy = -kw[:, 1] * c[..., 0] * s[..., 1]
        return np.stack([gx, gy], axis=-1)

    def density_coefficients(self, density: ArrayLike, points_mm: ArrayLike, cell_area_mm2: float) -> NDArray:
        """φ_k = ∫ φ F_k dx by the midpoint rule: ``density`` (G,) at cell centres ``points_mm`` (G, 2)."""
        return np.asarray(density, dtype=np.float64) @ self.values(points_mm) * float(cell_area_mm2)

    def trajectory_coefficients(self, path_mm: ArrayLike) -> NDArray[np.float64]:
        """c_k = (1/T) Σ_t F_k(x_t) of the visited points ``path_mm`` (T, 2), T ≥ 1."""
        return self.values(_path(path_mm)).mean(axis=0)

    def metric(self, path_mm: ArrayLike, phi_k: ArrayLike) -> float:
        """The ergodic metric ℰ = Σ_k Λ_k (c_k − φ_k)² of a trajectory against a density's coefficients."""
        d = self.trajectory_coefficients(path_mm) - np.asarray(phi_k, dtype=np.float64)
        return float(self.weights @ (d * d))

    def smc_direction(self, path_mm: ArrayLike, phi_k: ArrayLike) -> NDArray[np.float64]:
        """B = Σ_k Λ_k S_k ∇F_k(x_T), S_k = Σ_t (F_k(x_t) − φ_k): the SMC law moves along −B (2,)."""
        path = _path(path_mm)
        s_k = self.values(path).sum(axis=0) - path.shape[0] * np.asarray(phi_k, dtype=np.float64)
        return (self.weights * s_k) @ self.gradients(path[-1])


def _path(path_mm: ArrayLike) -> NDArray[np.float64]:
    p = np.asarray(path_mm, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 1:
        raise ValueError(f"path_mm must have shape (T, 2) with T ≥ 1, got {p.shape}")
    return p


def workspace_grid(low_mm: ArrayLike, high_mm: ArrayLike, pitch_mm: float) -> tuple[NDArray[np.float64], float]:
    """Cell centres (G, 2) covering the box ``[low, high]`` with cells of at most ``pitch_mm`` per side,
    and the cell area (mm²): n_i = ⌈L_i / pitch⌉ equal cells per axis.
    """
    if isinstance(pitch_mm, bool) or not isinstance(pitch_mm, (int, float)) or not 0 < pitch_mm < math.inf:
        raise ValueError(f"pitch_mm must be a number of mm > 0, got {pitch_mm!r}")
    low = np.asarray(low_mm, dtype=np.float64)
    high = np.asarray(high_mm, dtype=np.float64)
    side = high - low
    n = np.maximum(np.ceil(side / pitch_mm - 1e-9).astype(int), 1)
    cell = side / n
    axes = [low[i] + cell[i] * (np.arange(n[i]) + 0.5) for i in range(2)]
    gx, gy = np.meshgrid(*axes, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel()], axis=-1), float(cell[0] * cell[1])


def belief_fisher_information(
    reading_fn: Callable[[NDArray], tuple[NDArray, NDArray]], carriages_mm: ArrayLike, step_mm: float = 1.0
) -> NDArray[np.float64]:
    """Ī(q) (G, 2, 2): the Fisher information about the target's position, averaged over the hypotheses.

    Args:
        reading_fn: carriage positions (N, 2), mm → (mean_V, std_V), each (N, S): every hypothesis' reading
            from each position (S hypotheses drawn from the belief, equally weighted).
        carriages_mm: (G, 2) positions q, mm.
        step_mm: central-difference step, mm (> 0).

    Returns:
        (G, 2, 2) Ī(q) = (1/S) Σ_s ∇μ_s ∇μ_sᵀ / σ_s², 1/mm² (σ: the mean of the four shifted stds).
    """
    if isinstance(step_mm, bool) or not isinstance(step_mm, (int, float)) or not 0 < step_mm < math.inf:
        raise ValueError(f"step_mm must be a number of mm > 0, got {step_mm!r}")
    q = np.asarray(carriages_mm, dtype=np.float64)
    g = q.shape[0]
    e = np.array([[step_mm, 0.0], [-step_mm, 0.0], [0.0, step_mm], [0.0, -step_mm]])
    shifted = (q[None, :, :] + e[:, None, :]).reshape(4 * g, 2)
    mean, std = (np.asarray(a, dtype=np.float64).reshape(4, g, -1) for a in reading_fn(shifted))
    gx = (mean[0] - mean[1]) / (2.0 * step_mm)  # (G, S), V/mm
    gy = (mean[2] - mean[3]) / (2.0 * step_mm)
    inv_var = 1.0 / std.mean(axis=0) ** 2
    out = np.empty((g, 2, 2))
    out[:, 0, 0] = (gx * gx * inv_var).mean(axis=1)
    out[:, 1, 1] = (gy * gy * inv_var).mean(axis=1)
    out[:, 0, 1] = out[:, 1, 0] = (gx * gy * inv_var).mean(axis=1)
    return out


def information_density(fisher: ArrayLike, cell_area_mm2: float, criterion: str = "det") -> NDArray[np.float64]:
    """The EID (G,), 1/mm², from Ī (G, 2, 2): det or trace, normalised so Σ φ·cell area = 1.

    A workspace with no information anywhere (all zero) gets the uniform density.
    """
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {list(CRITERIA)}, got {criterion!r}")
    f = np.asarray(fisher, dtype=np.float64)
    if criterion == "det":
        raw = np.maximum(f[:, 0, 0] * f[:, 1, 1] - f[:, 0, 1] * f[:, 1, 0], 0.0)
    else:
        raw = f[:, 0, 0] + f[:, 1, 1]
    total = raw.sum() * cell_area_mm2
    if not total > 0 or not math.isfinite(total):
        return np.full(raw.shape, 1.0 / (raw.size * cell_area_mm2))
    return raw / total
