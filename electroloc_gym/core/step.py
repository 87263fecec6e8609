"""The simulation core: reset and step N envs of one task (the only implementation of the env's logic).

One step of env i (paper §4.1, Algorithm 1):

1. the commanded move (action × 10 mm per axis, or one of the 9 discrete moves) moves the carriage,
   truncated at the walls of the allowed box (:meth:`~electroloc_gym.core.tasks.TargetTask.move`);
2. env i's generator draws, in order: the reading noise (1 normal), the resampling offset (1 uniform)
   and the jitter (2M 16-bit indices into the normal quantile table);
3. the reading Φ = clip(noise-free reading + noise, ±V_sat) (:mod:`electroloc_gym.sensor`);
4. the belief update in one compiled call per step: the sensor model's log-likelihood of every
   particle (calibrated: the bilinear table lookup in the kernel; analytic: the physics in numpy),
   the weights, systematic resampling, jitter, the clip to the box, the new cloud's mean, covariance
   and histogram (:mod:`electroloc_gym.kernels.filter`);
5. reward −1; terminated when √trace Σ ≤ ``success_spread_mm``; truncated after
   ``max_observations`` readings (or ``max_episode_steps`` steps);
6. the observation (:mod:`electroloc_gym.envs.observation`) and the info arrays.

A reset draws the episode (:mod:`electroloc_gym.core.tasks`) and takes the first reading (steps 2–4),
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

from electroloc_gym.core.params import DISCRETE_MOVES_MM, MAX_STEP_MM, EnvParams
from electroloc_gym.core.state import State
from electroloc_gym.core.tasks import group_by_world, make_task
from electroloc_gym.draws import normal_table, table_normal_indices
from electroloc_gym.envs.observation import BELIEF_OBS_DIM, HIST_BINS, RAW_OBS_DIM, belief_observation, raw_observation
from electroloc_gym.kernels import calibrated_assimilate, egocentric_counts, loglik_assimilate, mean_cov_rows
from electroloc_gym.sensor import saturated_reading

__all__ = ["Simulation", "AUTORESET_MODES", "INFO_KEYS"]

AUTORESET_MODES = ("next_step", "same_step", "disabled")
#: The info keys of every step and reset, in order.
INFO_KEYS = ("position_mm", "estimate_mm", "error_mm", "spread_mm", "reading_V", "n_observations", "success",
             "condition")
_ALL = slice(None)


class Simulation:
    """N envs of one task: :meth:`reset` and :meth:`step` over arrays, the state in :attr:`state`.

    Args:
        params: the frozen parameters (:class:`~electroloc_gym.core.params.EnvParams`).
        num_envs: N (≥ 1).

    Raises:
        ValueError: sizes that cannot fit in memory (the message names the limit).
    """

    def __init__(self, params: EnvParams, num_envs: int) -> None:
        self.params = params
        self.num_envs = int(num_envs)
        self.task = make_task(params)
        params.check_memory(self.num_envs, self.task.calibration_points())
        self.state = State.empty(self.num_envs, params.n_particles, self.task.table_cells(),
                                 getattr(self.task, "shape_dims", 0))
        self.n_gains = len(params.gains)
        self.dynamic_gain = params.gain_levels is not None
        # the raw observation gets the gain level of its reading as a fourth entry with dynamic gain
        self.obs_dim = BELIEF_OBS_DIM if params.observation == "belief" else RAW_OBS_DIM + int(self.dynamic_gain)
        self._normal_table = normal_table()
        self._all_ids = np.arange(self.num_envs)
        self._sign = self.task.offset_sign

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
        x, y = s.particles_mm[i:i + 1, 0], s.particles_mm[i:i + 1, 1]
        mean_cov_rows(x, y, s.mean_mm[i:i + 1], s.cov_mm2[i:i + 1])
        egocentric_counts(x, y, self.task.histogram_origin(s, slice(i, i + 1)), np.full(1, 2 * h), HIST_BINS,
                          s.counts[i:i + 1])

    # ---- reset / step --------------------------------------------------------------------------
    def reset(self, ids: NDArray[np.intp] | None = None) -> None:
        """Start a new episode in envs ``ids`` (all if None): the episode's draws and the first reading."""
        ids = self._all_ids if ids is None else np.asarray(ids, dtype=np.intp)
        for i in ids.tolist():
            self.task.begin_episode(self.state, i, self.generator(i))
        self.task.set_gain(self.state, ids, self.params.reset_gain_index)
        self._observe(ids)
        self.state.done[ids] = False
        self.state.started = True

    def moves_from_actions(self, actions: Any, single: bool = False) -> NDArray[np.float64]:
        """The commanded moves (N, 2), mm, of a batch of actions (or of one action with ``single``)."""
        if self.dynamic_gain:
            return self._split_gain_actions(actions, single)[0]
        return self._moves(actions, single)

    def gains_from_actions(self, actions: Any, single: bool = False) -> NDArray[np.int64] | None:
        """The gain levels (N,) of a batch of actions (dynamic gain), else None."""
        return self._split_gain_actions(actions, single)[1] if self.dynamic_gain else None

    def _split_gain_actions(self, actions: Any, single: bool) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Dynamic gain: continuous (dx, dy, g), g ∈ [−1, 1] cut into K equal bins (level ⌊(g + 1)/2·K⌋);
        discrete (move index, level) of MultiDiscrete([9, K]).
        """
        n, k = self.num_envs, self.n_gains
        a = np.asarray(actions)
        shape = (2,) if single else (n, 2)
        if self.params.action_type == "discrete":
            if a.shape != shape or not np.issubdtype(a.dtype, np.integer) or np.any((a[..., 1] < 0) | (a[..., 1] >= k)):
                what = "action" if single else f"actions of {n} envs"
                raise ValueError(f"{what} must be (move index in [0, 8], gain level in [0, {k - 1}]) integers, "
                                 f"got {actions!r}")
            a = a.reshape(n, 2)
            return self._moves(a[:, 0], False), a[:, 1].astype(np.int64)
        a = np.asarray(actions, dtype=np.float64)
        shape = (3,) if single else (n, 3)
        if a.shape != shape or not np.all(np.isfinite(a)):
            what = "action" if single else "actions"
            raise ValueError(f"{what} must be finite with shape {shape} (dx, dy, gain in [-1, 1]), got {actions!r}")
        a = a.reshape(n, 3)
        g = np.minimum(np.maximum(a[:, 2], -1.0), 1.0)
        levels = np.minimum(np.floor((g + 1.0) * 0.5 * k), k - 1).astype(np.int64)
        return self._moves(a[:, :2], False), levels

    def _moves(self, actions: Any, single: bool) -> NDArray[np.float64]:
        n = self.num_envs
        if self.params.action_type == "discrete":
            a = np.asarray(actions)
            ok = (a.size == 1 if single else a.shape == (n,)) and np.issubdtype(a.dtype, np.integer)
            if not (ok and np.all((a >= 0) & (a < len(DISCRETE_MOVES_MM)))):
                what = "action must be an integer" if single else f"actions must be {n} integers"
                raise ValueError(f"{what} in [0, {len(DISCRETE_MOVES_MM) - 1}], got {actions!r}")
            return DISCRETE_MOVES_MM[a.reshape(n)]
        a = np.asarray(actions, dtype=np.float64)
        shape = (2,) if single else (n, 2)
        if a.shape != shape:
            what = "action" if single else "actions"
            raise ValueError(f"{what} must have shape {shape} (dx, dy in [-1, 1]), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action{'' if single else 's'} must be finite (dx, dy in [-1, 1]), got {actions!r}")
        return np.minimum(np.maximum(a.reshape(n, 2), -1.0), 1.0) * MAX_STEP_MM

    def step(self, moves_mm: NDArray[np.float64], autoreset: str = "next_step",
             gains: NDArray[np.int64] | None = None
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
        rewards = np.full(self.num_envs, -1.0)
        if s.done.any():
            if autoreset == "disabled":
                raise RuntimeError("the episode has ended (terminated or truncated): call reset() before step()")
            if autoreset == "next_step":
                reset_ids = np.flatnonzero(s.done)
                step_ids = np.flatnonzero(~s.done)
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
                rewards[reset_ids] = 0.0
                s.done = terminated | truncated
                return self.observation(), rewards, terminated, truncated, self.info()
        if gains is not None:
            self.task.set_gain(s, self._all_ids, gains)
        self.task.move(s, _ALL, moves_mm)
        self._observe(self._all_ids)
        s.elapsed += 1
        terminated, truncated = self._flags()
        obs, info = self.observation(), self.info()
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
        s = self.state
        success = s.spread_mm() <= self.params.success_spread_mm
        truncated = ~success & (s.n_observations >= self.params.max_observations)
        if self.params.max_episode_steps is not None:
            truncated |= s.elapsed >= self.params.max_episode_steps
        return success, truncated

    def _reference_mm(self, sel: Any) -> NDArray[np.float64]:
        """The observation's entries 0–1: the carriage (localize) or the odometry (global)."""
        s = self.state
        return s.odometry_mm[sel] if self.task.name == "global" else s.position_mm[sel]

    def observation(self, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """(k, obs_dim) float32 observations of envs ``ids`` (all if None)."""
        s, sel = self.state, _ALL if ids is None else ids
        half, sat = s.half_mm[sel], s.saturation_V[sel]
        if self.params.observation == "raw":
            obs = raw_observation(self._reference_mm(sel), s.reading_V[sel], half, sat)
            if self.dynamic_gain:  # the reading's gain level, in [−1, 1]
                level = s.gain_index[sel] * (2.0 / max(self.n_gains - 1, 1)) - 1.0
                obs = np.concatenate([obs, level.astype(np.float32)[:, None]], axis=1)
            return obs
        origin = np.zeros((len(half), 2)) if self.task.name == "global" else s.position_mm[sel]
        obs = belief_observation(origin, s.reading_V[sel], s.mean_mm[sel], s.cov_mm2[sel],
                                 s.counts[sel] / s.n_particles, s.n_observations[sel], self.params.max_observations,
                                 half, s.noise_V[sel], sat, self.params.success_spread_mm, s.descriptor[sel])
        if self.task.name == "global":  # entries 0–1: the odometry instead of the (unknown) carriage
            obs[:, 0:2] = np.minimum(np.maximum(s.odometry_mm[sel] / half[:, None], -1.0), 1.0)
        return obs

    def info(self, ids: NDArray[np.intp] | None = None) -> dict[str, NDArray]:
        """The info arrays of envs ``ids`` (all if None), keys :data:`INFO_KEYS`."""
        s, sel = self.state, _ALL if ids is None else ids
        est = s.mean_mm[sel]
        spread = np.sqrt(np.maximum(s.cov_mm2[sel, 0, 0] + s.cov_mm2[sel, 1, 1], 0.0))
        d = est - self.task.truth_mm(s, sel)
        extra = self.task.shape_info(s, sel) if self.task.name == "unknown" else {}
        if self.dynamic_gain:  # the amplifier gain G of the last reading
            extra["gain"] = np.array([w.amplifier.gain for w in s.world], dtype=np.float64)[sel] * \
                np.asarray(self.params.gains)[s.gain_index[sel]]
        return {
            "position_mm": s.position_mm[sel].copy(),
            "estimate_mm": est.copy(),
            "error_mm": np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]),
            "spread_mm": spread,
            "reading_V": s.reading_V[sel].copy(),
            "n_observations": s.n_observations[sel].copy(),
            "success": spread <= self.params.success_spread_mm,
            "condition": s.names[sel].copy(),
            **extra,
        }

    # ---- the reading and the belief update -----------------------------------------------------
    def _observe(self, ids: NDArray[np.intp]) -> None:
        """Envs ``ids`` take a noisy reading and fuse it into their beliefs (steps 2–4 of the docstring)."""
        s = self.state
        k = len(ids)
        full = k == self.num_envs
        sel: Any = _ALL if full else ids
        noise = np.empty(k)
        u0 = np.empty(k)
        jitter = s.jitter_idx if full else s.jitter_idx[:k]
        draws = s.jitter_idx.shape[1]  # 2·M (4·M with shapes)
        gens = s.gens
        for j, (i, sd) in enumerate(zip(ids.tolist(), s.noise_V[sel].tolist(), strict=True)):
            g = gens[i] or self.generator(i)
            noise[j] = g.normal(0.0, sd)
            u0[j] = g.random()
            jitter[j] = table_normal_indices(g, draws)
        reading = saturated_reading(self.task.true_mean_V(s, ids), noise, s.saturation_V[sel])
        s.reading_V[sel] = reading
        s.n_observations[sel] += 1
        if self.task.name == "unknown":  # position and shape resampled together (core.unknown)
            if self.task.assimilate(s, ids, reading, u0, jitter, self._normal_table, HIST_BINS) >= 0:
                raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
            return
        src = s.particles_mm if full else s.particles_mm[ids]  # full: updated in place
        origin = self.task.histogram_origin(s, sel)
        half = s.half_mm[sel].astype(np.float32)
        if full:  # the kernels write the statistics in place
            mean, cov, counts = s.mean_mm, s.cov_mm2, s.counts
        else:
            mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
        if self.task.calibrated:
            rows = self.task.table_rows(s, sel)  # each env's rows at its current gain level
            bad = calibrated_assimilate(src, origin, self._sign, s.grid_lo_mm[sel], s.grid_inv_mm[sel],
                                        s.grid_cells[sel], rows, s.table, reading.astype(np.float32), u0,
                                        jitter, self._normal_table, half, src, mean, cov, 2 * half, HIST_BINS, counts)
        else:
            ll = self._analytic_log_likelihood(ids, src, origin, reading)
            bad = loglik_assimilate(ll, src, origin, u0, jitter, self._normal_table, half, src, mean, cov, 2 * half,
                                    HIST_BINS, counts)
        if bad >= 0:
            raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
        if not full:
            s.particles_mm[ids] = src
            s.mean_mm[ids], s.cov_mm2[ids], s.counts[ids] = mean, cov, counts

    def _analytic_log_likelihood(self, ids: NDArray[np.intp], src: NDArray[np.float32], origin: NDArray[np.float32],
                                 reading: NDArray[np.float64]) -> NDArray[np.float32]:
        """(k, M) float32 log-likelihoods of the analytic models, one numpy evaluation per world (and gain
        level, with dynamic gain).
        """
        off = ((src - origin[:, :, None]) * self._sign).transpose(0, 2, 1)  # (k, M, 2) offsets
        groups = group_by_world(self.state, ids, by_gain=self.dynamic_gain)
        if len(groups) == 1:
            model = self.task.sensor_model(self.state, int(ids[0]))
            return np.ascontiguousarray(model.log_likelihood(reading[:, None], off), dtype=np.float32)
        ll = np.empty((len(ids), src.shape[2]), dtype=np.float32)
        for _, rows in groups:
            model = self.task.sensor_model(self.state, int(ids[rows[0]]))
            ll[rows] = model.log_likelihood(reading[rows][:, None], off[rows])
        return ll
