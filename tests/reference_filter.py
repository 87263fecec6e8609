"""A numpy reference of the paper's particle filter (§4.1), for the tests of the compiled kernels.

The simulation core runs the filter in compiled kernels (electroloc_gym.kernels.filter); these are
the plain numpy expressions those kernels must reproduce bit for bit (weights normalised in the log
domain, systematic resampling by ``searchsorted``, table-drawn jitter, the clip to the box, weighted
statistics, the observation's histogram). Test code only: the package has one implementation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels import exp_f32, mean_cov_rows, row_sums
from electroloc_gym.kernels.streams import normal_table, table_normal_indices, uniform_in_box


def table_standard_normal(rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.float32]:
    """Standard normals (float32) of ``shape`` from the quantile table: the kernels' jitter draws."""
    n = int(np.prod(shape))
    return normal_table()[table_normal_indices(rng, n)].reshape(shape)


def shifted_exp_weights(log_w: NDArray) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """``exp(log_w − max)`` over the last axis (float64; weights 1 for a cloud whose log-weights are all
    −inf) and a per-cloud "degenerate" flag: :func:`normalise_log_weights` before its division.

    Float32 log-weights (those of the float32 sensor models) are exponentiated in float32 by the
    compiled :func:`electroloc_gym.kernels.exp32` (within 1 ulp, ≈3× numpy's ``exp`` here; a relative
    error of 1e-7 on a weight is far below systematic resampling's resolution of 1/M), then
    everything is float64. The native vector env fuses the same operations into one kernel, and
    numpy's SIMD ``exp`` differs between CPUs, so a compiled one is what keeps the two envs identical.
    Float64 log-weights use numpy's ``exp``.

    Raises:
        ValueError: any log-weight is NaN.
    """
    if np.isnan(log_w).any():
        raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
    m = np.max(log_w, axis=-1, keepdims=True)
    degenerate = ~np.isfinite(m[..., 0])
    m = np.where(np.isfinite(m), m, 0.0).astype(log_w.dtype)
    d = log_w - m
    if d.dtype == np.float32:
        e = np.empty_like(d)  # not in place: the compiled loop only vectorises without overlap
        exp_f32(d.reshape(-1), e.reshape(-1))
    else:
        e = np.exp(d)
    w = e.astype(np.float64)
    return np.where(degenerate[..., None], 1.0, w), degenerate


