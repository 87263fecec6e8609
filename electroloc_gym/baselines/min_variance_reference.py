"""Algorithm 1 written out literally: the references the vectorised min-var is tested against.

* :func:`literal_predicted_variances` — steps 1–3 and the weighted variance as loops over options,
  voters and particles (one sensor-model call per particle, ``math.exp``); small M only.
* :func:`multinomial_resampled_variances` — step 4 as the paper wrote it (§4.1.2: "randomly chooses M
  times from a roulette wheel"): per voter and option, the counts of M draws from the re-weighted cloud
  (``Generator.multinomial``), then the population variance of the resampled cloud (step 5). Exact in
  distribution, vectorised over particles, ≈ 50× slower than the central-limit form of
  :func:`electroloc_gym.baselines.min_variance.resampled_variances`; it is also ``min-var[vote=multinomial]``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["literal_predicted_variances", "multinomial_resampled_variances"]


def literal_predicted_variances(
    sensor_model: Any, particles: NDArray, weights: NDArray | None, positions_mm: NDArray, voters: NDArray[np.intp]
) -> NDArray[np.float64]:
    """Weighted variance (V, C), mm², of the cloud re-weighted by each voter's predicted reading (slow).

    Per option, one sensor-model call per particle (its predicted mean and std from that carriage
    position); then, per voter, Gaussian likelihoods of the voter's predicted reading with ``math.exp``
    for every particle and the weighted variance, in float64. Same layout as
    :func:`electroloc_gym.baselines.min_variance.predicted_variances`.
    """
    x = np.asarray(particles)
    m = x.shape[0]
    w_prior = [1.0 / m] * m if weights is None else [float(v) for v in weights]
    px = [float(v) for v in x[:, 0]]
    py = [float(v) for v in x[:, 1]]
    out = np.zeros((len(voters), len(positions_mm)))
    for c, pos in enumerate(positions_mm):
        p = np.asarray(pos, dtype=x.dtype)
        mus, sds = [], []
        for i in range(m):  # (1) move, per particle
            mu_i, sd_i = sensor_model.mean_std((x[i] - p)[None, :])
            mus.append(float(mu_i[0]))
            sds.append(float(sd_i[0]))
        for vi, mi in enumerate(voters):
            z = mus[int(mi)]  # (2) simulated reading
            ws = [w_prior[i] * math.exp(-0.5 * ((z - mus[i]) / sds[i]) ** 2) / sds[i] for i in range(m)]  # (3)
            tot = sum(ws)
            mx = sum(ws[i] * px[i] for i in range(m)) / tot
            my = sum(ws[i] * py[i] for i in range(m)) / tot
            var = sum(ws[i] * ((px[i] - mx) ** 2 + (py[i] - my) ** 2) for i in range(m))
            out[vi, c] = var / tot
    return out


def multinomial_resampled_variances(
    particles: NDArray,
    weights: NDArray | None,
    mean_V: NDArray,
    std_V: NDArray,
    voters: NDArray[np.intp],
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Variance (V, C), mm², of the cloud after one literal roulette-wheel resample per voter and option.

    Args:
        particles: (M, 2) particle positions, mm, or (C, M, 2) after each option's move.
        weights: (M,) prior weights (None: uniform).
        mean_V: (C, M) sensor-model mean of each particle's reading under each option, V.
        std_V: (C, M) sensor-model std, V.
        voters: (V,) indices of the voting particles.
        rng: generator of the resampling draws.
    """
    x = np.asarray(particles, dtype=np.float64)
    n_options, m = np.shape(mean_V)
    xs = np.broadcast_to(x, (n_options, m, 2))
    prior = np.full(m, 1.0 / m) if weights is None else np.asarray(weights, dtype=np.float64)
    mu = np.asarray(mean_V, dtype=np.float64)
    sd = np.asarray(std_V, dtype=np.float64)
    voters = np.asarray(voters, dtype=np.intp)
    out = np.empty((voters.size, n_options))
    for c in range(n_options):
        z = (mu[c, voters][:, None] - mu[c][None, :]) / sd[c][None, :]  # (V, M)
        logw = -0.5 * z * z - np.log(sd[c])[None, :] + np.log(prior)[None, :]
        w = np.exp(logw - logw.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        counts = rng.multinomial(m, w)  # (V, M): step 4
        mean = counts @ xs[c] / m  # (V, 2)
        second = counts @ np.einsum("mi,mi->m", xs[c], xs[c]) / m
        out[:, c] = np.maximum(second - np.einsum("vi,vi->v", mean, mean), 0.0)  # step 5
    return out
