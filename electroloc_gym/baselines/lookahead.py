"""lookahead: a belief-space look-ahead planner over sequences of moves (beyond the paper, §7).

The paper's controllers never look past one step; §7 asks for a controller that does, with "a limited
number of lookahead steps" and "heuristics to select which paths to evaluate". This agent is a
sparse-sampling planner over the particle belief that uses only the env's public accessors (as
min-var does): ``belief.particles``/``weights``, ``predicted_reading_model``,
``predicted_particles_mm``, ``position_mm``/``allowed_box_mm``, ``success_spread_mm`` and the move
bounds.

**One decision.**

1. Subsample ``n_particles`` hypotheses from the belief (by weight; the subsample then has uniform
   weights): the planner's cloud ``X`` (S, 2), mm.
2. Draw ``n_options`` first moves: stay, the eight full-range *compass* moves (±10 mm on one or both
   axes, clipped to the move bounds; ``compass=True``), and uniform moves in the ±10 mm square within
   the move bounds for the rest (:func:`~electroloc_gym.baselines.agent.sample_options_mm`;
   ``compass=False`` gives the paper's stay + uniform options). Draw ``continuations`` continuation
   sequences of ``depth − 1`` further moves, shared by every first move (every first move is judged
   on the same continuations). ``cont="compass"``: distinct sequences of compass moves, as many of
   the 8^(depth−1) as ``continuations`` allows; ``cont="uniform"``: uniform in ±10 mm. A sequence is
   a first move plus one continuation: C·K sequences of ``depth`` moves.
3. Draw ``branches`` hypothetical futures: a hypothesis ``h`` from ``X`` and one standard-normal
   noise draw per step; in the future ``b`` of a sequence the readings are ``μ_t(x_h) + σ_t(x_h)·ε_bt``
   (the sensor model's mean and std of that hypothesis after the t-th move). The same futures serve
   every sequence (common random numbers: the sequences are compared on equal draws).
4. Re-weight ``X`` by the likelihood of each future's readings, ``Π_t N(z_t; μ_t(x_i), σ_t(x_i)²)``,
   and score the future with the ``objective``
   (:mod:`~electroloc_gym.baselines.lookahead_objectives`): ``"steps"`` (default), the expected
   number of further readings until the env's success rule (posterior spread √trace Σ ≤
   ``success_spread_mm``) holds, with a tail of ``1 + tail·ln(s_T / success_spread_mm)`` readings
   for a future still short of it after the last move; ``"spread"``, the posterior spread after the
   sequence (mm); ``"logspread"``, its logarithm; ``"entropy"``, the entropy of the re-weighted
   cloud's weights.
5. A sequence's objective is its mean over the futures; a first move's score is the best (lowest)
   objective of its continuations (open loop: one continuation for all futures); the move with the
   lowest score is taken (ties broken at random). ``closed=True`` (depth 2) chooses the second move
   after the first reading instead: for each first move and future, ``inner`` further futures draw a
   hypothesis from the posterior after the first reading, and the first move scores
   ``E_{z₁}[c₁ + min_{u₂} E_{z₂|z₁}[c₂]]`` (:func:`~electroloc_gym.baselines.lookahead_objectives.adaptive_costs`).

Why these defaults (measured in the global env, where §6.5 says greedy min-var "had trouble
disambiguating the multiple hypotheses"; docs/baselines.md has the figures): the readings of the
mapped tank carry information only near the cylinders, so a short move from a flat region learns
little, and the full-range compass moves are what let the planner separate the modes of the belief.
``"steps"`` counts a sequence that succeeds after its first move as better than one that merely ends
narrower, which the posterior spread after the last move does not see.

**Budget.** One *round* is steps 2–5 with fresh continuations and futures; a first move's score is
averaged over rounds. ``rounds`` is the simulation budget (deterministic: decisions depend only on the
agent's seed). With ``budget_s`` set, further rounds run while the decision's wall time is below it
(at most ``max_rounds``); the number of rounds then depends on the machine, so decisions are
reproducible only with ``budget_s=None``.

**Motion rule.** In ElectroLoc-v0 the target is static: the reading after a sequence is the reading of
hypothesis ``x`` from the carriage at ``p + D`` (D the cumulative move, the carriage kept in the allowed
box as the env keeps it), which the sensor models (functions of the offset target − carriage) give
as ``predicted_reading_model(x − D, 0)``. In ElectroLocGlobal-v0 the hypotheses are the robot's own
position and move with it: each step applies ``predicted_particles_mm`` and asks
``predicted_reading_model`` of the moved hypotheses. The agent tells the two apart by whether
``predicted_particles_mm`` moves the hypotheses.

**Vectorisation.** Readings of all C·K sequences × S hypotheses come from one accessor call per step
(static target: one call in all); the likelihoods and objectives are (B, C, K, S) array operations; the
only Python loops are over the ≤ 3 steps and, in the third step of the global env, over its distinct
moves (one accessor call per move: ≤ 8 with compass continuations).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import MAX_STEP_MM, BaselineAgent, move_bounds_mm, sample_belief, sample_options_mm
from electroloc_gym.baselines.lookahead_objectives import OBJECTIVES, adaptive_costs, posterior_spreads, sequence_costs
from electroloc_gym.protocol import SUCCESS_SPREAD_MM
from electroloc_gym.utils.checks import check_int

__all__ = ["LookaheadAgent", "posterior_spreads", "MAX_DEPTH", "COMPASS_MM", "CONTINUATIONS", "OBJECTIVES"]

#: Longest sequence the planner evaluates.
MAX_DEPTH = 3
#: How continuation moves are drawn: uniform in ±10 mm, or one of the compass moves per step.
CONTINUATIONS = ("uniform", "compass")
#: The eight full-range moves (``compass=True``), mm: the four diagonals first, then the four axes.
COMPASS_MM = MAX_STEP_MM * np.array(
    [[1, 1], [-1, 1], [-1, -1], [1, -1], [1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.float64
)


class LookaheadAgent(BaselineAgent):
    """Belief-space look-ahead over sequences of ``depth`` moves (see the module docstring).

    Args:
        seed: seed or generator of every draw (subsample, moves, futures).
        depth: moves per evaluated sequence, 1–3 (1: a greedy controller on the same objective).
        n_options: first moves per decision including "stay" (paper: 16; default 9: stay + the compass).
        continuations: continuation sequences per round (shared by all first moves).
        branches: sampled futures (hypothesis + reading noise) per round.
        n_particles: size of the planner's subsample of the belief (its cloud).
        rounds: rounds per decision (the simulation budget).
        budget_s: wall-time budget per decision, s: further rounds while below it (None: ``rounds`` only).
        max_rounds: cap on the rounds a time budget may run.
        objective: ``"steps"``, ``"spread"``, ``"logspread"`` or ``"entropy"``
            (:data:`~electroloc_gym.baselines.lookahead_objectives.OBJECTIVES`).
        tail: ``"steps"``' tail, readings per unit of ln(spread / success spread) (0–100).
        compass: include the eight full-range moves among the first moves.
        cont: continuation moves, ``"compass"`` or ``"uniform"`` (:data:`CONTINUATIONS`).
        closed: depth 2 only: choose the second move after the first reading (closed loop).
        inner: ``closed``'s futures per first reading (1–256).

    Attributes:
        last_scores: each first move's score of the last decision, in the objective's unit
            (readings, mm, ln mm or nats).
        last_options_mm: the first moves (C, 2) of the last decision, mm.
        last_rounds: rounds run in the last decision.
    """

    name = "lookahead"

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        depth: int = 2,
        n_options: int = 9,
        continuations: int = 8,
        branches: int = 8,
        n_particles: int = 300,
        rounds: int = 1,
        budget_s: float | None = None,
        max_rounds: int = 64,
        objective: str = "steps",
        tail: float = 0.5,
        compass: bool = True,
        cont: str = "compass",
        closed: bool = False,
        inner: int = 8,
    ) -> None:
        super().__init__(seed)
        self.depth = check_int("depth", depth, 1, MAX_DEPTH)
        self.n_options = check_int("n_options", n_options, 1, 256)
        self.continuations = check_int("continuations", continuations, 1, 256)
        self.branches = check_int("branches", branches, 1, 1024)
        self.n_particles = check_int("n_particles", n_particles, 2, 100_000)
        self.rounds = check_int("rounds", rounds, 1, 1024)
        self.max_rounds = check_int("max_rounds", max_rounds, 1, 4096)
        if budget_s is not None and (
            isinstance(budget_s, bool)
            or not isinstance(budget_s, (int, float))
            or not math.isfinite(budget_s)
            or not 0 < budget_s <= 60
        ):
            raise ValueError(f"budget_s must be a number of seconds in (0, 60] or None, got {budget_s!r}")
        self.budget_s = None if budget_s is None else float(budget_s)
        if objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {list(OBJECTIVES)}, got {objective!r}")
        self.objective = objective
        if (
            isinstance(tail, bool)
            or not isinstance(tail, (int, float))
            or not math.isfinite(tail)
            or not 0 <= tail <= 100
        ):
            raise ValueError(f"tail must be a number of readings in [0, 100], got {tail!r}")
        self.tail = float(tail)
        if not isinstance(compass, bool):
            raise ValueError(f"compass must be True or False, got {compass!r}")
        self.compass = compass
        if cont not in CONTINUATIONS:
            raise ValueError(f"cont must be one of {list(CONTINUATIONS)}, got {cont!r}")
        self.cont = cont
        if not isinstance(closed, bool):
            raise ValueError(f"closed must be True or False, got {closed!r}")
        if closed and self.depth != 2:
            raise ValueError(f"closed=True needs depth=2, got depth={self.depth}")
        self.closed = closed
        self.inner = check_int("inner", inner, 1, 256)
        self.last_scores: NDArray[np.float64] | None = None
        self.last_options_mm: NDArray[np.float64] | None = None
        self.last_rounds = 0

    def reset(self, env: Any) -> None:
        """Bind to ``env``'s agent view.

        Raises:
            ValueError: an env of another sensor layout, or hypotheses that are not positions (M, 2).
        """
        super().reset(env)
        self._require_positions(np.shape(self.env.belief.particles))

    @staticmethod
    def _require_positions(shape: tuple[int, ...]) -> None:
        if len(shape) != 2 or shape[1] != 2:
            raise ValueError(
                f"lookahead plans over position hypotheses (M, 2); this env's are {shape} "
                "(ElectroLocUnknownTarget-v0's carry a radius and a contrast, ElectroLocTrack-v0's with "
                "motion_model='swimmer' a speed and a heading): use min-var there"
            )

    def _success_spread_mm(self) -> float:
        return float(getattr(self.env, "success_spread_mm", SUCCESS_SPREAD_MM))

    # ---- the planner's cloud and motion ---------------------------------------------------------
    def _subsample(self) -> NDArray[np.float64]:
        belief = self.env.belief
        x = np.asarray(belief.particles, dtype=np.float64)
        self._require_positions(x.shape)
        return sample_belief(belief, self.n_particles, self.rng)[0].astype(np.float64, copy=False)

    def _moves_with_robot(self) -> bool:
        """Whether the belief is over the robot's own position (the env's ``belief_frame``)."""
        return bool(self.env.belief_frame == "robot")

    def _readings_static(self, x: NDArray, first: NDArray, cont: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Static target: (T, C·K, S) mean/std from the carriage at p + D_t (kept in the box)."""
        env = self.env
        p = np.asarray(env.position_mm, dtype=np.float64)
        low, high = (np.asarray(b, dtype=np.float64) for b in env.allowed_box_mm)
        c, k = first.shape[0], cont.shape[0]
        steps = [np.broadcast_to(first[:, None, :], (c, k, 2))]
        steps += [np.broadcast_to(cont[None, :, t, :], (c, k, 2)) for t in range(cont.shape[1])]
        carriage, d = p, []
        for u in steps:  # a handful of steps (≤ MAX_DEPTH)
            carriage = np.clip(carriage + u, low, high)
            d.append(carriage - p)
        disp = np.stack(d).reshape(len(steps), c * k, 1, 2)  # (T, N, 1, 2)
        shifted = (x[None, None, :, :] - disp).reshape(-1, 2).astype(np.float32)
        mean, std = env.predicted_reading_model(shifted, np.zeros(2))
        shape = (len(steps), c * k, x.shape[0]) + np.shape(mean)[1:]  # a sensor array: K readings, last axis
        return np.asarray(mean).reshape(shape), np.asarray(std).reshape(shape), x

    def _readings_moving(self, x: NDArray, first: NDArray, cont: NDArray) -> tuple[NDArray, NDArray, list[NDArray]]:
        """Hypotheses that move with the robot: (T, C·K, S) mean/std and the (C·K, S, 2) cloud after each move."""
        env = self.env
        c, k, s = first.shape[0], cont.shape[0], x.shape[0]
        xf = x.astype(np.float32)
        m0, s0 = (np.asarray(a) for a in env.predicted_reading_model(xf, first))  # (C, S)
        q = np.asarray(env.predicted_particles_mm(xf, first))  # (C, S, 2)
        means = [np.repeat(m0, k, axis=0)]
        stds = [np.repeat(s0, k, axis=0)]
        clouds = [np.repeat(q, k, axis=0)]
        if cont.shape[1] == 0:
            return np.stack(means), np.stack(stds), clouds
        qf = q.reshape(c * s, 2)
        m1, s1 = (np.asarray(a).reshape(k, c, s) for a in env.predicted_reading_model(qf, cont[:, 0]))
        q = np.asarray(env.predicted_particles_mm(qf, cont[:, 0])).reshape(k, c, s, 2)
        means.append(m1.transpose(1, 0, 2).reshape(c * k, s))
        stds.append(s1.transpose(1, 0, 2).reshape(c * k, s))
        clouds.append(q.transpose(1, 0, 2, 3).reshape(c * k, s, 2))
        for t in range(1, cont.shape[1]):  # later steps: one call per distinct move
            moves, group = np.unique(cont[:, t], axis=0, return_inverse=True)
            mt, st, qt = np.empty((k, c, s)), np.empty((k, c, s)), np.empty((k, c, s, 2))
            for g, u in enumerate(moves):  # ≤ 8 compass moves (≤ K uniform ones)
                js = np.flatnonzero(group.ravel() == g)
                pts = q[js].reshape(-1, 2)
                a, b = env.predicted_reading_model(pts, u)
                mt[js] = np.asarray(a).reshape(js.size, c, s)
                st[js] = np.asarray(b).reshape(js.size, c, s)
                qt[js] = np.asarray(env.predicted_particles_mm(pts, u)).reshape(js.size, c, s, 2)
            means.append(mt.transpose(1, 0, 2).reshape(c * k, s))
            stds.append(st.transpose(1, 0, 2).reshape(c * k, s))
            q = qt
            clouds.append(q.transpose(1, 0, 2, 3).reshape(c * k, s, 2))
        return np.stack(means), np.stack(stds), clouds

    def _pair_axis(self) -> tuple[int, ...]:
        """() for one reading per step; (K,) for a sensor array of K pairs (each reading its own noise)."""
        layout = getattr(self.env, "sensor_layout", None)
        k = 1 if layout is None else layout.n_pairs
        if k > 1 and self.closed:
            raise ValueError("lookahead closed=True plans one reading per step; with a sensor array use closed=False")
        return (k,) if k > 1 else ()

    def _first_moves(self) -> NDArray[np.float64]:
        """The first-move options (C, 2), mm: stay, the compass moves if asked, then uniform moves."""
        lo, hi = move_bounds_mm(self.env)
        first = sample_options_mm(self.rng, lo, hi, self.n_options)
        if self.compass and self.n_options > 1:
            n = min(len(COMPASS_MM), self.n_options - 1)
            first[1 : 1 + n] = np.clip(COMPASS_MM[:n], lo, hi)
        return first

    # ---- one decision ---------------------------------------------------------------------------
    def _round(self, x: NDArray, first: NDArray, moving: bool) -> NDArray[np.float64]:
        """One round: each first move's best expected objective (C,)."""
        k = self.continuations if self.depth > 1 else 1
        if self.cont == "compass":
            n_seq = len(COMPASS_MM) ** (self.depth - 1)  # every compass sequence once, as far as k allows
            pick = self.rng.permutation(n_seq)[:k] if k <= n_seq else self.rng.integers(0, n_seq, size=k)
            digits = (pick[:, None] // len(COMPASS_MM) ** np.arange(self.depth - 1)) % len(COMPASS_MM)
            cont = COMPASS_MM[digits]
        else:
            cont = self.rng.uniform(-MAX_STEP_MM, MAX_STEP_MM, size=(k, self.depth - 1, 2))
        hyp = self.rng.integers(0, x.shape[0], size=self.branches)
        eps = self.rng.standard_normal((self.branches, self.depth) + self._pair_axis())
        reader = self._readings_moving if moving else self._readings_static
        mean, std, clouds = reader(x, first, cont)
        if self.closed:
            u_inner = self.rng.random((self.branches, self.inner))
            eps2 = self.rng.standard_normal((self.branches, self.inner))
            return adaptive_costs(
                mean,
                std,
                clouds,
                first.shape[0],
                hyp,
                eps[:, 0],
                u_inner,
                eps2,
                self.objective,
                success_spread_mm=self._success_spread_mm(),
                tail=self.tail,
            )
        cost = sequence_costs(
            mean, std, clouds, hyp, eps, self.objective, success_spread_mm=self._success_spread_mm(), tail=self.tail
        )  # (B, C·K)
        return cost.mean(axis=0).reshape(first.shape[0], k).min(axis=1)

    def choose_move_mm(self) -> NDArray[np.float64]:
        t0 = time.perf_counter()
        x = self._subsample()
        first = self._first_moves()
        moving = self._moves_with_robot()
        total = np.zeros(first.shape[0])
        n = 0
        while True:
            total += self._round(x, first, moving)
            n += 1
            if n >= self.max_rounds or (
                n >= self.rounds and (self.budget_s is None or time.perf_counter() - t0 >= self.budget_s)
            ):
                break
        scores = total / n
        best = np.flatnonzero(scores <= scores.min() * (1.0 + 1e-9) + 1e-12)
        choice = int(best[0]) if best.size == 1 else int(self.rng.choice(best))
        self.last_scores, self.last_options_mm, self.last_rounds = scores, first, n
        return first[choice]

    def __repr__(self) -> str:
        return (
            f"LookaheadAgent(depth={self.depth}, n_options={self.n_options}, continuations={self.continuations}, "
            f"branches={self.branches}, n_particles={self.n_particles}, rounds={self.rounds}, "
            f"budget_s={self.budget_s}, objective={self.objective!r}, tail={self.tail}, "
            f"compass={self.compass}, cont={self.cont!r})"
        )
