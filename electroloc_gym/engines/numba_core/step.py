"""The simulation core: reset and step N envs of one task (the only implementation of the env's logic).

One step of env i (paper §4.1, Algorithm 1):

1. the commanded move (mm, parsed from the action by the adapter, :mod:`electroloc_gym.envs.actions`)
   moves the carriage, truncated at the walls of the allowed box (:meth:`Task.move
   <electroloc_gym.engines.numba_core.task.Task.move>`);
2. env i's generator draws, in order: the reading noise (1 normal; K with K readings per step), the
   resampling offset (1 uniform) and the jitter (2M 16-bit indices into the normal quantile table;
   (2 + S)·M with S shape coordinates per particle);
3. the reading Φ = clip(noise-free reading + noise, ±V_sat) (the task's ``true_mean_V``,
   :func:`electroloc_gym.world.sensor.saturated_reading`);
4. the task's belief update (``assimilate``: one compiled call per step for the x–y beliefs — the
   sensor model's log-likelihood of every particle, the weights, systematic resampling, jitter, the
   clip to the box, the new cloud's mean, covariance and histogram, :mod:`electroloc_gym.kernels.filter`);
5. the task's reward and flags (``rewards``, ``flags``; the paper's tasks: −1; terminated when
   √trace Σ ≤ ``success_spread_mm``; truncated after ``max_observations`` readings (or
   ``max_episode_steps`` steps));
6. the task's observation (:mod:`electroloc_gym.contract.observation`) and info arrays.

A reset sets the task's own arrays (``State.task``) back to their declared fill values, draws the episode
(the task's ``begin_episode``) and takes the first reading (steps 2–4),
so an episode starts with one observation. Autoreset follows Gymnasium's modes: ``"next_step"`` (the
step after an episode ends resets that env: reward 0, not done, the action ignored), ``"same_step"``
(reset within the ending step; the final observation and info returned beside) or ``"disabled"``
(stepping an env whose episode ended is an error — the single env).

Why env i's values do not depend on N or on the CPU: every per-env number comes from env i's own
generator, from exact elementwise numpy operations, or from the kernels, which work one env at a time
with exact operations and fixed-order sums (docs/design.md, "Results that do not depend on the CPU").
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.utils import seeding
from numpy.typing import NDArray

from electroloc_gym.contract.observation import RESET_REWARD
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.engines.numba_core.task import Task
from electroloc_gym.kernels.streams import normal_table, table_normal_indices
from electroloc_gym.registry import task_entry
from electroloc_gym.world.sensor import saturated_reading

__all__ = ["Simulation", "AUTORESET_MODES", "make_task"]

AUTORESET_MODES = ("next_step", "same_step", "disabled")
_ALL = slice(None)


def make_task(params: EnvParams) -> Task:
    """The task object of ``params.task`` (its class from the env table, :mod:`electroloc_gym.registry`)."""
    task: Task = task_entry(params.task).task_class(params)
    return task


class Simulation:
    """N envs of one task: :meth:`reset` and :meth:`step` over arrays, the state in :attr:`state`.

    Args:
        params: the frozen parameters (:class:`~electroloc_gym.contract.params.EnvParams`).
        num_envs: N (≥ 1).

    Raises:
        ValueError: sizes that cannot fit in memory (the message names the limit).
    """

    def __init__(self, params: EnvParams, num_envs: int) -> None:
        self.params = params
        self.num_envs = int(num_envs)
        self.task = make_task(params)
        params.check_memory(self.num_envs, self.task.calibration_points())
        self.state = State.empty(
            self.num_envs,
            params.n_particles,
            self.task.table_cells(),
            self.task.shape_dims,
            self.task.n_readings,
            self.task.State.empty(self.num_envs, params),
        )
        self.obs_dim = self.task.obs_dim
        self._normal_table = normal_table()
        self._all_ids = np.arange(self.num_envs)

    # ---- generators ----------------------------------------------------------------------------
    def generator(self, i: int) -> np.random.Generator:
        """Env ``i``'s generator (created unseeded on first use, as a Gymnasium env's)."""
        g = self.state.gens[i]
        if g is None:
            g, self.state.seeds[i] = seeding.np_random(None)
            self.state.gens[i] = g
        return g

    def set_generator(self, i: int, generator: np.random.Generator, seed: int | None = None) -> None:
        """Env ``i`` draws from ``generator`` from now on (``seed``: what it was created from)."""
        self.state.gens[i] = generator
        self.state.seeds[i] = seed

    def seed(self, i: int, seed: int) -> None:
        """A new generator for env ``i`` from ``seed`` (Gymnasium's ``seeding.np_random``)."""
        self.state.gens[i], self.state.seeds[i] = seeding.np_random(int(seed))

    def set_particles(self, i: int, particles_mm: NDArray) -> None:
        """Replace env ``i``'s cloud by ``particles_mm`` (M, 2), mm (clipped to its box; e.g. to restore a
        snapshot or to start from a given belief), and recompute its statistics.
        """
        s = self.state
        p = np.asarray(particles_mm, dtype=np.float32)
        if p.shape != (s.n_particles, 2) or not np.all(np.isfinite(p)):
            raise ValueError(f"particles_mm must be finite with shape ({s.n_particles}, 2), got {p.shape}")
        h = np.float32(s.half_mm[i])
        s.particles_mm[i] = np.minimum(np.maximum(p, -h), h).T
        self.task.update_statistics(s, slice(i, i + 1))

    # ---- reset / step --------------------------------------------------------------------------
    def reset(self, ids: NDArray[np.intp] | None = None) -> None:
        """Start a new episode in envs ``ids`` (all if None): the episode's draws and the first reading."""
        ids = self._all_ids if ids is None else np.asarray(ids, dtype=np.intp)
        self.state.task.reset_rows(ids)  # the task's own arrays back to their fill values, then its draws
        for i in ids.tolist():
            self.task.begin_episode(self.state, i, self.generator(i))
        self.task.set_gain(self.state, ids, self.params.reset_gain_index)
        self._observe(ids)
        self.state.done[ids] = False
        self.state.started = True

    def step(
        self, moves_mm: NDArray[np.float64], autoreset: str = "next_step", gains: NDArray[np.int64] | None = None
    ) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """One step of every env: (observations, rewards, terminated, truncated, info); ``gains``: each
        env's gain level of this step's reading (dynamic gain; None: unchanged).

        With ``autoreset="same_step"`` the info also holds ``final_obs`` ((N,) object, the ended envs'
        last observations, else None), ``final_info`` (the step's info before the resets) and ``done``.

        Raises:
            RuntimeError: before the first reset, or (``"disabled"``) an env whose episode ended.
        """
        s = self.state
        if not s.started:
            raise RuntimeError("call reset() before step()")
        if s.done.any():
            if autoreset == "disabled":
                raise RuntimeError("the episode has ended (terminated or truncated): call reset() before step()")
            if autoreset == "next_step":
                reset_ids = np.flatnonzero(s.done)
                step_ids = np.flatnonzero(~s.done)
                s.task.reset_rows(reset_ids)
                for i in reset_ids.tolist():
                    self.task.begin_episode(s, i, self.generator(i))
                self.task.set_gain(s, reset_ids, self.params.reset_gain_index)
                if gains is not None:
                    self.task.set_gain(s, step_ids, gains[step_ids])
                self.task.move(s, step_ids, moves_mm[step_ids])
                self._observe(self._all_ids)  # every env reads once: the stepped and the fresh ones
                s.elapsed[step_ids] += 1
                terminated, truncated = self._flags()
                terminated[reset_ids] = False
                truncated[reset_ids] = False
                rewards = self.task.rewards(s)
                rewards[reset_ids] = RESET_REWARD
                s.done = terminated | truncated
                return self.observation(), rewards, terminated, truncated, self.info()
        if gains is not None:
            self.task.set_gain(s, self._all_ids, gains)
        self.task.move(s, _ALL, moves_mm)
        self._observe(self._all_ids)
        s.elapsed += 1
        terminated, truncated = self._flags()
        rewards = self.task.rewards(s)
        obs = self.observation()
        info: dict[str, Any] = self.info()  # the step's arrays, then (same_step) final_obs, final_info, done
        done = terminated | truncated
        s.done = done.copy()
        if autoreset == "same_step" and done.any():
            ids = np.flatnonzero(done)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in ids.tolist():
                final_obs[i] = obs[i].copy()
            final_info = {k: v.copy() for k, v in info.items()}
            self.reset(ids)
            obs[ids] = self.observation(ids)
            for k, v in self.info(ids).items():
                info[k][ids] = v
            info.update(final_obs=final_obs, final_info=final_info, done=done.copy())
        return obs, rewards, terminated, truncated, info

    # ---- observation, flags, info --------------------------------------------------------------
    def _flags(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        return self.task.flags(self.state)

    def observation(self, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """(k, obs_dim) float32 observations of envs ``ids`` (all if None): the task's."""
        return self.task.observation(self.state, ids)

    def info(self, ids: NDArray[np.intp] | None = None) -> dict[str, NDArray[Any]]:
        """The info arrays of envs ``ids`` (all if None): the task's (``INFO_KEYS`` first)."""
        return self.task.info(self.state, ids)

    # ---- the reading and the belief update -----------------------------------------------------
    def _observe(self, ids: NDArray[np.intp]) -> None:
        """Envs ``ids`` take a noisy reading and fuse it into their beliefs (steps 2–4 of the docstring)."""
        s = self.state
        k = len(ids)
        full = k == self.num_envs
        sel: Any = _ALL if full else ids
        n_readings = self.task.n_readings
        noise = np.empty(k) if n_readings == 1 else np.empty((k, n_readings))
        u0 = np.empty(k)
        jitter = s.jitter_idx if full else s.jitter_idx[:k]
        draws = s.jitter_idx.shape[1]  # (2 + S)·M
        gens = s.gens
        size = None if n_readings == 1 else n_readings
        for j, (i, sd) in enumerate(zip(ids.tolist(), s.noise_V[sel].tolist(), strict=True)):
            g = gens[i] or self.generator(i)
            noise[j] = g.normal(0.0, sd, size)
            u0[j] = g.random()
            jitter[j] = table_normal_indices(g, draws)
        sat = s.saturation_V[sel] if n_readings == 1 else s.saturation_V[sel][:, None]
        reading = saturated_reading(self.task.true_mean_V(s, ids), noise, sat)
        s.reading_V[sel] = reading
        s.n_observations[sel] += 1
        if self.task.assimilate(s, ids, reading, u0, jitter, self._normal_table) >= 0:
            raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
