"""Fusing the K readings of a sensor array into a belief: all at once, or one reading at a time (paper §7).

Bayes' rule commutes: with independent noises, ``p(x | Φ_1..Φ_K) ∝ p(x) Π_k p(Φ_k | x)`` whatever the order
and grouping of the updates, so "K readings fused at once" and "the same readings fused one by one" give the
same posterior. Two forms:

* :func:`grid_posterior`: the exact posterior on a grid of hypotheses (float64), either as one product or as
  K successive normalised updates — equal up to rounding.
* :func:`assimilate_readings`: the particle filter's update (:func:`~electroloc_gym.kernels.loglik_assimilate`:
  shifted float32 weights, systematic resampling, jitter N(0, 1 mm²) per axis, the clip to the box) applied
  once to the summed log-likelihood, or K times, once per reading. The resampling and the jitter make the two
  differ per seed; experiments/array/commutativity.py compares their distributions.

The sum over pairs needs no compiled loop: elementwise additions in pair order (:func:`sum_over_pairs`) are
IEEE-exact and CPU-independent, and each update is the existing kernel. One compiled loop is here,
:func:`general_pair_difference`: Eq. 4 and Eq. 7 for a pair of electrodes anywhere in the field of any two
emitters, in one elementwise pass (the general counterpart of the paper's pair's fast path in
:mod:`electroloc_gym.world.physics`; tested equal to ``physics.emitter_field`` + ``physics.sphere_perturbation``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numba import vectorize
from numpy.typing import NDArray

from electroloc_gym.kernels.filter import loglik_assimilate
from electroloc_gym.kernels.streams import normal_table, table_normal_indices
from electroloc_gym.protocol import HIST_BINS

__all__ = ["sum_over_pairs", "grid_posterior", "assimilate_readings", "general_pair_difference"]


@vectorize(["float64(" + ", ".join(["float64"] * 13) + ")"], cache=True)
def general_pair_difference(x, y, depth, strength, k, px, py, nx, ny, ax, ay, bx, by):  # pragma: no cover - compiled
    """``strength · E_f(c)·[(a − c)/|a − c|³ − (b − c)/|b − c|³]`` (V) for a sphere centre c = (x, y, −depth) (mm),
    the emitters ±k (V·mm, = V_e·E) at (px, py, 0) and (nx, ny, 0), the electrodes a = (ax, ay, 0) and
    b = (bx, by, 0): δV(a) − δV(b) of Eq. 4 in the field of Eq. 7, ``strength`` = χ·a³ (mm³). Exact operations
    only (+ − × ÷, √), float64.
    """
    z2 = depth * depth
    dxp = x - px
    dyp = y - py
    tp = dxp * dxp + dyp * dyp + z2
    rp = np.sqrt(tp)
    ip = 1.0 / (rp * rp * rp)
    dxn = x - nx
    dyn = y - ny
    tn = dxn * dxn + dyn * dyn + z2
    rn = np.sqrt(tn)
    inn = 1.0 / (rn * rn * rn)
    ex = k * (dxp * ip - dxn * inn)
    ey = k * (dyp * ip - dyn * inn)
    ez = k * ((-depth) * ip - (-depth) * inn)
    dax = ax - x
    day = ay - y
    ta = dax * dax + day * day + z2
    dbx = bx - x
    dby = by - y
    tb = dbx * dbx + dby * dby + z2
    dot_a = ex * dax + ey * day + ez * depth
    dot_b = ex * dbx + ey * dby + ez * depth
    return strength * (dot_a / (ta * np.sqrt(ta)) - dot_b / (tb * np.sqrt(tb)))


def sum_over_pairs(terms: Sequence[NDArray]) -> NDArray:
    """Σ_k terms[k] in pair order, elementwise (the first term itself, unchanged, when K = 1)."""
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    return total


def grid_posterior(
    log_likelihoods: NDArray, *, at_once: bool, order: Sequence[int] | None = None, log_prior: NDArray | None = None
) -> NDArray[np.float64]:
    """The normalised posterior (G,) on a grid of G hypotheses from K readings' log-likelihoods (K, G).

    Args:
        log_likelihoods: (K, G) log p(Φ_k | x_g), up to a constant per reading.
        at_once: True: one update with the summed log-likelihood; False: K normalised updates in ``order``.
        order: the readings' order for the one-by-one updates (default 0..K−1).
        log_prior: (G,) log prior (default uniform).
    """
    ll = np.asarray(log_likelihoods, dtype=np.float64)
    prior = np.zeros(ll.shape[1]) if log_prior is None else np.asarray(log_prior, dtype=np.float64)
    if at_once:
        lp = prior + sum_over_pairs(list(ll))
        p = np.exp(lp - lp.max())
        return p / p.sum()
    p = np.exp(prior - prior.max())
    p /= p.sum()
    for k in range(ll.shape[0]) if order is None else order:
        p = p * np.exp(ll[k] - ll[k].max())
        p /= p.sum()
    return p


def assimilate_readings(
    pair_loglik: Callable[[int, NDArray[np.float32]], NDArray],
    n_pairs: int,
    clouds: NDArray[np.float32],
    half_mm: NDArray,
    generators: Sequence[np.random.Generator],
    *,
    at_once: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fuse K readings into k particle clouds in place; returns the clouds' mean (k, 2) mm and covariance (k, 2, 2) mm².

    Args:
        pair_loglik: ``pair_loglik(j, clouds)`` → (k, M) log-likelihood of reading j at the clouds' particles
            (evaluated on the current clouds: one by one, reading j sees the cloud after readings 0..j−1).
        n_pairs: K.
        clouds: (k, 2, M) float32 particles, coordinate-major, mm (updated in place).
        half_mm: (k,) each cloud's box half-width H (the clip to [−H, H]²), mm.
        generators: one per cloud; every update draws, per cloud, the resampling offset U then the 2·M jitter
            indices (the order of the core's measurement update).
        at_once: True: one update from Σ_j log p(Φ_j | x); False: K updates, reading 0 first.

    Raises:
        ValueError: a NaN log-likelihood.
    """
    k, _, m = clouds.shape
    if len(generators) != k:
        raise ValueError(f"generators must hold one Generator per cloud ({k}), got {len(generators)}")
    table = normal_table()
    half = np.asarray(half_mm, dtype=np.float32).reshape(k)
    origin = np.zeros((k, 2), dtype=np.float32)
    mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
    groups = [list(range(n_pairs))] if at_once else [[j] for j in range(n_pairs)]
    for group in groups:
        ll = np.ascontiguousarray(sum_over_pairs([pair_loglik(j, clouds) for j in group]), dtype=np.float32)
        u0 = np.empty(k)
        jitter = np.empty((k, 2 * m), dtype=np.uint16)
        for i, g in enumerate(generators):
            u0[i] = g.random()
            jitter[i] = table_normal_indices(g, 2 * m)
        if (
            loglik_assimilate(
                ll, clouds, origin, u0, jitter, table, half, clouds, mean, cov, 2 * half, HIST_BINS, counts
            )
            >= 0
        ):
            raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
    return mean, cov
