"""infotaxis: the greedy controller that maximises the expected reduction of the belief's entropy.

Vergassola, Villermaux & Shraiman, "'Infotaxis' as a strategy for searching without gradients",
Nature 445, 406–409 (2007): the searcher moves where the expected gain of information about the
source's position is largest. Here the source is the target and the information is the entropy of
the env's particle belief; the options are min-var's (paper §4.1.3: stay + 15 moves uniform in the
±10 mm square, drawn from the agent's generator), so the two controllers differ only in what they
score.

**The score.** The belief is M weighted hypotheses ``x_i`` (weights ``w_i``; uniform after every update
of the env's filter). After option c the reading of hypothesis i is ``z ~ N(μ_ci, σ_ci²)`` (the env's
``predicted_reading_model``: the sensor model's mean and std, the env's motion rule applied). A reading
z re-weights the cloud to ``w'_i(z) ∝ w_i N(z; μ_ci, σ_ci²)``; its entropy is
``H(w') = −Σ w'_i ln w'_i`` (nats). The option's score is the expected entropy reduction

    ΔH_c = H(w) − E_z[H(w'(z))],   z drawn from the belief's own predictive distribution,

the mutual information between the next reading and the hypothesis. The expectation over z is a sum
over ``n_voters`` hypotheses drawn from the belief (the agent's generator; all of them if
``n_voters ≥ M``) and, for each, Gauss–Hermite quadrature with ``nodes`` points over its reading noise
(``z = μ_cv + √2 σ_cv t_q``, weights ``ω_q/√π``), exact for noise-free predictions and for every
polynomial of degree < 2·nodes in z. The posterior entropy is computed in the log domain over the
cloud's hypotheses. An option whose predicted readings are all equal leaves every w' equal to w: its ΔH is
exactly 0 (the prior's entropy is computed by the same function of the same log-weights).

Vergassola et al.'s second term — the chance of stepping onto the source, which ends the search —
has no counterpart here: the episode ends when the belief is tight, not when the carriage reaches the
target. The move with the largest ΔH wins; exact ties (a blind belief) go to a uniform draw among them.

**Cost.** Per option an (n_voters·nodes, M) float32 matrix of log-likelihoods. Over the whole
2500-particle belief that is 15·10⁶ exponentials per decision (≈ 0.4 s here); the entropy is therefore
measured over ``n_particles`` (500) hypotheses drawn from the belief afresh each decision, as the
look-ahead planner plans on a subsample: 128 voters × 3 nodes × 500 × 16 options = 3·10⁶, ≈ 0.1 s,
the order of min-var's vote (``benchmarks/decision_time.py``). Options are processed one at a time.

**Envs.** The belief must be over the target: ``ElectroLoc-v0`` (also with dynamic gain; the agent
reads at the preset gain) and ``ElectroLocUnknownTarget-v0`` (the entropy of the 4-D hypotheses
(x, y, radius, χ)). ``ElectroLocGlobal-v0``'s belief is over the robot's own position; the agent
refuses it (:func:`require_target_belief`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import (  # require_target_belief: re-exported
    BaselineAgent,
    move_bounds_mm,
    require_target_belief,
    sample_belief,
    sample_options_mm,
)
from electroloc_gym.utils.checks import check_int

__all__ = [
    "InfotaxisAgent",
    "require_target_belief",
    "log_weight_entropy",
    "expected_entropy_reduction",
    "gauss_hermite",
]

#: Largest Gauss–Hermite rule offered (the readings' noise is Gaussian; a few nodes are exact enough).
MAX_NODES = 16


def gauss_hermite(nodes: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Standard-normal quadrature: offsets ``√2·t_q`` (in σ) and weights ``ω_q/√π`` (summing to 1)."""
    t, w = np.polynomial.hermite.hermgauss(nodes)
    return np.sqrt(2.0) * t, w / np.sqrt(np.pi)


