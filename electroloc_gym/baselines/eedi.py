"""eedi: ergodic exploration of the expected information density (Miller et al. 2016) by SMC feedback.

Miller, Silverman, MacIver & Murphey, "Ergodic Exploration of Distributed Information", IEEE T-RO 32(1),
2016, localise targets with an electrolocation robot by driving the sensor along a trajectory whose
time average matches the *expected information density* (EID) of the belief: the robot spends time in
proportion to how much a reading there is expected to tell about the target's position. Exploration
(a diffuse belief spreads the EID) and exploitation (a tight belief concentrates it) are one objective.

**Each decision** (helpers in :mod:`electroloc_gym.baselines.ergodic`):

1. every ``update_period`` readings, the EID over the allowed box: a grid of cells of ≤ ``grid_mm``;
   ``n_particles`` hypotheses drawn from the belief (the agent's generator); each one's reading from
   every cell centre through the env's own sensor model (``predicted_reading_model`` of the
   hypotheses shifted by the carriage's displacement — the sensor models are functions of target −
   carriage, as the look-ahead planner uses them); the belief-averaged Fisher information about the
   target's position; its determinant (``criterion``), normalised to integrate to 1; its cosine
   coefficients φ_k (``n_coefficients`` per axis);
2. the SMC feedback law of Mathew & Mezić (2011) on the carriage's reading positions this episode
   (the env's ``path_mm``): the move goes along −B, B = Σ Λ_k S_k ∇F_k(x_T), as long as the paper's
   limit allows — the larger component 10 mm (§4.1.3: ≤ 10 mm per axis per step) — and kept in the
   allowed box (``move_bounds_mm``). If B vanishes (the trajectory already matches the EID to
   rounding) a uniform move in ±10 mm is drawn.

**Why SMC and not Miller's receding-horizon trajectory optimisation.** The carriage is a first-order
system (a commanded displacement per reading), exactly the dynamics of Mathew & Mezić's closed-form
law, which needs one pass over the coefficients per step and no inner optimiser; Miller et al.'s
projection-based optimisation earns its cost on robots with second-order or nonholonomic dynamics
and continuous sampling, and would add an optimiser's iteration count, step size and horizon to the
parameters on episodes that last ≈ 5–35 readings. The horizon of SMC is the whole episode so far (its
memory S_k); the controller looks no further ahead than one step.

**Parameters** (chosen on validation seeds 101 and 102, docs/baselines.md): ``n_coefficients = 10``
per axis (wavelengths down to 2L/9 ≈ 22 mm in the 100 mm box: the scale of one move pair and of the
EEV's lobes), ``grid_mm = 5`` (400–576 cells), ``n_particles = 200`` hypotheses for the EID,
``update_period = 1`` (the belief changes most in the first readings), ``step_mm = 1`` (central
differences; the calibrated model's grid is 4 mm).

**Envs.** ``ElectroLoc-v0`` (also with dynamic gain, read at the preset gain) and
``ElectroLocUnknownTarget-v0`` (the Fisher information about the (x, y) of its 4-D hypotheses); it
refuses ``ElectroLocGlobal-v0``, whose belief is the robot's own position.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import (
    MAX_STEP_MM,
    BaselineAgent,
    move_bounds_mm,
    require_target_belief,
    sample_belief,
)
from electroloc_gym.baselines.ergodic import (
    CRITERIA,
    CosineBasis,
    belief_fisher_information,
    information_density,
    workspace_grid,
)
from electroloc_gym.utils.checks import check_float, check_int

__all__ = ["EEDIAgent"]


#: Side of the largest allowed box of the presets, mm (the 38.1 mm spheres' ±60 mm).
_BOX_SIDE_MM = 120.0
#: Memory per sensor-model evaluation of an EID update, bytes (the (x, y) hypothesis, mean, deviation and
#: the sensor model's float64 temporaries).
_BYTES_PER_EVALUATION = 96
#: Time per sensor-model evaluation of an EID update on one core, s (order of magnitude).
_SECONDS_PER_EVALUATION = 5e-7


class EEDIAgent(BaselineAgent):
    """Ergodic exploration of the expected information density (module docstring).

    Args:
        seed: seed or generator of the EID's hypotheses and the fallback moves.
        n_coefficients: cosine coefficients per axis K (K² in all), 2–32.
        grid_mm: largest side of an EID cell, mm (1–20).
        n_particles: hypotheses drawn from the belief for the EID, 1–5000.
        update_period: readings between EID updates, 1–35.
        criterion: ``"det"`` (Miller et al.) or ``"trace"`` of the belief-averaged Fisher information.
        step_mm: central-difference step of the reading's gradient, mm (0–5].

    Attributes:
        last_density: the EID (G,) of the last update, 1/mm²; ``last_grid_mm`` its cell centres (G, 2).
        last_direction: B of the last decision (the move goes along −B).
    """

    name = "eedi"
    #: The Fisher information is of one pair's (N, S) readings: the paper's single pair only.
    sensor_layouts = ("single",)

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        n_coefficients: int = 10,
        grid_mm: float = 5.0,
        n_particles: int = 200,
        update_period: int = 1,
        criterion: str = "det",
        step_mm: float = 1.0,
    ) -> None:
        super().__init__(seed)
        self.n_coefficients = check_int("n_coefficients", n_coefficients, 2, 32)
        self.grid_mm = check_float("grid_mm", grid_mm, 1.0, inclusive=True, high=20.0)
        self.n_particles = check_int("n_particles", n_particles, 1, 5000)
        self.update_period = check_int("update_period", update_period, 1, 35)
        if criterion not in CRITERIA:
            raise ValueError(f"criterion must be one of {list(CRITERIA)}, got {criterion!r}")
        self.criterion = criterion
        self.step_mm = check_float("step_mm", step_mm, 0.0, high=5.0)
        self.last_density: NDArray[np.float64] | None = None
        self.last_grid_mm: NDArray[np.float64] | None = None
        self.last_direction: NDArray[np.float64] | None = None
        self._basis: CosineBasis | None = None
        self._phi_k: NDArray[np.float64] | None = None
        self._updated_at = -1

    def reset(self, env: Any) -> None:
        super().reset(env)
        require_target_belief(self.env, self.name)
        self._phi_k = None
        self._updated_at = -1

    # ---- cost ---------------------------------------------------------------------------------
    def _evaluations(self, n_particles: int) -> int:
        """Sensor-model evaluations of one EID update: 4 shifted carriages per cell of the grid over the
        largest allowed box of the presets (:data:`_BOX_SIDE_MM` a side), times the hypotheses.
        """
        cells = math.ceil(_BOX_SIDE_MM / self.grid_mm) ** 2
        return 4 * cells * min(self.n_particles, int(n_particles))

    def memory_bytes(self, n_particles: int) -> int:
        """Peak memory of one EID update, bytes: per evaluation the shifted (x, y) hypothesis and the
        float64 mean and deviation with the sensor model's temporaries, ≈ :data:`_BYTES_PER_EVALUATION`.
        """
        return _BYTES_PER_EVALUATION * self._evaluations(n_particles)

    def decision_seconds(self, n_particles: int) -> float:
        """Estimated time of one decision that updates the EID, s (:data:`_SECONDS_PER_EVALUATION` per
        sensor-model evaluation, measured on one core with the calibrated model).
        """
        return _SECONDS_PER_EVALUATION * self._evaluations(n_particles)

    # ---- the EID ------------------------------------------------------------------------------
    def _hypotheses(self) -> NDArray:
        return sample_belief(self.env.belief, self.n_particles, self.rng)[0]

    def _reading_fn(self, x: NDArray) -> Any:
        """The reading function: carriages (N, 2) → (mean, std) (N, S) of the hypotheses ``x`` (S, d) read there."""
        env = self.env
        p = np.asarray(env.position_mm, dtype=np.float64)
        zero = np.zeros(2)

        def readings(carriages: NDArray) -> tuple[NDArray, NDArray]:
            n, s = carriages.shape[0], x.shape[0]
            h = np.repeat(x[None], n, axis=0)
            h[..., :2] -= (carriages - p).astype(x.dtype)[:, None, :]  # target − q = (θ − (q − p)) − p
            mean, std = env.predicted_reading_model(h.reshape(n * s, x.shape[1]), zero)
            return np.asarray(mean).reshape(n, s), np.asarray(std).reshape(n, s)

        return readings

    def update_density(self) -> None:
        """Recompute the EID and its coefficients from the current belief."""
        low, high = (np.asarray(b, dtype=np.float64) for b in self.env.allowed_box_mm)
        if self._basis is None or self._basis.low_mm != tuple(low) or self._basis.high_mm != tuple(high):
            self._basis = CosineBasis(tuple(low), tuple(high), self.n_coefficients)
        grid, area = workspace_grid(low, high, self.grid_mm)
        fisher = belief_fisher_information(self._reading_fn(self._hypotheses()), grid, self.step_mm)
        density = information_density(fisher, area, self.criterion)
        self._phi_k = self._basis.density_coefficients(density, grid, area)
        self.last_density, self.last_grid_mm = density, grid
        self._updated_at = self.env.n_observations

    # ---- one decision -------------------------------------------------------------------------
    def choose_move_mm(self) -> NDArray[np.float64]:
        env = self.env
        if self._phi_k is None or env.n_observations - self._updated_at >= self.update_period:
            self.update_density()
        assert self._basis is not None and self._phi_k is not None
        b = self._basis.smc_direction(env.path_mm, self._phi_k)
        self.last_direction = b
        lo, hi = move_bounds_mm(env)
        top = float(np.max(np.abs(b)))
        if not top > 1e-300:
            return lo + (hi - lo) * self.rng.random(2)
        return np.clip(-b / top * MAX_STEP_MM, lo, hi)

    def __repr__(self) -> str:
        return (
            f"EEDIAgent(n_coefficients={self.n_coefficients}, grid_mm={self.grid_mm}, "
            f"n_particles={self.n_particles}, update_period={self.update_period}, "
            f"criterion={self.criterion!r}, step_mm={self.step_mm})"
        )
