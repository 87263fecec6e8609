"""lookahead_objectives: what the look-ahead planner minimises over the sampled futures of a move sequence.

The planner (:mod:`electroloc_gym.baselines.lookahead`) scores a sequence of T moves on B sampled
futures. A future is a hypothesis ``h`` of the planner's cloud (S hypotheses, uniform weights) and one
standard-normal noise draw per step. Its readings are ``z_t = μ_t(x_h) + σ_t(x_h)·ε_t``, where μ_t and
σ_t are the sensor model's mean and std after the t-th move. After t readings the cloud is re-weighted
by ``w_i ∝ Π_{t'≤t} N(z_t'; μ_t'(x_i), σ_t'(x_i)²)``, and the **posterior spread** is ``s_t = √trace Σ_w``
(mm, the env's success measure). The objectives (``objective=`` of the planner), per future:

* ``"spread"``: ``s_T``, the spread after the whole sequence;
* ``"logspread"``: ``ln(s_T + 1 mm)``. Halving a wide spread counts as much as halving a narrow one,
  so a future that stays wide does not dominate the mean;
* ``"entropy"``: ``H_T = −Σ w_i ln w_i`` (nats), the entropy of the re-weighted cloud's weights.
  Minimising its mean maximises the expected information gain about the hypothesis (uniform prior over
  the cloud), whether or not the belief is unimodal;
* ``"steps"``: the expected number of further readings until the env's success rule
  ``s ≤ success_spread_mm`` holds. The first reading of the sequence is always taken. Reading t + 1 is
  taken only while every ``s_t' > success_spread_mm`` (t' ≤ t), so ``alive_t`` is 1 until success
  and 0 after. A future that is still alive after the last move costs a tail estimate of the readings
  still to come, ``1 + tail·ln(s_T / success_spread_mm)``. The cost is
  ``Σ_{t<T} alive_t + alive_T·(1 + tail·ln(s_T / success_spread_mm))``. Unlike the other objectives
  it rewards a sequence that finishes *early* (a first move that succeeds at once beats one whose
  continuation ends narrower), and it is measured in the env's own currency (readings).

Everything is array arithmetic over (N sequences, B futures, S hypotheses). The only Python loop is
over the T ≤ 3 steps, each of which adds one step's log-likelihood.
"""

from __future__ import annotations

from typing import cast

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.protocol import SUCCESS_SPREAD_MM

__all__ = ["OBJECTIVES", "LOG_FLOOR_MM", "posterior_spreads", "sequence_costs", "adaptive_costs"]

#: The planner's objectives (see the module docstring).
OBJECTIVES = ("spread", "logspread", "entropy", "steps")
#: Added to the spread inside ``"logspread"``'s logarithm, mm (a collapsed cloud does not go to −∞).
LOG_FLOOR_MM = 1.0


def _weighted_spread(w: NDArray, x: NDArray) -> NDArray[np.float64]:
    """√trace Σ (N, B) of clouds x (N, S, 2) (or (S, 2)) weighted by w (N, B, S) (weights sum to 1)."""
    x = np.asarray(x, dtype=np.float64)
    x = x - x.reshape(-1, 2).mean(axis=0)  # centred: the float sums do not cancel
    if x.ndim == 2:
        x = x[None]
    m = np.einsum("nbs,nsi->nbi", w, x)
    second = np.einsum("nbs,ns->nb", w, np.einsum("nsi,nsi->ns", x, x))
    return np.sqrt(np.maximum(second - np.einsum("nbi,nbi->nb", m, m), 0.0))


def _step_log_likelihoods(mu: NDArray, sd: NDArray, hyp: NDArray[np.intp], eps: NDArray) -> NDArray[np.float64]:
    """(T, N, B, S) log-likelihood of every hypothesis under each future's t-th reading (up to a constant).

    A sensor array's K readings per step (``mu``, ``sd`` (T, N, S, K), ``eps`` (B, T, K)): independent noises,
    so the step's log-likelihood is the sum over the pairs.
    """
    if mu.ndim == 4:
        total = sum(_step_log_likelihoods(mu[..., q], sd[..., q], hyp, eps[..., q]) for q in range(mu.shape[-1]))
        return cast("NDArray[np.float64]", total)  # K ≥ 1 pairs: a sum of arrays, never sum()'s start 0
    z = mu[:, :, hyp] + sd[:, :, hyp] * eps.T[:, None, :]  # (T, N, B)
    r = (z[..., None] - mu[:, :, None, :]) / sd[:, :, None, :]  # (T, N, B, S)
    return -0.5 * r * r - np.log(sd)[:, :, None, :]