def log_weight_entropy(log_w: NDArray) -> NDArray[np.float64]:
    """Entropy (nats) of the normalised weights ∝ exp(log_w) along the last axis.

    ``H = ln Z − Σ_i p_i (ℓ_i − m)`` with ``m = max ℓ``, ``Z = Σ exp(ℓ_i − m)``, ``p = exp(ℓ − m)/Z``:
    no underflow however sharp the weights; −inf log-weights count as zero weight.
    """
    ll = np.asarray(log_w, dtype=np.float64)
    shifted = ll - ll.max(axis=-1, keepdims=True)
    e = np.exp(shifted)
    z = e.sum(axis=-1)
    terms = e * np.where(e > 0.0, shifted, 0.0)
    return np.log(z) - terms.sum(axis=-1) / z


def expected_entropy_reduction(
    mean_V: NDArray, std_V: NDArray, weights: NDArray | None, voters: NDArray[np.intp], nodes: int = 3
) -> NDArray[np.float64]:
    """ΔH (C,), nats: each option's expected reduction of the belief's entropy (module docstring).

    Args:
        mean_V: (C, M) predicted mean reading of every hypothesis under every option, V.
        std_V: (C, M) its std, V (> 0).
        weights: (M,) the belief's weights (None: uniform).
        voters: (V,) indices of the hypotheses whose readings the expectation runs over (their own
            weights weight them).
        nodes: Gauss–Hermite points per voter (1: the noise-free prediction only).

    Returns:
        (C,) expected entropy reductions (≥ 0 up to the sampling of the voters; exactly 0 for an option
        whose predictions are all equal).
    """
    mu = np.asarray(mean_V, dtype=np.float64)
    sd = np.asarray(std_V, dtype=np.float64)
    if mu.ndim != 2 or sd.shape != mu.shape:
        raise ValueError(f"mean_V and std_V must both have shape (C, M), got {mu.shape} and {sd.shape}")
    if not np.all(sd > 0):
        raise ValueError("std_V must be > 0")
    m = mu.shape[1]
    w = np.full(m, 1.0 / m) if weights is None else np.asarray(weights, dtype=np.float64)
    if not np.all(w > 0):
        raise ValueError("weights must be > 0")
    voters = np.asarray(voters, dtype=np.intp)
    offsets, quad = gauss_hermite(int(nodes))
    wv = w[voters] / w[voters].sum()
    node_weight = (wv[:, None] * quad[None, :]).ravel()  # (V·Q,)
    f32 = np.float32
    log_w = np.log(w)
    prior_entropy = float(_entropy_inplace(log_w.astype(f32)[None, :])[0])
    rows = voters.size * offsets.size
    buf = np.empty((rows, m), dtype=f32)
    out = np.empty(mu.shape[0])
    for c in range(mu.shape[0]):  # one option at a time (memory)
        z = (mu[c, voters, None] + sd[c, voters, None] * offsets[None, :]).ravel()  # (V·Q,)
        k = (np.sqrt(0.5) / sd[c]).astype(f32)  # r²/2 = ((z − μ)·k)²
        a = (log_w - np.log(sd[c])).astype(f32)  # ln w_i − ln σ_i
        np.subtract(z.astype(f32)[:, None], mu[c].astype(f32)[None, :], out=buf)
        buf *= k
        np.square(buf, out=buf)
        np.subtract(a[None, :], buf, out=buf)  # log posterior weights + const
        out[c] = float(node_weight @ (prior_entropy - _entropy_inplace(buf)))  # per reading: exact 0s stay 0
    return out


def _entropy_inplace(log_w: NDArray[np.float32]) -> NDArray[np.float64]:
    """:func:`log_weight_entropy` of the rows of a float32 buffer, overwriting it (finite log-weights)."""
    log_w -= log_w.max(axis=1, keepdims=True)
    shifted_dot = np.empty(log_w.shape[0], dtype=np.float64)
    e = np.exp(log_w)
    z = e.sum(axis=1, dtype=np.float64)
    shifted_dot[:] = np.einsum("ij,ij->i", e, log_w, dtype=np.float64)
    return np.log(z) - shifted_dot / z


