"""The simulation's explicit state: N envs as arrays (units in the field names).

Everything that changes during an episode lives in one :class:`State` (a task's own arrays in its
``task`` field, declared by the task); the parameters
(:class:`~electroloc_gym.contract.params.EnvParams`) and the task
(:class:`~electroloc_gym.engines.numba_core.task.Task`)
never change. Particles are stored coordinate-major, (N, 2, M), so that every kernel's inner loop runs over
contiguous particles; the belief's weights are uniform after every update, so they are not stored.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.observation import HIST_BINS
from electroloc_gym.contract.task_spec import TaskState

__all__ = ["State"]


@dataclass
class State:
    """The state of N envs (one row per env).

    Attributes:
        gens: each env's random generator (None until seeded or first used).
        seeds: the seed each generator was last created from.
        world: each env's episode world: its ``Condition`` (localize, unknown) or ``Scene`` (global).
        world_key: (N,) an integer naming each env's world (equal keys: the same world object).
        model: each env's sensor-model object for the agent (built on demand; None until asked for).
        cal_seed: (N,) each episode's calibration seed.
        half_mm: (N,) allowed half-width H of each env's box [−H, H]², mm.
        noise_V: (N,) reading noise G·σ_s, V.
        saturation_V: (N,) reading clip level, V.
        descriptor: (N, 5) float32 condition descriptors (observation entries 76–80).
        names: (N,) object, each world's name (info ``condition``).
        position_mm: (N, 2) true carriage position, mm.
        target_mm: (N, 2) true target centre (localize), mm.
        odometry_mm: (N, 2) sum of the commanded moves since reset (global), mm.
        particles_mm: (N, 2, M) float32 particles, coordinate-major, mm.
        reading_V: (N,) last reading Φ, V ((N, K) with K readings per step).
        n_observations: (N,) readings fused this episode.
        elapsed: (N,) steps this episode.
        mean_mm: (N, 2) belief mean, mm.
        cov_mm2: (N, 2, 2) belief covariance, mm².
        counts: (N, 64) the observation histogram's particle counts (8 × 8 cells).
        done: (N,) the episode ended (terminated or truncated) at the last step.
        started: reset has been called.
        grid_lo_mm: (N,) float32 first calibration grid coordinate, mm.
        grid_inv_mm: (N,) float32 inverse calibration grid step, 1/mm.
        grid_cells: (N,) int64 calibration cells per axis.
        table_row: (N,) int64 first row of each env's coefficients in ``table``.
        table: (N·cells + …, 8) float32 stacked bilinear coefficients of the calibrated models.
        jitter_idx: (N, D·M) uint16 scratch: each step's jitter draws (D = 2, or 4 with shapes).
        shape_particles: (N, S, M) float32: each particle's coordinates beyond x, y (``Task.shape_dims`` = S;
            the unknown target's radius mm and χ, S = 2; S = 0 elsewhere): part of the belief, which the
            step's jitter draws, the agents' hypotheses and the belief views size by ``Task.particle_dims``.
        gain_index: (N,) the gain level of each env's last reading (dynamic gain; 0 without).
        task: the task's own per-env arrays (its ``Task.State``, a
            :class:`~electroloc_gym.contract.task_spec.TaskState`; e.g. the moving target's heading).
        worlds_drawn: worlds drawn per episode so far (the global task's random maps: each new map's
            ``world_key``).
        distractor_scenes: each env's episode distractors as a ``Scene`` in its world's water (None: none;
            empty until a task with distractors resets; :mod:`electroloc_gym.engines.numba_core.distractor_task`).
    """

    gens: list[np.random.Generator | None]
    seeds: list[int | None]
    world: list[Any]
    world_key: NDArray[np.int64]
    model: list[Any]
    cal_seed: NDArray[np.int64]
    half_mm: NDArray[np.float64]
    noise_V: NDArray[np.float64]
    saturation_V: NDArray[np.float64]
    descriptor: NDArray[np.float32]
    names: NDArray[np.object_]
    position_mm: NDArray[np.float64]
    target_mm: NDArray[np.float64]
    odometry_mm: NDArray[np.float64]
    particles_mm: NDArray[np.float32]
    reading_V: NDArray[np.float64]
    n_observations: NDArray[np.int64]
    elapsed: NDArray[np.int64]
    mean_mm: NDArray[np.float64]
    cov_mm2: NDArray[np.float64]
    counts: NDArray[np.float64]
    done: NDArray[np.bool_]
    grid_lo_mm: NDArray[np.float32]
    grid_inv_mm: NDArray[np.float32]
    grid_cells: NDArray[np.int64]
    table_row: NDArray[np.int64]
    table: NDArray[np.float32]
    jitter_idx: NDArray[np.uint16]
    shape_particles: NDArray[np.float32]
    gain_index: NDArray[np.int64]
    task: TaskState
    started: bool = field(default=False)
    worlds_drawn: int = field(default=0)
    distractor_scenes: list[Any] = field(default_factory=list)

    @classmethod
    def empty(
        cls,
        num_envs: int,
        n_particles: int,
        table_cells: int,
        shape_dims: int = 0,
        n_readings: int = 1,
        task: TaskState | None = None,
    ) -> State:
        """A state of ``num_envs`` envs of ``n_particles`` particles, room for ``table_cells`` calibration
        rows per env (0: no calibrated model), ``shape_dims`` shape coordinates per particle,
        ``n_readings`` readings per step (``reading_V`` is (N,) for one, (N, K) for K) and the task's own
        arrays ``task`` (None: none).
        """
        n, m = num_envs, n_particles
        return cls(
            gens=[None] * n,
            seeds=[None] * n,
            world=[None] * n,
            world_key=np.full(n, -1, dtype=np.int64),
            model=[None] * n,
            cal_seed=np.zeros(n, dtype=np.int64),
            half_mm=np.ones(n),
            noise_V=np.ones(n),
            saturation_V=np.ones(n),
            descriptor=np.zeros((n, 5), dtype=np.float32),
            names=np.full(n, "", dtype=object),
            position_mm=np.zeros((n, 2)),
            target_mm=np.zeros((n, 2)),
            odometry_mm=np.zeros((n, 2)),
            particles_mm=np.zeros((n, 2, m), dtype=np.float32),
            reading_V=np.zeros(n) if n_readings == 1 else np.zeros((n, n_readings)),
            n_observations=np.zeros(n, dtype=np.int64),
            elapsed=np.zeros(n, dtype=np.int64),
            mean_mm=np.zeros((n, 2)),
            cov_mm2=np.zeros((n, 2, 2)),
            counts=np.zeros((n, HIST_BINS * HIST_BINS)),
            done=np.zeros(n, dtype=bool),
            grid_lo_mm=np.zeros(n, dtype=np.float32),
            grid_inv_mm=np.ones(n, dtype=np.float32),
            grid_cells=np.ones(n, dtype=np.int64),
            table_row=np.arange(n, dtype=np.int64) * table_cells,
            table=np.zeros((max(n * table_cells, 1), 8), dtype=np.float32),
            jitter_idx=np.empty((n, (2 + shape_dims) * m), dtype=np.uint16),
            shape_particles=np.zeros((n, shape_dims, m), dtype=np.float32),
            gain_index=np.zeros(n, dtype=np.int64),
            task=TaskState() if task is None else task,
        )

    @property
    def num_envs(self) -> int:
        """N."""
        return len(self.gens)

    @property
    def n_particles(self) -> int:
        """M."""
        return self.particles_mm.shape[2]

    def spread_mm(self) -> NDArray[np.float64]:
        """(N,) √trace Σ of each belief, mm (the paper's success measure, §5.4)."""
        c = self.cov_mm2
        return np.sqrt(np.maximum(c[:, 0, 0] + c[:, 1, 1], 0.0))
