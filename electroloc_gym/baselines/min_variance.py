"""min-var: the paper's greedy minimum-variance controller by particle voting (§4.1.3, Algorithm 1).

Algorithm 1 (paper): for every particle ``x_m`` (a target hypothesis) and every control option
``u_c`` (c = 1..C, C = 16: stay + 15 uniform moves in the ±10 mm square, drawn afresh each step):

1. simulate the move: the carriage goes to ``p_c = p + u_c``;
2. simulate the measurement ``z_mc = E[Φ | x_m, p_c]`` (noise-free: the sensor model's mean);
3. weight every particle ``i`` by the likelihood ``N(z_mc; μ_c(x_i), σ_c(x_i)²)``;
4. importance-resample the cloud with those weights;
5. compute the variance (trace of the covariance) of the resampled cloud.

Particle ``m`` votes for the option with the lowest variance; the option with the most votes wins.

**The random resample per vote (step 4).** Resampling M particles from the re-weighted cloud
("roulette wheel", §4.1.2) makes the variance of step 5 a random variable: each voter's ballot is the
argmin over options of one draw per option. That randomness is part of the algorithm. Most voters of
a wide belief are *blind* — their predicted reading is ≈ 0 V at every option, so their re-weighted
clouds barely differ between options; with one resample each, their near-tied ballots scatter over
the options and the few informed voters (near the sensor, whose options really differ) decide the
plurality. Replacing the random variance by its expectation makes every blind voter vote alike, for
whichever option has the marginally lowest expected variance (often "stay", or toward a wall), and
they out-vote the informed ones. ``vote`` selects the form:

* ``"resample"`` (default): the resampled variance drawn from its distribution. The population
  variance of M multinomial draws from weights ``w`` is ``s² = (1/M)Σ|d_j|² − |d̄|²`` (d = x − x̄_w);
  it is a mean of M i.i.d. terms, so (central limit, M = 2500) ``s² ≈ (M−1)/M·v + √((μ₄ − v²)/M)·Z``,
  ``Z ~ N(0, 1)`` per voter and option, with ``v = E_w|d|²`` and ``μ₄ = E_w|d|⁴`` computed exactly from
  the same weighted sums. Its distribution matches the literal resample (tested against
  :func:`~electroloc_gym.baselines.min_variance_reference.multinomial_resampled_variances`).
* ``"multinomial"``: the literal roulette-wheel resample (``Generator.multinomial`` counts per voter
  and option) — exact, ≈ 50× slower.
* ``"expected"``: ``E[s²] = (M − 1)/M · v`` — the argmin of the expectation. Not Algorithm 1; kept for
  comparison (``min-var[vote=expected]``).

The 1 mm jitter after resampling adds the same 2 mm² to every option and is left out.

**Vectorisation.** With ``z = (z_mc − μ_ic)/σ_ic`` the weight is ``w_i/σ_ic · exp(−z²/2)``
(``w_i`` the belief's prior weights), so for each option the voters × particles matrix
``E = exp(−z²/2)`` times the (M, K) matrix of moment features ``F = g·[1, x, y, x², y², xy, |x|²x,
|x|²y, |x|⁴]``, ``g = w/σ``, gives every weighted moment up to the fourth in one BLAS call
(coordinates centred on the cloud mean first, so the float32 sums do not cancel; ``"expected"``
needs only the first four columns). ``E`` is built in chunks of ``chunk_rows`` voters (a chunk stays in
cache), in float32, with the exponent clamped at ``exp_floor`` (−60): ``exp(−60) ≈ 10⁻²⁶`` is
negligible beside the voter's own weight (its own ``z`` is exactly 0, so ``S₀ ≥ g_m > 0``), and the
clamp keeps float32 ``exp`` out of denormals, which are many times slower. At M = 2500, C = 16 that
is 10⁸ exponentials per decision; ``n_voters`` lets a random subset of particles (drawn without
replacement from the agent's generator each step) vote, e.g. 256: every particle is still weighted,
only fewer ballots are counted (``benchmarks/minvar.py`` shows the choice rarely changes).

:mod:`electroloc_gym.baselines.min_variance_reference` holds the line-by-line loop form and the literal
resample, the tests' references.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import BaselineAgent, move_bounds_mm, sample_options_mm

__all__ = [
    "MinVarianceAgent",
    "VOTES",
    "weighted_moments",
    "predicted_variances",
    "resampled_variances",
    "count_votes",
    "option_means_stds",
    "choose_voters",
]

#: The forms of Algorithm 1's step 4–5 (see the module docstring).
VOTES = ("resample", "multinomial", "expected")
#: Columns of the moment features: 1, x, y, x², y², xy, |x|²x, |x|²y, |x|⁴.
N_MOMENTS = 9


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


def weighted_moments(
    particles: NDArray,
    weights: NDArray | None,
    mean_V: NDArray,
    std_V: NDArray,
    voters: NDArray[np.intp],
    *,
    n_moments: int = N_MOMENTS,
    chunk_rows: int = 128,
    exp_floor: float = -60.0,
    kernel: str = "auto",
    expanded_max_exponent: float = 1000.0,
) -> NDArray[np.float64]:
    """Normalised weighted moments (V, C, K) of the cloud re-weighted by each voter's reading at each option.

    Step 3 of Algorithm 1, vectorised: the weights of particle i for voter v and option c are
    ``w_i/σ_ci · exp(−(μ_cv − μ_ci)²/(2σ_ci²))``. Two float32 kernels build the (voters × M) exponent:

    * ``"difference"``: ``((a_v − b_i)·k_i)²`` element by element (6 passes over the block);
    * ``"expanded"``: ``−k_i²a_v² + 2k_i²b_i·a_v − k_i²b_i²`` as one rank-3 matrix product (3
      passes), ≈ 1.5× faster. Its float32 rounding error in the exponent is ≈ 3·ε₃₂·max(|a·k|²),
      so ``"auto"`` uses it only when max (|μ − centre|/σ)²/2 ≤ ``expanded_max_exponent`` (1000:
      exponent error ≤ 2·10⁻⁴, i.e. weights within 0.02 %); saturated, very sharp models fall back
      to ``"difference"``.

    Args:
        particles: (M, 2) particle positions, mm, or (C, M, 2) positions after each option's move
            (hypotheses that move with the robot, global localisation).
        weights: (M,) prior weights (None: uniform, as right after the env's resampling).
        mean_V: (C, M) sensor-model mean of each particle's reading under each option, V; or (C, M, K) with K
            readings per step (a sensor array: their independent Gaussian likelihoods multiply).
        std_V: (C, M) (or (C, M, K)) sensor-model std, V (> 0).
        voters: (V,) indices of the voting particles.
        n_moments: 4 (1, x, y, |x|²: enough for the variance) or 9 (up to |x|⁴).
        chunk_rows: voters per block of the (voters × M) likelihood matrix.
        exp_floor: clamp of the exponent −z²/2 (keeps float32 exp out of denormals).
        kernel: ``"auto"``, ``"difference"`` or ``"expanded"``.
        expanded_max_exponent: the ``"auto"`` switch, see above.

    Returns:
        (V, C, K) moments E_w[f] of the features (1, x, y, |x|², …) with coordinates in mm relative to
        the prior cloud's weighted mean; column 0 is the weights' total (not normalised).
    """
    if kernel not in ("auto", "difference", "expanded"):
        raise ValueError(f"kernel must be 'auto', 'difference' or 'expanded', got {kernel!r}")
    if n_moments not in (4, N_MOMENTS):
        raise ValueError(f"n_moments must be 4 or {N_MOMENTS}, got {n_moments!r}")
    x = np.asarray(particles, dtype=np.float64)
    n_options, m = mean_V.shape[:2]
    pairs = np.ndim(mean_V) == 3  # K readings per option: the exponent sums over the pairs
    if x.shape not in ((m, 2), (n_options, m, 2)) or np.shape(std_V) != mean_V.shape:
        raise ValueError(f"shapes disagree: particles {x.shape}, mean_V {mean_V.shape}, std_V {np.shape(std_V)}")
    w = np.full(m, 1.0 / m) if weights is None else np.asarray(weights, dtype=np.float64)
    centre = np.einsum("m,...mi->...i", w, x) / w.sum()
    xc = x - centre[..., None, :]  # centred coordinates: float32 sums of |x|² do not cancel
    r2 = np.einsum("...i,...i->...", xc, xc)
    f32 = np.float32
    inv_s = 1.0 / np.asarray(std_V, dtype=np.float64)  # (C, M)
    g = (np.prod(inv_s, axis=-1) if pairs else inv_s) * w  # prior × Gaussian 1/σ
    cx, cy = xc[..., 0], xc[..., 1]
    if n_moments == 4:
        cols = [g, g * cx, g * cy, g * r2]
    else:
        cols = [g, g * cx, g * cy, g * cx * cx, g * cy * cy, g * cx * cy, g * r2 * cx, g * r2 * cy, g * r2 * r2]
    feats = np.stack(np.broadcast_arrays(*cols), axis=-1).astype(f32)  # (C, M, K)
    mu64 = np.asarray(mean_V, dtype=np.float64)
    mu64 = mu64 - 0.5 * (mu64.max(axis=1, keepdims=True) + mu64.min(axis=1, keepdims=True))  # z is shift-free
    half_k2 = 0.5 * inv_s**2  # z²/2 = (a − b)²·k²/2
    if pairs:
        kernel = "difference"
    elif kernel == "auto":
        kernel = "expanded" if float(np.max(mu64**2 * half_k2)) <= expanded_max_exponent else "difference"
    voters = np.asarray(voters, dtype=np.intp)
    n_vot = voters.size
    sums = np.empty((n_options, n_vot, n_moments), dtype=f32)
    rows = max(1, min(int(chunk_rows), n_vot))
    buf = np.empty((rows, m), dtype=f32)
    # Each kernel's clamp bound is a block of the buffer's shape: numpy's maximum and minimum against a scalar
    # take about four times as long as against an array (the result is the same: both are exact).
    if kernel == "expanded":
        floor = np.full_like(buf, exp_floor)
        # −z²/2 = [a², a, 1] · [−k²/2, k²b, −k²b²/2]ᵀ  (k² = 1/σ²): one sgemm with inner size 3.
        right = np.stack([-half_k2, 2.0 * half_k2 * mu64, -half_k2 * mu64**2], axis=1).astype(f32)  # (C, 3, M)
        a_all = mu64[:, voters]
        left = np.stack([a_all**2, a_all, np.ones_like(a_all)], axis=-1).astype(f32)  # (C, V, 3)
        for c in range(n_options):
            for r0 in range(0, n_vot, rows):
                r1 = min(r0 + rows, n_vot)
                d = buf[: r1 - r0]
                np.matmul(left[c, r0:r1], right[c], out=d)  # −z²/2
                np.maximum(d, floor[: r1 - r0], out=d)  # clamp: exp(−60) ≈ 1e-26
                np.exp(d, out=d)
                np.matmul(d, feats[c], out=sums[c, r0:r1])
    else:
        k = np.sqrt(half_k2).astype(f32)  # z/√2 = (a − b)·k
        mu = mu64.astype(f32)
        bk = mu * k  # (C, M[, K])
        if not pairs:  # one pair: a trailing axis of 1
            k, mu, bk = k[..., None], mu[..., None], bk[..., None]
        k, bk = np.ascontiguousarray(k.transpose(0, 2, 1)), np.ascontiguousarray(bk.transpose(0, 2, 1))  # (C, K, M)
        cap = np.full_like(buf, -exp_floor)
        term = np.empty_like(buf)
        for c in range(n_options):
            a = mu[c, voters]  # (V, K)
            kc, bkc, fc = k[c], bk[c], feats[c]
            for r0 in range(0, n_vot, rows):
                r1 = min(r0 + rows, n_vot)
                d = buf[: r1 - r0]
                np.multiply(a[r0:r1, 0, None], kc[0][None, :], out=d)  # a_v·k_i
                np.subtract(d, bkc[0][None, :], out=d)  # (a_v − b_i)·k_i = z/√2
                np.multiply(d, d, out=d)  # z²/2
                for q in range(1, kc.shape[0]):  # further pairs: Σ_q z_q²/2
                    t = term[: r1 - r0]
                    np.multiply(a[r0:r1, q, None], kc[q][None, :], out=t)
                    np.subtract(t, bkc[q][None, :], out=t)
                    np.multiply(t, t, out=t)
                    np.add(d, t, out=d)
                np.minimum(d, cap[: r1 - r0], out=d)  # clamp: exp(−60) ≈ 1e-26
                np.negative(d, out=d)
                np.exp(d, out=d)
                np.matmul(d, fc, out=sums[c, r0:r1])
    s = sums.astype(np.float64).transpose(1, 0, 2)  # (V, C, K)
    out = s / s[..., :1]
    out[..., 0] = s[..., 0]
    return out


def _variance(mom: NDArray[np.float64]) -> NDArray[np.float64]:
    """Trace of the covariance, mm², from the moments (either layout)."""
    m2 = mom[..., 1] ** 2 + mom[..., 2] ** 2
    second = mom[..., 3] if mom.shape[-1] == 4 else mom[..., 3] + mom[..., 4]
    return np.maximum(second - m2, 0.0)


def predicted_variances(
    particles: NDArray,
    weights: NDArray | None,
    mean_V: NDArray,
    std_V: NDArray,
    voters: NDArray[np.intp],
    **kwargs: Any,
) -> NDArray[np.float64]:
    """Weighted variance (trace, mm²) of the re-weighted cloud (V, C): the ``"expected"`` vote's score.

    ``E[s²]`` after resampling M particles is ``(M − 1)/M`` times this for every option, so the argmin
    is the same. Arguments as :func:`weighted_moments` (``kwargs``: its keyword options).
    """
    return _variance(weighted_moments(particles, weights, mean_V, std_V, voters, n_moments=4, **kwargs))


def resampled_variances(moments: NDArray[np.float64], n_resample: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """One draw per voter and option of the variance (mm²) after resampling ``n_resample`` particles.

    ``s² = (1/M)Σ|d_j|² − |d̄|²`` over M roulette-wheel draws is, to the central limit, normal with mean
    ``(M − 1)/M·v`` and variance ``(μ₄ − v²)/M`` (``v = E_w|d|²``, ``μ₄ = E_w|d|⁴``, d = x − x̄_w).

    Args:
        moments: (V, C, 9) from :func:`weighted_moments`.
        n_resample: M, the resampled cloud's size (the belief's particle count).
        rng: the agent's generator (one standard normal per voter and option).
    """
    mom = np.asarray(moments, dtype=np.float64)
    if mom.shape[-1] != N_MOMENTS:
        raise ValueError(f"moments must have {N_MOMENTS} columns (weighted_moments(..., n_moments=9))")
    mx, my = mom[..., 1], mom[..., 2]
    exx, eyy, exy, erx, ery, er4 = (mom[..., k] for k in range(3, 9))
    mm = mx * mx + my * my
    v = np.maximum(exx + eyy - mm, 0.0)
    # E|x − m|⁴ expanded in the centred moments: |d|⁴ = (|x|² − 2x·m + |m|²)².
    mu4 = (
        er4
        - 4.0 * (erx * mx + ery * my)
        + 4.0 * (mx * mx * exx + 2.0 * mx * my * exy + my * my * eyy)
        + 2.0 * (exx + eyy) * mm
        - 3.0 * mm * mm
    )
    sd = np.sqrt(np.maximum(mu4 - v * v, 0.0) / n_resample)
    z = rng.standard_normal(v.shape)
    return np.maximum((n_resample - 1) / n_resample * v + sd * z, 0.0)


def count_votes(variances: NDArray) -> tuple[int, NDArray[np.int64]]:
    """Each voter's ballot goes to its lowest-variance option; returns (winner, votes per option).

    Ties in the count go to the lowest option index (option 0 is "stay").
    """
    ballots = np.argmin(variances, axis=1)
    votes = np.bincount(ballots, minlength=variances.shape[1])
    return int(np.argmax(votes)), votes


class MinVarianceAgent(BaselineAgent):
    """Greedy minimum variance by particle voting (paper §4.1.3 policy #2, Algorithm 1).

    Reads its agent view's ``belief`` (particles, weights), ``predicted_particles_mm``,
    ``predicted_reading_model``, ``gain_levels`` and ``move_bounds_mm`` (or ``position_mm`` and
    ``allowed_box_mm``); never the true target.

    Args:
        seed: seed or generator for the option draws, the voter subset and the resampling draws.
        n_options: options per step including "stay" (paper: 16).
        n_voters: number of particles that vote (a random subset each step); None or ≥ M: all.
            Default 256 (≈ 10× cheaper than all 2500; ``benchmarks/minvar.py`` measures how often the
            choice changes).
        vote: ``"resample"`` (Algorithm 1, default), ``"multinomial"`` (the literal resample, slow) or
            ``"expected"`` (the argmin of the expected variance); see the module docstring.
        chunk_rows: voters per block of the vectorised vote.
        exp_floor: clamp of the Gaussian exponent.
        gain: with dynamic gain (the env's ``gain_levels``): ``"choose"`` (default) votes over the options
            × the gain levels, each reading predicted by the sensor model at that gain; ``"preset"``
            reads at the preset gain (the level nearest to 1).

    Attributes:
        last_votes: votes per option of the last decision.
        last_options_mm: the options (C, 2) of the last decision, mm.
    """

    name = "min-var"

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        n_options: int = 16,
        n_voters: int | None = 256,
        vote: str = "resample",
        chunk_rows: int = 128,
        exp_floor: float = -60.0,
        gain: str = "choose",
    ) -> None:
        super().__init__(seed)
        if isinstance(n_options, bool) or not isinstance(n_options, int) or n_options < 1:
            raise ValueError(f"n_options must be an integer ≥ 1, got {n_options!r}")
        if n_voters is not None and (isinstance(n_voters, bool) or not isinstance(n_voters, int) or n_voters < 1):
            raise ValueError(f"n_voters must be an integer ≥ 1 or None (all particles vote), got {n_voters!r}")
        if vote not in VOTES:
            raise ValueError(f"vote must be one of {list(VOTES)}, got {vote!r}")
        if isinstance(chunk_rows, bool) or not isinstance(chunk_rows, int) or chunk_rows < 1:
            raise ValueError(f"chunk_rows must be an integer ≥ 1, got {chunk_rows!r}")
        if not (isinstance(exp_floor, (int, float)) and -80.0 <= exp_floor < 0):
            raise ValueError(f"exp_floor must be in [-80, 0) (float32 exp underflows below ≈ -87), got {exp_floor!r}")
        if gain not in ("choose", "preset"):
            raise ValueError(f"gain must be 'choose' or 'preset', got {gain!r}")
        self.gain = gain
        self.n_options = n_options
        self.n_voters = n_voters
        self.vote = vote
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
        # The env's own motion rule and frame (ElectroLoc-v0: the target is static; the global env: the
        # hypotheses are the robot's own position and move with it).
        # the vote is on the position variance: columns 0–1 (an unknown target's hypotheses also carry
        # a radius and a contrast, which enter only through the predicted readings)
        moved = env.predicted_particles_mm(particles, options)[..., :2]
        levels = getattr(env, "gain_levels", None)
        n_moves = len(options)
        if levels is not None and self.gain == "choose":  # options × gain levels (§7's dynamic gain)
            preds = [env.predicted_reading_model(particles, options, gain_level=j) for j in range(len(levels))]
            mean = np.concatenate([m for m, _ in preds])
            std = np.concatenate([s for _, s in preds])
            moved = np.concatenate([moved] * len(levels)) if moved.ndim == 3 else moved
        else:
            mean, std = env.predicted_reading_model(particles, options)
        prior = None if uniform else weights
        opts = {"chunk_rows": self.chunk_rows, "exp_floor": self.exp_floor}
        if self.vote == "expected":
            var = predicted_variances(moved, prior, mean, std, voters, **opts)
        elif self.vote == "resample":
            var = resampled_variances(
                weighted_moments(moved, prior, mean, std, voters, **opts), particles.shape[0], self.rng
            )
        else:
            from electroloc_gym.baselines.min_variance_reference import multinomial_resampled_variances

            var = multinomial_resampled_variances(moved, prior, mean, std, voters, self.rng)
        best, votes = count_votes(var)
        self.last_votes, self.last_options_mm = votes, options
        if levels is not None and self.gain == "choose":
            self.gain_level = best // n_moves
        return options[best % n_moves]

    def __repr__(self) -> str:
        return (
            f"MinVarianceAgent(n_options={self.n_options}, n_voters={self.n_voters}, vote={self.vote!r}, "
            f"gain={self.gain!r})"
        )