class InfotaxisAgent(BaselineAgent):
    """Greedy expected entropy reduction over the paper's 16 options (module docstring).

    Reads its agent view's ``belief``, ``belief_frame``, ``predicted_reading_model`` and ``move_bounds_mm``
    (or ``position_mm`` and ``allowed_box_mm``); never the true target.

    Args:
        seed: seed or generator of the options, the voters and the tie breaks.
        n_options: options per step including "stay" (paper: 16).
        n_particles: hypotheses the entropy is measured over: a random subset of the belief each step
            (None or ≥ M: the whole belief). Default 500.
        n_voters: hypotheses of that cloud whose readings the expectation runs over (a random subset each
            step; None or ≥ the cloud: all). Default 128.
        nodes: Gauss–Hermite points over each voter's reading noise (1–16; default 3).

    Attributes:
        last_gains: each option's expected entropy reduction of the last decision, nats.
        last_options_mm: the options (C, 2) of the last decision, mm.
    """

    name = "infotaxis"
    #: The score reads one pair's (C, M) predictions: the paper's single pair only.
    sensor_layouts = ("single",)

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        n_options: int = 16,
        n_particles: int | None = 500,
        n_voters: int | None = 128,
        nodes: int = 3,
    ) -> None:
        super().__init__(seed)
        self.n_options = check_int("n_options", n_options, 1)
        self.n_particles = None if n_particles is None else check_int("n_particles", n_particles, 2)
        self.n_voters = None if n_voters is None else check_int("n_voters", n_voters, 1)
        self.nodes = check_int("nodes", nodes, 1, MAX_NODES)
        self.last_gains: NDArray[np.float64] | None = None
        self.last_options_mm: NDArray[np.float64] | None = None

    def reset(self, env: Any) -> None:
        super().reset(env)
        require_target_belief(self.env, self.name)

    def memory_bytes(self, n_particles: int) -> int:
        """Peak memory of one decision with a belief of ``n_particles``, bytes: the options' float64
        predicted means and deviations and their moved hypotheses (C, S) — ≈ 32 bytes per (option,
        hypothesis) — and two float32 (V·Q, S) buffers of one option's log-weights, with S the measured
        cloud, V its voters and Q the quadrature nodes.
        """
        s = int(n_particles) if self.n_particles is None else min(self.n_particles, int(n_particles))
        v = s if self.n_voters is None else min(self.n_voters, s)
        return 32 * self.n_options * s + 8 * v * self.nodes * s

    def _cloud(self) -> tuple[NDArray, NDArray[np.float64] | None]:
        """The hypotheses the entropy is measured over: the belief, or ``n_particles`` drawn from it."""
        return sample_belief(self.env.belief, self.n_particles, self.rng, keep_weights=True)

    def choose_move_mm(self) -> NDArray[np.float64]:
        env = self.env
        options = sample_options_mm(self.rng, *move_bounds_mm(env), self.n_options)
        x, weights = self._cloud()
        s = x.shape[0]
        if self.n_voters is None or self.n_voters >= s:
            voters = np.arange(s)
        else:
            voters = np.sort(self.rng.choice(s, size=self.n_voters, replace=False))
        mean, std = env.predicted_reading_model(x, options)
        gains = expected_entropy_reduction(mean, std, weights, voters, self.nodes)
        best = np.flatnonzero(gains >= gains.max() - 1e-12 * max(abs(gains.max()), 1.0))
        choice = int(best[0]) if best.size == 1 else int(self.rng.choice(best))
        self.last_gains, self.last_options_mm = gains, options
        return options[choice]

    def __repr__(self) -> str:
        return (
            f"InfotaxisAgent(n_options={self.n_options}, n_particles={self.n_particles}, "
            f"n_voters={self.n_voters}, nodes={self.nodes})"
        )
