"""min-var: the paper's greedy minimum-variance controller by particle voting (§4.1.3, Algorithm 1).

Algorithm 1 (paper): for every particle ``x_m`` (a target hypothesis) and every control option
``u_c`` (c = 1..C, C = 16: stay + 15 uniform moves in the ±10 mm square, drawn afresh each step):

1. simulate the move: the carriage goes to ``p_c = p + u_c``;
2. simulate the measurement ``z_mc = E[Φ | x_m, p_c]`` (noise-free: the sensor model's mean);
3. weight every particle ``i`` by the likelihood ``N(z_mc; μ_c(x_i), σ_c(x_i)²)``;
4. importance-resample the cloud with those weights;
5. compute the variance (trace of the covariance) of the resampled cloud.

Particle ``m`` votes for the option with the lowest variance; the option with the most votes wins.

**Expectation instead of a random resample.** Step 4–5 as written give a random variance. We use
its expectation: resampling ``M`` particles from the weighted cloud gives a population variance
whose expectation is ``(M − 1)/M`` times the *weighted* variance ``Σ w_i |x_i − x̄_w|²`` (multinomial
resampling; systematic resampling has the same mean and less spread). The factor is the same for
every option, so ``argmin`` over options is that of the weighted variance, which we compute exactly
(and the paper's post-resampling 1 mm jitter adds the same constant 2 mm² to every option). This is
Algorithm 1 "exact in expectation", without the sampling noise of a single resample per vote.

**Vectorisation** (DESIGN §10). With ``z = (z_mc − μ_ic)/σ_ic`` the weight is
``w_i/σ_ic · exp(−z²/2)`` (``w_i`` the belief's prior weights), so for each option the voters ×
particles matrix ``E = exp(−z²/2)`` times the (M, 4) matrix
``F = [g, g·x, g·y, g·|x|²]``, ``g = w/σ``, gives all the sums the weighted variance needs in one
BLAS call: ``var = S₃/S₀ − (S₁² + S₂²)/S₀²`` (coordinates centred on the cloud mean first, so the
float32 sums do not cancel). ``E`` is built in chunks of ``chunk_rows`` voters (a chunk stays in
cache), in float32, with the exponent clamped at ``exp_floor`` (−60): ``exp(−60) ≈ 10⁻²⁶`` is
negligible beside the voter's own weight (its own ``z`` is exactly 0, so ``S₀ ≥ g_m > 0``), and the
clamp keeps float32 ``exp`` out of denormals, which are many times slower. At M = 2500, C = 16 that
is 10⁸ exponentials per decision; ``n_voters`` lets a random subset of particles (drawn without
replacement from the agent's generator each step) vote, e.g. 256: every particle is still weighted,
only fewer ballots are counted (``benchmarks/minvar.py`` shows the choice rarely changes).

:func:`literal_predicted_variances` is a line-by-line loop implementation of the same quantity (one
sensor-model call per particle, ``math.exp``), used by the tests on small M as the reference.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.agent import BaselineAgent, move_bounds_mm, sample_options_mm

__all__ = [
    "MinVarianceAgent",
    "predicted_variances",
    "literal_predicted_variances",
    "count_votes",
    "option_means_stds",
    "choose_voters",
]


def option_means_stds(sensor_model: Any, particles: NDArray, positions_mm: NDArray) -> tuple[NDArray, NDArray]:
    """Sensor-model mean and std (C, M) of every particle's reading from each carriage position (C, 2).

    Offsets are ``particle − carriage`` (target − carriage, the sensor models' convention); computed
    in the particles' dtype (float32 for the env's belief) in one batched call.
    """
    x = np.asarray(particles)
    dtype = x.dtype if x.dtype in (np.float32, np.float64) else np.float64
    offsets = x[None, :, :].astype(dtype, copy=False) - np.asarray(positions_mm, dtype=dtype)[:, None, :]
    mean, std = sensor_model.mean_std(offsets)
    return np.asarray(mean), np.asarray(std)


def choose_voters(rng: np.random.Generator, n_particles: int, n_voters: int | None) -> NDArray[np.intp]:
    """Indices of the voting particles: all (``n_voters`` None or ≥ M) or a random subset, sorted."""
    if n_voters is None or n_voters >= n_particles:
        return np.arange(n_particles)
    return np.sort(rng.choice(n_particles, size=n_voters, replace=False))


def predicted_variances(particles: NDArray, weights: NDArray | None, mean_V: NDArray, std_V: NDArray,
                        voters: NDArray[np.intp], *, chunk_rows: int = 128, exp_floor: float = -60.0,
                        kernel: str = "auto", expanded_max_exponent: float = 1000.0) -> NDArray[np.float64]:
    """Expected post-update variance (trace, mm²) for every voter and option — vectorised Algorithm 1.

    Two float32 kernels build the (voters × M) exponent ``−z²/2`` of each option:

    * ``"difference"``: ``((a_v − b_i)·k_i)²`` element by element (6 passes over the block);
    * ``"expanded"``: ``−k_i²a_v² + 2k_i²b_i·a_v − k_i²b_i²`` as one rank-3 matrix product (3
      passes), ≈ 1.5× faster. Its float32 rounding error in the exponent is ≈ 3·ε₃₂·max(|a·k|²),
      so ``"auto"`` uses it only when max (|μ − centre|/σ)²/2 ≤ ``expanded_max_exponent`` (1000:
      exponent error ≤ 2·10⁻⁴, i.e. weights within 0.02 %), which holds for every preset with the
      fitted signal; saturated, very sharp models fall back to ``"difference"``.

    Args:
        particles: (M, 2) particle positions, mm, or (C, M, 2) positions after each option's move
            (hypotheses that move with the robot, global localisation).
        weights: (M,) prior weights (None: uniform, as right after the env's resampling).
        mean_V: (C, M) sensor-model mean of each particle's reading under each option, V.
        std_V: (C, M) sensor-model std, V (> 0).
        voters: (V,) indices of the voting particles.
        chunk_rows: voters per block of the (voters × M) likelihood matrix.
        exp_floor: clamp of the exponent −z²/2 (keeps float32 exp out of denormals).
        kernel: ``"auto"``, ``"difference"`` or ``"expanded"``.
        expanded_max_exponent: the ``"auto"`` switch, see above.

    Returns:
        (V, C) weighted variance of the cloud after option c's simulated reading z_vc = mean_V[c, v].
    """
    if kernel not in ("auto", "difference", "expanded"):
        raise ValueError(f"kernel must be 'auto', 'difference' or 'expanded', got {kernel!r}")
    x = np.asarray(particles, dtype=np.float64)
    n_options, m = mean_V.shape
    if x.shape not in ((m, 2), (n_options, m, 2)) or np.shape(std_V) != mean_V.shape:
        raise ValueError(f"shapes disagree: particles {x.shape}, mean_V {mean_V.shape}, std_V {np.shape(std_V)}")
    w = np.full(m, 1.0 / m) if weights is None else np.asarray(weights, dtype=np.float64)
    centre = np.einsum("m,...mi->...i", w, x) / w.sum()
    xc = x - centre[..., None, :]  # centred coordinates: float32 sums of |x|² do not cancel
    r2 = np.einsum("...i,...i->...", xc, xc)
    f32 = np.float32
    inv_s = 1.0 / np.asarray(std_V, dtype=np.float64)                          # (C, M)
    g = inv_s * w                                                             # prior × Gaussian 1/σ
    feats = np.stack([g, g * xc[..., 0], g * xc[..., 1], g * r2], axis=-1).astype(f32)  # (C, M, 4)
    mu64 = np.asarray(mean_V, dtype=np.float64)
    mu64 = mu64 - 0.5 * (mu64.max(axis=1, keepdims=True) + mu64.min(axis=1, keepdims=True))  # z is shift-free
    half_k2 = 0.5 * inv_s**2                                                  # z²/2 = (a − b)²·k²/2
    if kernel == "auto":
        kernel = "expanded" if float(np.max(mu64**2 * half_k2)) <= expanded_max_exponent else "difference"
    voters = np.asarray(voters, dtype=np.intp)
    n_vot = voters.size
    sums = np.empty((n_options, n_vot, 4), dtype=f32)
    rows = max(1, min(int(chunk_rows), n_vot))
    buf = np.empty((rows, m), dtype=f32)
    floor = f32(exp_floor)
    if kernel == "expanded":
        # −z²/2 = [a², a, 1] · [−k²/2, k²b, −k²b²/2]ᵀ  (k² = 1/σ²): one sgemm with inner size 3.
        right = np.stack([-half_k2, 2.0 * half_k2 * mu64, -half_k2 * mu64**2], axis=1).astype(f32)  # (C, 3, M)
        a_all = mu64[:, voters]
        left = np.stack([a_all**2, a_all, np.ones_like(a_all)], axis=-1).astype(f32)               # (C, V, 3)
        for c in range(n_options):
            for r0 in range(0, n_vot, rows):
                r1 = min(r0 + rows, n_vot)
                d = buf[: r1 - r0]
                np.matmul(left[c, r0:r1], right[c], out=d)    # −z²/2
                np.maximum(d, floor, out=d)                     # clamp: exp(−60) ≈ 1e-26
                np.exp(d, out=d)
                np.matmul(d, feats[c], out=sums[c, r0:r1])
    else:
        k = np.sqrt(half_k2).astype(f32)                                      # z/√2 = (a − b)·k
        mu = mu64.astype(f32)
        bk = mu * k                                                           # (C, M)
        cap = f32(-exp_floor)
        for c in range(n_options):
            a = mu[c, voters]
            kc, bkc, fc = k[c], bk[c], feats[c]
            for r0 in range(0, n_vot, rows):
                r1 = min(r0 + rows, n_vot)
                d = buf[: r1 - r0]
                np.multiply(a[r0:r1, None], kc[None, :], out=d)   # a_v·k_i
                np.subtract(d, bkc[None, :], out=d)                # (a_v − b_i)·k_i = z/√2
                np.multiply(d, d, out=d)                           # z²/2
                np.minimum(d, cap, out=d)                          # clamp: exp(−60) ≈ 1e-26
                np.negative(d, out=d)
                np.exp(d, out=d)
                np.matmul(d, fc, out=sums[c, r0:r1])
    s = sums.astype(np.float64)
    s0 = s[..., 0]
    var = s[..., 3] / s0 - (s[..., 1] ** 2 + s[..., 2] ** 2) / s0**2
    return np.maximum(var, 0.0).T                                             # (V, C)


def literal_predicted_variances(sensor_model: Any, particles: NDArray, weights: NDArray | None,
                                positions_mm: NDArray, voters: NDArray[np.intp]) -> NDArray[np.float64]:
    """Reference: Algorithm 1 written as loops over options, voters and particles (slow; small M only).

    Per option, one sensor-model call per particle (its predicted mean and std from that carriage
    position); then, per voter, Gaussian likelihoods of the voter's predicted reading with
    ``math.exp`` for every particle and the weighted (expected post-resampling) variance, in float64.
    Same inputs and result layout as :func:`predicted_variances` (which takes precomputed means/stds).
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
        for i in range(m):                                                   # (1) move, per particle
            mu_i, sd_i = sensor_model.mean_std((x[i] - p)[None, :])
            mus.append(float(mu_i[0]))
            sds.append(float(sd_i[0]))
        for vi, mi in enumerate(voters):
            z = mus[int(mi)]                                                  # (2) simulated reading
            ws = [w_prior[i] * math.exp(-0.5 * ((z - mus[i]) / sds[i]) ** 2) / sds[i] for i in range(m)]  # (3)
            tot = sum(ws)
            mx = sum(ws[i] * px[i] for i in range(m)) / tot
            my = sum(ws[i] * py[i] for i in range(m)) / tot
            var = sum(ws[i] * ((px[i] - mx) ** 2 + (py[i] - my) ** 2) for i in range(m))  # (4–5) expected
            out[vi, c] = var / tot
    return out


def count_votes(variances: NDArray) -> tuple[int, NDArray[np.int64]]:
    """Each voter's ballot goes to its lowest-variance option; returns (winner, votes per option).

    Ties in the count go to the lowest option index (option 0 is "stay").
    """
    ballots = np.argmin(variances, axis=1)
    votes = np.bincount(ballots, minlength=variances.shape[1])
    return int(np.argmax(votes)), votes


class MinVarianceAgent(BaselineAgent):
    """Greedy minimum expected variance by particle voting (paper §4.1.3 policy #2, Algorithm 1).

    Reads ``env.unwrapped.belief`` (particles, weights), ``.sensor_model`` (``mean_std``),
    ``.position_mm`` and ``.allowed_box_mm``; never the true target.

    Args:
        seed: seed or generator for the option draws and the voter subset.
        n_options: options per step including "stay" (paper: 16).
        n_voters: number of particles that vote (a random subset each step); None or ≥ M: all.
            Default 256 (DESIGN §10: ≈ 35 ms instead of ≈ 330 ms per decision at M = 2500; the
            benchmark statistics do not change beyond noise, see ``benchmarks/minvar.py``).
        chunk_rows: voters per block of the vectorised vote.
        exp_floor: clamp of the Gaussian exponent.

    Attributes:
        last_votes: votes per option of the last decision.
        last_options_mm: the options (C, 2) of the last decision, mm.
    """

    name = "min-var"

    def __init__(self, seed: int | np.random.Generator | None = None, n_options: int = 16,
                 n_voters: int | None = 256, chunk_rows: int = 128, exp_floor: float = -60.0) -> None:
        super().__init__(seed)
        if isinstance(n_options, bool) or not isinstance(n_options, int) or n_options < 1:
            raise ValueError(f"n_options must be an integer ≥ 1, got {n_options!r}")
        if n_voters is not None and (isinstance(n_voters, bool) or not isinstance(n_voters, int) or n_voters < 1):
            raise ValueError(f"n_voters must be an integer ≥ 1 or None (all particles vote), got {n_voters!r}")
        if isinstance(chunk_rows, bool) or not isinstance(chunk_rows, int) or chunk_rows < 1:
            raise ValueError(f"chunk_rows must be an integer ≥ 1, got {chunk_rows!r}")
        if not (isinstance(exp_floor, (int, float)) and -80.0 <= exp_floor < 0):
            raise ValueError(f"exp_floor must be in [-80, 0) (float32 exp underflows below ≈ -87), got {exp_floor!r}")
        self.n_options = n_options
        self.n_voters = n_voters
        self.chunk_rows = chunk_rows
        self.exp_floor = float(exp_floor)
        self.last_votes: NDArray[np.int64] | None = None
        self.last_options_mm: NDArray[np.float64] | None = None

    def choose_move_mm(self) -> NDArray[np.float64]:
        env = self.env
        belief = env.belief
        options = sample_options_mm(self.rng, *move_bounds_mm(env), self.n_options)
        particles = belief.particles
        weights = belief.weights
        uniform = bool(np.all(weights == weights[0]))
        voters = choose_voters(self.rng, particles.shape[0], self.n_voters)
        if hasattr(env, "predicted_reading_model"):
            # The env's own motion rule and frame (ElectroLoc-v0: the target is static; the global
            # env: the hypotheses are the robot's own position and move with it).
            mean, std = env.predicted_reading_model(particles, options)
            moved = env.predicted_particles_mm(particles, options)
        else:
            mean, std = option_means_stds(env.sensor_model, particles, env.position_mm + options)
            moved = particles
        var = predicted_variances(moved, None if uniform else weights, mean, std, voters,
                                  chunk_rows=self.chunk_rows, exp_floor=self.exp_floor)
        best, votes = count_votes(var)
        self.last_votes, self.last_options_mm = votes, options
        return options[best]

    def __repr__(self) -> str:
        return f"MinVarianceAgent(n_options={self.n_options}, n_voters={self.n_voters})"