def weight_sums(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sums (...,) of float64 weights (..., M) over the last axis, in a fixed order
    (:func:`electroloc_gym.kernels.row_sums`: the same bits alone or batched, on every machine).
    """
    flat = np.ascontiguousarray(w, dtype=np.float64).reshape(-1, w.shape[-1])
    out = np.empty(flat.shape[0])
    row_sums(flat, out)
    return out.reshape(w.shape[:-1])


def normalise_log_weights(log_w: NDArray) -> tuple[NDArray, NDArray[np.bool_]]:
    """Normalised weights from log-weights over the last axis, and a per-cloud "degenerate" flag.

    A cloud whose log-weights are all −inf gets uniform weights and ``degenerate=True``.

    Raises:
        ValueError: any log-weight is NaN.
    """
    w, degenerate = shifted_exp_weights(log_w)
    w /= weight_sums(w)[..., None]
    return w, degenerate


def systematic_resample(weights: NDArray, rng: np.random.Generator) -> NDArray[np.intp]:
    """Indices (..., M) of a systematic resampling of each cloud's weights (..., M).

    One uniform draw per cloud; batched clouds are resampled with a single ``searchsorted`` by
    offsetting each row's cumulative sum by its row number.
    """
    batch = weights.shape[:-1]
    m = weights.shape[-1]
    cum = np.cumsum(weights, axis=-1)
    cum /= cum[..., -1:]
    u = (rng.random(batch + (1,)) + np.arange(m)) / m
    if not batch:
        return np.minimum(np.searchsorted(cum, u, side="right"), m - 1)
    rows = np.arange(int(np.prod(batch))).reshape(batch + (1,))
    idx = np.searchsorted((cum + rows).ravel(), (u + rows).ravel(), side="right").reshape(batch + (m,))
    idx -= rows * m
    return np.clip(idx, 0, m - 1)


def weighted_mean_cov(particles: NDArray, weights: NDArray | None = None) -> tuple[NDArray, NDArray]:
    """Weighted mean (..., 2) and covariance (..., 2, 2) of particle clouds (..., M, 2).

    Uses the population (biased) covariance, as a filter's spread should (``Σ wᵢ (xᵢ − μ)(xᵢ − μ)ᵀ``).
    Without weights the sums are sequential float64 sums in particle order (a compiled kernel,
    :func:`electroloc_gym.kernels.mean_cov_rows`), so one cloud gives the same bits whether it is
    passed alone or in a batch, in any memory layout — the native vector env relies on it.
    """
    if weights is None:
        p = np.asarray(particles)
        if p.dtype not in (np.float32, np.float64):
            p = p.astype(np.float64)
        batch, m = p.shape[:-2], p.shape[-2]
        flat = p.reshape((-1, m, 2))
        mean = np.empty((flat.shape[0], 2))
        cov = np.empty((flat.shape[0], 2, 2))
        mean_cov_rows(flat[..., 0], flat[..., 1], mean, cov)
        return mean.reshape(batch + (2,)), cov.reshape(batch + (2, 2))
    x = np.asarray(particles, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    mean = np.einsum("...m,...mi->...i", w, x)
    d = x - mean[..., None, :]
    cov = np.einsum("...m,...mi,...mj->...ij", w, d, d)
    return mean, cov


def spread_from_cov(cov: NDArray) -> NDArray:
    """√trace Σ (mm), the paper's success measure (§5.4)."""
    return np.sqrt(np.maximum(cov[..., 0, 0] + cov[..., 1, 1], 0.0))


class ParticleBelief:
    """A particle cloud over 2-D positions (mm) inside a box.

    Args:
        n_particles: number of particles M (> 0). Paper: 2500.
        low_mm: lower corner (x, y) of the box, mm.
        high_mm: upper corner (x, y) of the box, mm.
        jitter_std_mm: standard deviation of the post-resampling jitter per axis, mm (paper: 1 mm).
        dtype: particle dtype; float32 halves the cost of the sensor-model evaluation.
    """

    def __init__(
        self,
        n_particles: int,
        low_mm: ArrayLike,
        high_mm: ArrayLike,
        jitter_std_mm: float = 1.0,
        dtype: type = np.float64,
    ) -> None:
        if isinstance(n_particles, bool) or not isinstance(n_particles, (int, np.integer)) or n_particles <= 0:
            raise ValueError(f"n_particles must be a positive integer, got {n_particles!r}")
        low = np.asarray(low_mm, dtype=float).reshape(2)
        high = np.asarray(high_mm, dtype=float).reshape(2)
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(high > low)):
            raise ValueError(f"box must satisfy low_mm < high_mm (finite), got {low} and {high}")
        if not (np.isfinite(jitter_std_mm) and jitter_std_mm >= 0):
            raise ValueError(f"jitter_std_mm must be ≥ 0, got {jitter_std_mm!r}")
        self.n_particles = int(n_particles)
        self.low_mm = low
        self.high_mm = high
        self.jitter_std_mm = float(jitter_std_mm)
        self.dtype = np.dtype(dtype)
        self._particles = np.zeros((self.n_particles, 2), dtype=self.dtype)
        self._weights = np.full(self.n_particles, 1.0 / self.n_particles)
        self._uniform = True  # weights known to be uniform: skip them in the statistics
        self.last_update_degenerate = False
        self._stats: tuple[NDArray, NDArray] | None = None

    # ---- state ----------------------------------------------------------------------------
    @property
    def particles(self) -> NDArray:
        """Particle positions (M, 2), mm (read-only view)."""
        v = self._particles.view()
        v.flags.writeable = False
        return v

    @property
    def weights(self) -> NDArray:
        """Normalised weights (M,) (read-only view); uniform right after resampling."""
        v = self._weights.view()
        v.flags.writeable = False
        return v

    @property
    def uniform_weights(self) -> bool:
        """True when the weights are uniform (after every resampling; :attr:`weights` is then 1/M)."""
        return self._uniform

    def set_state(self, particles: ArrayLike, weights: ArrayLike | None = None) -> None:
        """Replace the cloud (e.g. to restore a snapshot)."""
        p = np.asarray(particles, dtype=self.dtype)
        if p.shape != (self.n_particles, 2):
            raise ValueError(f"particles must have shape ({self.n_particles}, 2), got {p.shape}")
        self._particles = p.copy()
        self._uniform = weights is None
        self._weights = (
            np.full(self.n_particles, 1.0 / self.n_particles)
            if weights is None
            else np.asarray(weights, dtype=float).copy()
        )
        self._stats = None

    # ---- filter steps ---------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> None:
        """Uniform particles over the box, uniform weights."""
        self._particles = uniform_in_box(rng, self.low_mm, self.high_mm, self.n_particles).astype(self.dtype)
        self._weights = np.full(self.n_particles, 1.0 / self.n_particles)
        self._uniform = True
        self._stats = None

    def predict(self, move_mm: ArrayLike) -> None:
        """Deterministic motion: shift every particle by ``move_mm`` (2,) and keep it in the box."""
        self._particles += np.asarray(move_mm, dtype=self.dtype)
        self._clip_to_box()
        self._stats = None

    def update(self, log_likelihood: ArrayLike) -> NDArray:
        """Multiply the weights by ``exp(log_likelihood)`` (M,) and normalise; returns the weights."""
        ll = np.asarray(log_likelihood)
        if ll.dtype not in (np.float32, np.float64):
            ll = ll.astype(np.float64)
        if ll.shape != (self.n_particles,):
            raise ValueError(f"log_likelihood must have shape ({self.n_particles},), got {ll.shape}")
        if self._uniform:
            log_w = ll  # uniform prior weights add a constant, which normalisation removes
        else:
            with np.errstate(divide="ignore"):
                log_w = np.log(self._weights) + ll
        w, degenerate = normalise_log_weights(log_w)
        self.last_update_degenerate = bool(degenerate)
        self._weights = w
        self._uniform = False
        self._stats = None
        return self.weights

    def resample(self, rng: np.random.Generator) -> None:
        """Systematic importance resampling; weights become uniform."""
        idx = systematic_resample(self._weights, rng)
        self._particles = self._particles[idx]
        self._weights = np.full(self.n_particles, 1.0 / self.n_particles)
        self._uniform = True
        self._stats = None

    def jitter(self, rng: np.random.Generator) -> None:
        """Add N(0, jitter_std_mm²) per axis and keep the particles inside the box."""
        if self.jitter_std_mm > 0:
            noise = table_standard_normal(rng, self._particles.shape).astype(self.dtype)
            noise *= self.dtype.type(self.jitter_std_mm)
            self._particles += noise
            self._clip_to_box()
        self._stats = None

    def _clip_to_box(self) -> None:
        # np.minimum/np.maximum with out= avoid np.clip's per-call overhead (hot path).
        np.maximum(self._particles, self.low_mm.astype(self.dtype), out=self._particles)
        np.minimum(self._particles, self.high_mm.astype(self.dtype), out=self._particles)

    def assimilate(self, log_likelihood: ArrayLike, rng: np.random.Generator) -> None:
        """One measurement update as in the paper: weight, resample, jitter."""
        self.update(log_likelihood)
        self.resample(rng)
        self.jitter(rng)

    # ---- summaries -----------------------------------------------------------------------
    def _mean_cov(self) -> tuple[NDArray, NDArray]:
        if self._stats is None:
            self._stats = weighted_mean_cov(self._particles, None if self._uniform else self._weights)
        return self._stats

    def mean(self) -> NDArray[np.float64]:
        """Estimate: weighted particle mean (2,), mm."""
        return self._mean_cov()[0].copy()

    def covariance(self) -> NDArray[np.float64]:
        """Weighted covariance Σ (2, 2), mm²."""
        return self._mean_cov()[1].copy()

    def spread(self) -> float:
        """√trace Σ, mm."""
        return float(spread_from_cov(self._mean_cov()[1]))


def egocentric_histogram(particles_mm: NDArray, weights: NDArray | None, carriage: NDArray, hw: NDArray) -> NDArray:
    """Mass fraction of particles in an 8×8 grid of offsets ±H around the carriage, (..., 64).

    Without weights each particle counts 1/M.
    """
    p = np.asarray(particles_mm)
    if p.dtype not in (np.float32, np.float64):
        p = p.astype(np.float64)
    m = p.shape[-2]
    batch = p.shape[:-2]
    nb = 8 * 8
    if weights is None:
        return egocentric_histogram(p, np.ones(batch + (m,)), carriage, hw) / m
    rel = (p - carriage[..., None, :].astype(p.dtype)) / (2 * hw[..., None, None]).astype(p.dtype) + 0.5
    ij = np.clip((rel * 8).astype(np.intp), 0, 8 - 1)
    cell = ij[..., 0] * 8 + ij[..., 1]
    n_clouds = int(np.prod(batch)) if batch else 1
    flat_cells = (cell.reshape(n_clouds, m) + nb * np.arange(n_clouds)[:, None]).ravel()
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    return np.bincount(flat_cells, weights=w, minlength=n_clouds * nb).reshape(batch + (nb,))