def _normalise(ll: NDArray) -> tuple[NDArray, NDArray]:
    """Weights (…, S) ∝ exp(ll) and their entropy (…), nats."""
    shifted = ll - ll.max(axis=-1, keepdims=True)
    e = np.exp(shifted)
    z = e.sum(axis=-1, keepdims=True)
    w = e / z
    entropy = np.log(z[..., 0]) - np.einsum("...s,...s->...", w, shifted)
    return w, entropy


def sequence_costs(
    mean_V: NDArray,
    std_V: NDArray,
    particles_mm: NDArray | list[NDArray],
    hyp: NDArray[np.intp],
    eps: NDArray,
    objective: str = "spread",
    *,
    success_spread_mm: float = SUCCESS_SPREAD_MM,
    tail: float = 1.0,
) -> NDArray[np.float64]:
    """The objective (B, N) of every future and sequence (lower is better).

    Args:
        mean_V: (T, N, S) sensor-model mean of each hypothesis' reading after the t-th move of each of N
            sequences, V; (T, N, S, K) with K readings per step (a sensor array).
        std_V: (T, N, S) (or (T, N, S, K)) its std, V (> 0).
        particles_mm: the hypotheses after the sequence, (S, 2) or (N, S, 2) mm, or a list of T such
            arrays (the hypotheses after each move; ``"steps"`` needs the spread after every move).
        hyp: (B,) index of the hypothesis that generates each future's readings.
        eps: (B, T) (or (B, T, K)) standard-normal noise of each future's readings.
        objective: one of :data:`OBJECTIVES`.
        success_spread_mm: the env's success spread, mm (``"steps"``).
        tail: readings per unit of ``ln(s_T / success_spread_mm)`` in ``"steps"``' tail estimate (≥ 0).

    Returns:
        (B, N) cost of every future and sequence: mm (spread), ln mm, nats or readings.

    Raises:
        ValueError: an unknown objective.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {list(OBJECTIVES)}, got {objective!r}")
    mu = np.asarray(mean_V, dtype=np.float64)
    sd = np.asarray(std_V, dtype=np.float64)
    t_steps = mu.shape[0]
    xs = list(particles_mm) if isinstance(particles_mm, list) else [particles_mm] * t_steps
    ll_t = _step_log_likelihoods(mu, sd, hyp, np.asarray(eps, dtype=np.float64))
    if objective != "steps":
        w, entropy = _normalise(ll_t.sum(axis=0))  # (N, B, S)
        if objective == "entropy":
            return entropy.T
        spread = _weighted_spread(w, xs[-1]).T
        return spread if objective == "spread" else np.log(spread + LOG_FLOOR_MM)
    cost = np.zeros(ll_t.shape[1:3])
    alive = np.ones(ll_t.shape[1:3], dtype=bool)
    cum = np.zeros(ll_t.shape[1:])
    for t in range(t_steps):  # T ≤ 3 steps
        cum += ll_t[t]
        spread = _weighted_spread(_normalise(cum)[0], xs[t])
        alive &= spread > success_spread_mm
        if t < t_steps - 1:
            cost += alive
        else:
            tail_readings = 1.0 + tail * np.log(np.maximum(spread, success_spread_mm) / success_spread_mm)
            cost += alive * tail_readings
    return cost.T


def _final_cost(
    w: NDArray, entropy: NDArray, x: NDArray, objective: str, success_spread_mm: float, tail: float
) -> NDArray[np.float64]:
    """The objective of clouds x weighted by w (…, S) after the last move (``"steps"``: the tail if alive)."""
    if objective == "entropy":
        return entropy
    spread = _weighted_spread(w.reshape(w.shape[0], -1, w.shape[-1]), x).reshape(w.shape[:-1])
    if objective == "spread":
        return spread
    if objective == "logspread":
        return np.log(spread + LOG_FLOOR_MM)
    alive = spread > success_spread_mm
    return alive * (1.0 + tail * np.log(np.maximum(spread, success_spread_mm) / success_spread_mm))


def adaptive_costs(
    mean_V: NDArray,
    std_V: NDArray,
    clouds: list[NDArray] | NDArray,
    n_first: int,
    hyp: NDArray[np.intp],
    eps1: NDArray,
    u_inner: NDArray,
    eps2: NDArray,
    objective: str = "steps",
    *,
    success_spread_mm: float = SUCCESS_SPREAD_MM,
    tail: float = 1.0,
) -> NDArray[np.float64]:
    """Each first move's expected objective (C,) when the second move is chosen after the first reading.

    Depth 2, closed loop: ``Q(u₁) = E_{z₁}[c₁ + min_{u₂} E_{z₂ | z₁}[c₂]]``. The outer futures are
    as in :func:`sequence_costs` (hypothesis ``hyp[b]``, noise ``eps1[b]``); for each first move and
    outer future the inner futures draw a hypothesis from the posterior after ``z₁`` (inverse CDF of
    the re-weighted cloud at the uniforms ``u_inner``) and a noise ``eps2``, so the second move is
    judged on what the first reading left open. ``c₁`` is ``"steps"``' first reading after the first
    move (1 while the spread is above ``success_spread_mm``, 0 after success, when ``c₂`` is 0 too);
    the other objectives have ``c₁ = 0`` and ``c₂`` their value after the second move.

    Args:
        mean_V: (2, C·K, S) sensor-model mean, V, as in :func:`sequence_costs`; the K continuations of
            first move c at rows c·K … c·K + K − 1.
        std_V: (2, C·K, S) its std, V.
        clouds: the hypotheses after each move ((S, 2), (C·K, S, 2) or a list of two).
        n_first: C.
        hyp: (B,) outer hypotheses.
        eps1: (B,) their first-reading noise (standard normal).
        u_inner: (B, M) uniforms in [0, 1) of the inner hypotheses.
        eps2: (B, M) the inner futures' second-reading noise (standard normal).
        objective: one of :data:`OBJECTIVES`.
        success_spread_mm: the env's success spread, mm.
        tail: ``"steps"``' tail (readings per unit of ln spread ratio).

    Returns:
        (C,) expected cost of each first move.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {list(OBJECTIVES)}, got {objective!r}")
    mu = np.asarray(mean_V, dtype=np.float64)
    sd = np.asarray(std_V, dtype=np.float64)
    c = n_first
    k, s = mu.shape[1] // c, mu.shape[2]
    xs = list(clouds) if isinstance(clouds, list) else [clouds] * 2
    mu1, sd1 = mu[0].reshape(c, k, s)[:, 0], sd[0].reshape(c, k, s)[:, 0]  # (C, S)
    z1 = mu1[:, hyp] + sd1[:, hyp] * np.asarray(eps1, dtype=np.float64)[None, :]  # (C, B)
    r1 = (z1[..., None] - mu1[:, None, :]) / sd1[:, None, :]
    ll1 = -0.5 * r1 * r1 - np.log(sd1)[:, None, :]  # (C, B, S)
    w1, _ = _normalise(ll1)
    inner = (np.cumsum(w1, axis=-1)[:, :, None, :] <= u_inner[None, :, :, None]).sum(axis=-1)
    inner = np.minimum(inner, s - 1)  # (C, B, M)
    mu2, sd2 = mu[1].reshape(c, k, s), sd[1].reshape(c, k, s)
    ci = np.arange(c)[:, None, None, None]
    ki = np.arange(k)[None, :, None, None]
    h2 = inner[:, None, :, :]  # (C, 1, B, M)
    z2 = mu2[ci, ki, h2] + sd2[ci, ki, h2] * eps2[None, None]  # (C, K, B, M)
    r2 = (z2[..., None] - mu2[:, :, None, None, :]) / sd2[:, :, None, None, :]
    ll2 = ll1[:, None, :, None, :] - 0.5 * r2 * r2 - np.log(sd2)[:, :, None, None, :]  # (C, K, B, M, S)
    w2, entropy2 = _normalise(ll2)
    x2 = np.asarray(xs[1], dtype=np.float64)
    if x2.ndim == 3:  # (C·K, S, 2) → one cloud per (c, k), repeated over B·M
        x2 = x2.reshape(c * k, s, 2)
    cost2 = _final_cost(
        w2.reshape(c * k, -1, s), entropy2.reshape(c * k, -1), x2, objective, success_spread_mm, tail
    ).reshape(c, k, *inner.shape[1:])  # (C, K, B, M)
    best2 = cost2.mean(axis=-1).min(axis=1)  # (C, B)
    if objective != "steps":
        return best2.mean(axis=-1)
    x1 = np.asarray(xs[0], dtype=np.float64)
    x1 = x1.reshape(c, k, s, 2)[:, 0] if x1.ndim == 3 else x1
    alive1 = _weighted_spread(w1, x1) > success_spread_mm  # (C, B)
    return (alive1 * (1.0 + best2)).mean(axis=-1)


def posterior_spreads(
    mean_V: NDArray, std_V: NDArray, particles_mm: NDArray, hyp: NDArray[np.intp], eps: NDArray
) -> NDArray[np.float64]:
    """Posterior spread √trace Σ (B, N) (mm) of a uniform cloud after each sequence's sampled readings.

    ``sequence_costs(..., objective="spread")``; the arguments as there.
    """
    return sequence_costs(mean_V, std_V, particles_mm, hyp, eps, "spread")
