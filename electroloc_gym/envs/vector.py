"""Native batched vector env for ElectroLoc-v0: N tanks and N particle filters stepped as arrays.

``gym.make_vec("ElectroLoc-v0", num_envs=N, vectorization_mode="vector_entry_point")`` builds a
:class:`ElectroLocVectorEnv`. All the per-step math — carriage motion, the true readings, the sensor
model on N×M particles, log-weight normalisation, systematic resampling, jitter, the belief statistics,
the observations and the infos — runs on arrays of shape (N, M, 2) / (N, M) / (N, …), with no Python
loop over envs or particles.

Same per-env behaviour as the single env (tested bit for bit)
-------------------------------------------------------------
Every sub-env ``i`` owns its own ``np.random.Generator`` (``reset(seed=s)`` seeds env ``i`` with
``s + i``, exactly like :class:`gymnasium.vector.SyncVectorEnv`), and each generator is advanced in
the single env's order: per step the reading noise (1 normal), the resampling offset (1 uniform) and
the jitter (M·2 16-bit table indices, :func:`electroloc_gym.draws.table_normal_indices`); per reset
the condition (``condition="random"``), the calibration seed, the target (``randomize_target``), the
start (2 uniforms), the particles (M·2 uniforms) and then the first reading's draws. Only these
*draws* are made per env (3 generator calls per env per step, ≈3 µs) — they are what makes sub-env
``i`` produce exactly what ``gym.make("ElectroLoc-v0")`` seeded alike produces: observations, rewards,
terminations, truncations and infos, across autoresets.

The math runs in compiled kernels (:mod:`electroloc_gym.kernels`, numba) instead of numpy's ~25
elementwise passes with their temporaries. With the calibrated sensor model (the default) the whole
update is one call, :func:`~electroloc_gym.kernels.calibrated_assimilate`, which takes one env at a
time through a few passes over its particles while they are in cache, in place:

* the calibrated sensor model's bilinear lookup and Gaussian log-likelihood (per env a new
  calibration per episode, all stacked into one float32 coefficient table; the calibration's
  noise-free grid, the same for every seed of a condition, is computed once per condition);
* the weights (``exp32`` of the shifted log-likelihoods, their fixed-order total), systematic
  resampling (branch-free: each particle's pointer count from ``ceil(M·c − U)`` checked against the
  pointers themselves), the jitter and the clip to the box;
* the belief's mean/covariance and the observation's particle histogram.

They repeat the single env's float32/float64 operations in the same order, and where the single env's
result would depend on numpy's internals (``exp``/``log``, summation order) it calls the same kernels,
so the results are identical, not merely close: a float rounding difference would flip a resampling
index within a step or two and the two runs would diverge. Particles are stored coordinate-major,
(N, 2, M), so every inner loop runs over contiguous particles.

Per env-step at M = 2500 on this machine (``python benchmarks/vector_env.py --profile``), roughly: the
update kernel 40–60 µs (40 with a warm cache; the gather of 8 calibration coefficients per particle
and the sequential cumulative sum dominate), the per-env draws ≈8 µs, the per-episode recalibration and
reset draws ≈6 µs amortised, the rest (true readings, observations, infos) ≈20 µs — 85–100 µs in all,
against ≈0.9 ms for a single env step.

Autoreset
---------
``metadata["autoreset_mode"]`` is :attr:`gymnasium.vector.AutoresetMode.NEXT_STEP` by default, like
Gymnasium's built-in vector envs: the step after a sub-env terminates or truncates resets it (reward 0,
not done, the action is ignored). ``autoreset_mode="same_step"`` resets it within the terminating step
and returns the final observation and info in ``info["final_obs"]`` / ``info["final_info"]`` (masks
``info["_final_obs"]`` / ``info["_final_info"]``) — the SB3 adapter (``train/native_vec.py``) uses it.
``reset(options={"reset_mask": mask})`` resets only the masked sub-envs (as ``SyncVectorEnv``).

Info
----
A dict of arrays over the N envs (Gymnasium's vector convention), each key with an all-true
``"_key"`` mask: ``position_mm`` (N, 2), ``estimate_mm`` (N, 2), ``error_mm``, ``spread_mm``,
``reading_V`` (N,) float64, ``n_observations`` (N,) int64, ``success`` (N,) bool, ``condition`` (N,)
object (names). ``SyncVectorEnv`` stores the tuple-valued keys as object arrays of tuples; here they
are plain float arrays.

Rendering is not supported (``render_mode`` must be None): render one sub-env with the single env.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from electroloc_gym.kernels import calibrated_assimilate, resample_jitter_clip
from electroloc_gym.belief import (
    normal_table,
    shifted_exp_weights,
    spread_from_cov,
    table_normal_indices,
    uniform_in_box,
    weight_sums,
)
from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition
from electroloc_gym.envs.localize import DISCRETE_MOVES_MM, MAX_STEP_MM, ElectroLocEnv
from electroloc_gym.envs.observation import HIST_BINS, belief_observation, condition_descriptor, raw_observation
from electroloc_gym.sensor import expected_reading
from electroloc_gym.sensor_models import (
    DEFAULT_CALIBRATION,
    AnalyticSensorModel,
    CalibratedSensorModel,
    calibration_coefficients,
    calibration_grid_for,
    make_sensor_model,
)

__all__ = ["ElectroLocVectorEnv", "GlobalLocalizationVectorEnv", "make_electroloc_vector_env", "make_global_vector_env"]

#: Particles processed per block of a step (several envs at a time): bounds the step's temporaries
#: (≈24 bytes per particle) so that they stay in cache and under glibc's mmap threshold. Measured on this
#: machine at N = 64, M = 2500: blocks of 16 envs 141 µs per env-step, one block of 64 envs 157 µs.
BLOCK_PARTICLES = 40000


# --------------------------------------------------------------------------------------------
# Exact batched building blocks
# --------------------------------------------------------------------------------------------
class _StackedCalibratedLookup:
    """N calibrated sensor models (one per env, possibly different grids) as one float32 table.

    :meth:`grid_args` are the per-env arguments of the calibrated kernels
    (:func:`~electroloc_gym.kernels.calibrated_assimilate`,
    :func:`~electroloc_gym.kernels.calibrated_log_likelihood`), which compute
    ``CalibratedSensorModel.log_likelihood`` for every env at once with the same float32 operations.
    """

    def __init__(self, num_envs: int, max_cells: int) -> None:
        if num_envs * max_cells >= 2**31:  # the kernels index table rows with int32
            raise ValueError(f"num_envs too large for the stacked calibration table ({num_envs} envs)")
        self.max_cells = max_cells
        self.table = np.zeros((num_envs * max_cells, 8), dtype=np.float32)
        self.base = (np.arange(num_envs, dtype=np.int64) * max_cells)[:, None]
        self.lo = np.zeros((num_envs, 1), dtype=np.float32)
        self.inv = np.ones((num_envs, 1), dtype=np.float32)
        self.n1 = np.ones((num_envs, 1), dtype=np.int64)

    def set(self, env: int, model: CalibratedSensorModel) -> None:
        """Env ``env`` uses ``model`` (its own coefficient table, last row = outside the grid)."""
        coef = model._coef
        self._set_grid(env, model.grid_mm, model.grid_step_mm)
        start = env * self.max_cells
        self.table[start:start + coef.shape[0]] = coef

    def calibrate(self, env: int, condition: Condition, seed: int) -> None:
        """Env ``env`` uses ``CalibratedSensorModel(condition, seed)`` (its table, computed in place)."""
        grid = calibration_grid_for(condition, DEFAULT_CALIBRATION)
        self._set_grid(env, grid, DEFAULT_CALIBRATION.grid_step_mm)
        start = env * self.max_cells
        calibration_coefficients(condition, seed, DEFAULT_CALIBRATION,
                                 out=self.table[start:start + (grid.size - 1) ** 2 + 1])

    def _set_grid(self, env: int, grid_mm: NDArray[np.float64], step_mm: float) -> None:
        n1 = grid_mm.size - 1
        if n1 * n1 + 1 > self.max_cells:
            raise ValueError(f"calibration grid too large for the stacked table ({n1 * n1 + 1} > {self.max_cells})")
        self.lo[env] = np.float32(grid_mm[0])
        self.inv[env] = np.float32(1.0 / step_mm)
        self.n1[env] = n1

    def grid_args(self, sel: slice | NDArray[np.intp]) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
        """The calibrated kernels' per-env grid arguments (lo, inv, n1, base, table) for envs ``sel``."""
        return (self.lo[sel].reshape(-1), self.inv[sel].reshape(-1), self.n1[sel].reshape(-1),
                self.base[sel].reshape(-1), self.table)


def _check_vector_args(num_envs: Any, render_mode: Any, autoreset_mode: Any, max_episode_steps: Any) -> AutoresetMode:
    """Validate the vector-only arguments; returns the autoreset mode."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer ≥ 1, got {num_envs!r}")
    if render_mode is not None:
        raise ValueError(f"render_mode must be None for the native vector env (got {render_mode!r}); "
                         "render a single env instead")
    mode = _AUTORESET_MODES.get(autoreset_mode if isinstance(autoreset_mode, (str, AutoresetMode)) else None)
    if mode is None:
        raise ValueError(f"autoreset_mode must be AutoresetMode.NEXT_STEP or SAME_STEP (or 'next_step', "
                         f"'same_step'), got {autoreset_mode!r}")
    if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
            max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
        raise ValueError(f"max_episode_steps must be None or an integer ≥ 1, got {max_episode_steps!r}")
    return mode


_AUTORESET_MODES: dict[Any, AutoresetMode] = {
    AutoresetMode.NEXT_STEP: AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP: AutoresetMode.SAME_STEP,
    "next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP,
    AutoresetMode.NEXT_STEP.value: AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP.value: AutoresetMode.SAME_STEP,
}


# --------------------------------------------------------------------------------------------
# The vector env
# --------------------------------------------------------------------------------------------
class ElectroLocVectorEnv(VectorEnv):
    """
    ## Description

    ``num_envs`` independent copies of ElectroLoc-v0 (:class:`~electroloc_gym.envs.localize.ElectroLocEnv`)
    stepped together: N carriages, N targets and N particle filters held as arrays (particles
    (N, M, 2) float32). Sub-env ``i`` behaves exactly like ``gym.make("ElectroLoc-v0", **kwargs)``
    reset with seed ``seed + i`` (see the module docstring).

    ## Action Space

    ``Box(-1, 1, (N, 2), float32)`` (continuous) or ``MultiDiscrete([9] * N)`` (discrete), the single
    env's action space batched.

    ## Observation Space

    The single env's space batched: ``Box(-1, 1, (N, 81), float32)`` ("belief") or ``(N, 3)`` ("raw").

    ## Rewards, Starting State, Episode End

    As ElectroLoc-v0 per sub-env: −1 per step; success (terminated) when √trace Σ ≤
    ``success_spread_mm``; truncated after ``max_observations`` readings (or ``max_episode_steps``
    steps, if given, like a TimeLimit). Sub-envs autoreset (``autoreset_mode``).

    ## Arguments

    ```python
    gym.make_vec("ElectroLoc-v0", num_envs=16, vectorization_mode="vector_entry_point",
                 condition="fresh-steel-12.7", observation="belief", sensor_model="calibrated",
                 n_particles=2500, max_observations=35, success_spread_mm=10.0, signal="fitted",
                 action_type="continuous", randomize_target=False, calibration_seed=None,
                 autoreset_mode="next_step")
    ```

    The ElectroLoc-v0 keyword arguments (validated by the single env's constructor) plus
    ``num_envs`` (≥ 1), ``autoreset_mode`` (``AutoresetMode`` or its value: "next_step",
    "same_step") and ``max_episode_steps`` (None or ≥ 1).
    ``render_mode`` must be None.

    ## Version History

    * v0: initial version.
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        condition: str | Condition = "fresh-steel-12.7",
        observation: str = "belief",
        sensor_model: str = "calibrated",
        n_particles: int = 2500,
        max_observations: int = 35,
        success_spread_mm: float = 10.0,
        signal: str | float = "fitted",
        action_type: str = "continuous",
        randomize_target: bool = False,
        calibration_seed: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
    ) -> None:
        mode = _check_vector_args(num_envs, render_mode, autoreset_mode, max_episode_steps)
        # The single env validates every shared argument and defines the spaces.
        template = ElectroLocEnv(condition=condition, observation=observation, sensor_model=sensor_model,
                                 n_particles=n_particles, max_observations=max_observations,
                                 success_spread_mm=success_spread_mm, signal=signal, action_type=action_type,
                                 randomize_target=randomize_target, calibration_seed=calibration_seed)
        self.randomize_target = bool(randomize_target)
        if isinstance(condition, str) and condition == "random":
            pool: tuple[Condition, ...] = tuple(get_condition(n, signal) for n in PRESET_NAMES)
        else:
            pool = (get_condition(condition, signal),)
        self._init_common(template, int(num_envs), mode, max_episode_steps, pool,
                          tuple(AnalyticSensorModel(c) for c in pool))

    def _init_common(self, template: Any, num_envs: int, mode: AutoresetMode, max_episode_steps: int | None,
                     pool: tuple[Condition, ...], analytic_models: tuple[Any, ...]) -> None:
        """State shared by the native vector envs; ``template`` is a validated single env."""
        self.num_envs = int(num_envs)
        self.n_particles = template.n_particles
        self.max_observations = template.max_observations
        self.success_spread_mm = template.success_spread_mm
        self.observation_mode = template.observation_mode
        self.sensor_model_name = template.sensor_model_name
        self.action_type = template.action_type
        self.calibration_seed = template.calibration_seed
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.autoreset_mode = mode
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self.render_mode = None
        self.single_action_space = template.action_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = template.observation_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        template.close()

        self._pool = pool
        self._pool_half = np.array([c.allowed_half_width_mm for c in pool])
        self._pool_start = np.array([c.start_half_width_mm for c in pool])
        self._pool_noise = np.array([c.noise_std_V for c in pool])
        self._pool_sat = np.array([c.saturation_V for c in pool])
        self._pool_desc = np.stack([condition_descriptor(c) for c in pool])
        self._pool_analytic = analytic_models
        self._pool_names = np.array([c.name for c in pool], dtype=object)

        n, m = self.num_envs, self.n_particles
        self._gens: list[np.random.Generator | None] = [None] * n
        self._seeds: list[int | None] = [None] * n
        self._cidx = np.zeros(n, dtype=np.intp)
        self._models: list[Any] = [None] * n
        self._cal_seeds: list[int] = [0] * n
        # Particles are stored coordinate-major, (N, 2, M), and handed to the shared (..., M, 2) functions
        # as the transposed view: numpy then iterates over M in its inner loops (contiguous), where an
        # (N, M, 2) array makes it iterate over the axis of length 2 — 3-4x slower for the broadcasts
        # in the statistics and the histogram. Same elementwise operations, identical results (tested).
        self._soa = np.zeros((n, 2, m), dtype=np.float32)
        self._jitter_idx = np.empty((n, 2 * m), dtype=np.uint16)
        self._normal_table = normal_table()
        self._block_envs = max(1, BLOCK_PARTICLES // m)
        self._position = np.zeros((n, 2))
        self._target = np.zeros((n, 2))
        self._reading = np.zeros(n)
        self._n_obs = np.zeros(n, dtype=np.int64)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._mean = np.zeros((n, 2))
        self._cov = np.zeros((n, 2, 2))
        self._counts = np.zeros((n, HIST_BINS * HIST_BINS))  # the observation histogram's particle counts
        self._autoreset = np.zeros(n, dtype=bool)
        self._started = False
        self._cal: _StackedCalibratedLookup | None = None
        if self.sensor_model_name == "calibrated":
            cells = max((calibration_grid_for(c, DEFAULT_CALIBRATION).size - 1) ** 2 + 1 for c in pool)
            self._cal = _StackedCalibratedLookup(n, cells)

    # ---- read-only accessors ------------------------------------------------------------------
    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        """The sub-envs' generators (created unseeded on first use, as a single env's)."""
        return tuple(self._gen(i) for i in range(self.num_envs))

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:
        """The seeds the sub-envs' generators were last created from."""
        return tuple(self._seeds)

    @property
    def particles_mm(self) -> NDArray[np.float32]:
        """Particles (N, M, 2), mm (a copy); weights are uniform after every update."""
        return self._soa.transpose(0, 2, 1).copy()

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """Carriage centres (N, 2), mm (a copy)."""
        return self._position.copy()

    @property
    def conditions(self) -> tuple[Condition, ...]:
        """Each sub-env's current condition."""
        return tuple(self._pool[i] for i in self._cidx)

    @property
    def sensor_models(self) -> tuple[Any, ...]:
        """Each sub-env's sensor model for its current episode."""
        for i, model in enumerate(self._models):
            if model is None and self._started:
                self._models[i] = CalibratedSensorModel(self._pool[self._cidx[i]], self._cal_seeds[i])
        return tuple(self._models)

    @property
    def allowed_half_width_mm(self) -> NDArray[np.float64]:
        """Half-width H of each sub-env's allowed box (N,), mm (the box is [−H, H]²)."""
        return self._pool_half[self._cidx]

    @property
    def n_observations(self) -> NDArray[np.int64]:
        """Readings fused so far in each sub-env's episode (N,) (a copy)."""
        return self._n_obs.copy()

    @property
    def last_reading_V(self) -> NDArray[np.float64]:
        """Each sub-env's last reading Φ (N,), V (a copy)."""
        return self._reading.copy()

    # ---- gymnasium API ------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Reset all sub-envs (or those in ``options["reset_mask"]``); seeds as SyncVectorEnv."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be None, an int or a sequence of {n} seeds, got {len(seeds)} seeds")
        mask = np.ones(n, dtype=bool)
        if options is not None and "reset_mask" in options:
            mask = options["reset_mask"]
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,) and mask.any()):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},) with a True entry")
        ids = np.flatnonzero(mask)
        for i in ids:
            if seeds[i] is not None:
                self._gens[i], self._seeds[i] = seeding.np_random(int(seeds[i]))
        self._reset_envs(ids)
        self._started = True
        self._autoreset[ids] = False
        return self._get_obs(), self._get_info()

    def step(self, actions: Any) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_],
                                          NDArray[np.bool_], dict[str, Any]]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        moves = self._actions_to_moves(actions)
        rewards = np.full(n, -1.0)
        if self.autoreset_mode is AutoresetMode.NEXT_STEP and self._autoreset.any():
            reset_ids = np.flatnonzero(self._autoreset)
            step_ids = np.flatnonzero(~self._autoreset)
            self._reset_draws(reset_ids)
            self._move(step_ids, moves[step_ids])
            self._observe(None)  # every env reads once: the stepped ones and the freshly reset ones
            self._elapsed[step_ids] += 1
            terminated, truncated = self._done_flags()
            terminated[reset_ids] = False
            truncated[reset_ids] = False
            rewards[reset_ids] = 0.0
            obs, info = self._get_obs(), self._get_info()
        else:
            self._move(None, moves)
            self._observe(None)
            self._elapsed += 1
            terminated, truncated = self._done_flags()
            obs, info = self._get_obs(), self._get_info()
            done = terminated | truncated
            if self.autoreset_mode is AutoresetMode.SAME_STEP and done.any():
                ids = np.flatnonzero(done)
                final_obs = np.full(n, None, dtype=object)
                for i in ids:
                    final_obs[i] = obs[i].copy()
                final_info = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in info.items()}
                for k in list(final_info):
                    if k.startswith("_"):
                        final_info[k] = done.copy()
                self._reset_envs(ids)
                new_obs, new_info = self._get_obs(ids), self._get_info(ids)
                obs[ids] = new_obs
                for k, v in new_info.items():
                    if not k.startswith("_"):
                        info[k][ids] = v
                info["final_obs"], info["_final_obs"] = final_obs, done.copy()
                info["final_info"], info["_final_info"] = final_info, done.copy()
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, info

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release (no subprocesses, no renderer)."""

    # ---- internals ----------------------------------------------------------------------------
    def _gen(self, i: int) -> np.random.Generator:
        if self._gens[i] is None:
            self._gens[i], self._seeds[i] = seeding.np_random(None)
        return self._gens[i]  # type: ignore[return-value]

    def _actions_to_moves(self, actions: Any) -> NDArray[np.float64]:
        n = self.num_envs
        if self.action_type == "discrete":
            a = np.asarray(actions)
            if (a.shape != (n,) or not np.issubdtype(a.dtype, np.integer)
                    or not np.all((a >= 0) & (a < len(DISCRETE_MOVES_MM)))):
                raise ValueError(f"actions must be {n} integers in [0, {len(DISCRETE_MOVES_MM) - 1}], got {actions!r}")
            return DISCRETE_MOVES_MM[a]
        a = np.asarray(actions, dtype=np.float64)
        if a.shape != (n, 2):
            raise ValueError(f"actions must have shape ({n}, 2) (dx, dy in [-1, 1]), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("actions must be finite (dx, dy in [-1, 1])")
        return np.minimum(np.maximum(a, -1.0), 1.0) * MAX_STEP_MM  # np.clip's values, less overhead

    def _move(self, ids: NDArray[np.intp] | None, moves: NDArray[np.float64]) -> None:
        """Carriage moves, kept inside each env's allowed box (the single env's np.clip)."""
        sel = slice(None) if ids is None else ids
        h = self._pool_half[self._cidx[sel]][:, None]
        self._position[sel] = np.minimum(np.maximum(self._position[sel] + moves, -h), h)

    def _reset_draws(self, ids: NDArray[np.intp]) -> None:
        """The per-env part of reset, in the single env's draw order (condition … particles)."""
        for i in ids:
            self._reset_one(int(i), self._gen(int(i)))

    def _reset_one(self, i: int, g: np.random.Generator) -> None:
        """Env ``i``'s reset draws, in ElectroLocEnv.reset's order (condition … particles)."""
        pool, m = self._pool, self.n_particles
        ci = int(g.integers(len(pool))) if len(pool) > 1 else 0
        c = pool[ci]
        cal_seed = self.calibration_seed if self.calibration_seed is not None else int(g.integers(2**31 - 1))
        if self._cal is not None:
            if self.calibration_seed is not None:  # one shared (cached) model
                model = make_sensor_model("calibrated", c, cal_seed)
                self._cal.set(i, model)
            else:  # a new calibration per episode: only its table now, the model object on demand
                model = None
                self._cal.calibrate(i, c, cal_seed)
        else:
            model = self._pool_analytic[ci]
        self._cidx[i] = ci
        self._models[i] = model
        self._cal_seeds[i] = cal_seed
        s = c.start_half_width_mm
        self._target[i] = g.uniform(-s, s, size=2) if self.randomize_target else np.asarray(c.target_xy_mm, float)
        self._position[i] = g.uniform(-s, s, size=2)
        h = c.allowed_half_width_mm
        low = np.array([-h, -h])
        uniform_in_box(g, low, -low, m, out_xy=(self._soa[i, 0], self._soa[i, 1]))
        self._n_obs[i] = 0
        self._elapsed[i] = 0

    def _reset_envs(self, ids: NDArray[np.intp]) -> None:
        self._reset_draws(ids)
        self._observe(None if len(ids) == self.num_envs else ids)

    def _observe(self, ids: NDArray[np.intp] | None) -> None:
        """Every selected env takes a noisy reading and fuses it: weight, resample, jitter (§4.1)."""
        full = ids is None
        sel: slice | NDArray[np.intp] = slice(None) if full else ids
        env_ids = range(self.num_envs) if full else [int(i) for i in ids]
        k = self.num_envs if full else len(ids)
        cidx = self._cidx[sel]
        noise_std = self._pool_noise[cidx]
        # Per-env draws, in the single env's order (normal, uniform, M·2 jitter table indices).
        noise = np.empty(k)
        u0 = np.empty(k)
        jitter = self._jitter_idx[:k]
        two_m = 2 * self.n_particles
        for j, (i, sd) in enumerate(zip(env_ids, noise_std.tolist())):
            g = self._gens[i] or self._gen(i)
            noise[j] = g.normal(0.0, sd)
            u0[j] = g.random()
            jitter[j] = table_normal_indices(g, two_m)
        # True readings (sensor.noisy_reading): float64 physics per distinct condition.
        position = self._position[sel]
        mean = self._true_mean(position, self._target[sel], cidx, k)
        sat = self._pool_sat[cidx]
        reading = np.minimum(np.maximum(mean + noise, -sat), sat)
        self._reading[sel] = reading
        self._n_obs[sel] += 1
        # Belief update, in blocks of ≈BLOCK_PARTICLES particles so that the temporaries stay in cache.
        b = self._block_envs
        for s0 in range(0, k, b):
            rows = slice(s0, min(s0 + b, k))
            esel = slice(s0, rows.stop) if full else ids[rows]
            self._fuse(esel, reading[rows], u0[rows], jitter[rows], cidx[rows], position[rows])

    def _true_mean(self, position: NDArray[np.float64], target: NDArray[np.float64], cidx: NDArray[np.intp],
                   k: int) -> NDArray[np.float64]:
        """Noise-free, unsaturated true readings (k,), V (sensor.noisy_reading's mean, float64)."""
        offsets = target - position
        return self._per_condition(cidx, lambda c, rows: expected_reading(self._pool[c], offsets[rows],
                                                                          saturate=False), k)

    #: Offsets = sign·(particle − frame origin): target hypothesis − carriage here.
    _OFFSET_SIGN = np.float32(1.0)

    def _frame_origin(self, position: NDArray[np.float64]) -> NDArray[np.float32]:
        """The sensor-model offsets' and the histogram's origin (k, 2), float32 mm: the carriage."""
        return position.astype(np.float32)

    def _true_state(self, sel: slice | NDArray[np.intp]) -> NDArray[np.float64]:
        """What the belief estimates (for info["error_mm"]): the target."""
        return self._target[sel]

    def _fuse(self, sel: slice | NDArray[np.intp], reading: NDArray[np.float64], u0: NDArray[np.float64],
              jitter: NDArray[np.uint16], cidx: NDArray[np.intp], position: NDArray[np.float64]) -> None:
        """Weight, resample and jitter the clouds of envs ``sel`` (a block); their mean, Σ and histogram counts."""
        m = self.n_particles
        k = len(reading)
        soa = self._soa[sel]  # a view for a slice: updated in place
        origin = self._frame_origin(position)
        mean, cov = np.empty((k, 2)), np.empty((k, 2, 2))
        counts = np.empty((k, HIST_BINS * HIST_BINS))
        half = self._pool_half[cidx].astype(np.float32)
        if self._cal is not None:  # the whole update in one kernel, one env at a time in cache, in place
            bad = calibrated_assimilate(soa, origin, self._OFFSET_SIGN, *self._cal.grid_args(sel),
                                        reading.astype(np.float32), u0, jitter, self._normal_table, half, soa,
                                        mean, cov, 2 * half, HIST_BINS, counts)
            if bad >= 0:
                raise ValueError("log-likelihood contains NaN (reading or sensor model produced NaN)")
            new = soa
        else:
            off = ((soa - origin[:, :, None]) * self._OFFSET_SIGN).transpose(0, 2, 1)
            ll = self._per_condition(cidx, lambda c, rows: self._pool_analytic[c].log_likelihood(
                reading[rows][:, None], off[rows]), k, (m,), np.float32)
            w, _ = shifted_exp_weights(ll)  # normalise_log_weights without its division (the kernel divides)
            new = np.empty_like(soa)
            resample_jitter_clip(w, weight_sums(w), u0, soa, jitter, self._normal_table, half, new,
                                 mean, cov, origin, 2 * half, HIST_BINS, counts)
        if not isinstance(sel, slice) or new is not soa:
            self._soa[sel] = new
        self._mean[sel], self._cov[sel], self._counts[sel] = mean, cov, counts

    def _per_condition(self, cidx: NDArray[np.intp], fn: Any, k: int, tail: tuple[int, ...] = (),
                       dtype: Any = np.float64) -> NDArray:
        """Apply ``fn(condition_index, rows)`` once per distinct condition (one call when fixed)."""
        if len(self._pool) == 1:
            return fn(0, slice(None))
        out = np.empty((k,) + tail, dtype=dtype)
        for c in np.unique(cidx):
            rows = np.flatnonzero(cidx == c)
            out[rows] = fn(int(c), rows)
        return out

    def _done_flags(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        spread = spread_from_cov(self._cov)
        success = spread <= self.success_spread_mm
        truncated = ~success & (self._n_obs >= self.max_observations)
        if self.max_episode_steps is not None:
            truncated |= self._elapsed >= self.max_episode_steps
        return success.copy(), truncated

    def _get_obs(self, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        sel = slice(None) if ids is None else ids
        cidx = self._cidx[sel]
        half = self._pool_half[cidx]
        if self.observation_mode == "raw":
            return raw_observation(self._position[sel], self._reading[sel], half, self._pool_sat[cidx])
        return belief_observation(
            self._position[sel], self._reading[sel], self._soa[sel].transpose(0, 2, 1), None, self._n_obs[sel],
            self.max_observations, half, self._pool_noise[cidx], self._pool_sat[cidx], self.success_spread_mm,
            self._pool_desc[cidx], mean_cov=(self._mean[sel], self._cov[sel]),
            hist=self._counts[sel] / self.n_particles)

    def _get_info(self, ids: NDArray[np.intp] | None = None) -> dict[str, Any]:
        sel = slice(None) if ids is None else ids
        est = self._mean[sel]
        cov = self._cov[sel]
        spread = spread_from_cov(cov)
        d = est - self._true_state(sel)
        info = {
            "position_mm": self._position[sel].copy(),
            "estimate_mm": est.copy(),
            "error_mm": np.hypot(d[:, 0], d[:, 1]),
            "spread_mm": spread,
            "reading_V": self._reading[sel].copy(),
            "n_observations": self._n_obs[sel].copy(),
            "success": spread <= self.success_spread_mm,
            "condition": self._pool_names[self._cidx[sel]],
        }
        masks = np.ones((len(info), len(spread)), dtype=bool)  # one allocation for the all-true masks
        for key, mask in zip(list(info), masks):
            info["_" + key] = mask
        return info


class GlobalLocalizationVectorEnv(ElectroLocVectorEnv):
    """
    ## Description

    ``num_envs`` copies of ElectroLocGlobal-v0
    (:class:`~electroloc_gym.envs.self_localize.GlobalLocalizationEnv`, the robot localises itself in
    a mapped tank, paper §6.5) stepped as arrays, with the same per-env behaviour as the single env
    under the same seeds (tested bit for bit): the particles are the robot's own position
    hypotheses, shifted by every commanded move; the sensor-model offsets are −particle; the reading
    is the map's (several objects). A fixed map only (``layout="benchmark"`` or a ``Scene``): with
    ``layout="random"`` every sub-env has its own map per episode, which cannot be evaluated as one
    array — use ``vectorization_mode="sync"`` for it.

    Spaces, rewards, episode end, info and autoreset as :class:`ElectroLocVectorEnv`; info
    ``position_mm`` is the true carriage position (the hidden state), ``error_mm`` the estimate's
    distance to it; the observation's entries 0–1 are the odometry (as the single env).

    ## Arguments

    ``num_envs``, ``layout``, ``observation``, ``sensor_model``, ``n_particles``,
    ``max_observations``, ``success_spread_mm``, ``action_type``, ``calibration_seed``,
    ``position_blur_mm`` (validated by GlobalLocalizationEnv), plus ``autoreset_mode`` and
    ``max_episode_steps`` as for :class:`ElectroLocVectorEnv`.
    """

    def __init__(
        self,
        num_envs: int = 1,
        layout: Any = "benchmark",
        observation: str = "belief",
        sensor_model: str = "calibrated",
        n_particles: int = 2500,
        max_observations: int = 35,
        success_spread_mm: float = 10.0,
        action_type: str = "continuous",
        calibration_seed: int | None = None,
        position_blur_mm: float | None = None,
        render_mode: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
    ) -> None:
        from electroloc_gym.envs.self_localize import GlobalLocalizationEnv
        from electroloc_gym.scene import BENCHMARK_SCENE, Scene
        from electroloc_gym.sensor_models.map import DEFAULT_POSITION_BLUR_MM, MapAnalyticSensorModel

        mode = _check_vector_args(num_envs, render_mode, autoreset_mode, max_episode_steps)
        if isinstance(layout, str) and layout == "random":
            raise ValueError("layout='random' (a new map per sub-env and episode) is not supported by the native "
                             "vector env; use gym.make_vec(..., vectorization_mode='sync') for it")
        blur = DEFAULT_POSITION_BLUR_MM if position_blur_mm is None else position_blur_mm
        template = GlobalLocalizationEnv(layout=layout, observation=observation, sensor_model=sensor_model,
                                         n_particles=n_particles, max_observations=max_observations,
                                         success_spread_mm=success_spread_mm, action_type=action_type,
                                         calibration_seed=calibration_seed, position_blur_mm=blur)
        self.scene: Scene = layout if isinstance(layout, Scene) else BENCHMARK_SCENE
        self.position_blur_mm = float(template.position_blur_mm)
        self.randomize_target = False
        self._init_common(template, int(num_envs), mode, max_episode_steps,
                          (self.scene.as_condition(),), (MapAnalyticSensorModel(self.scene, self.position_blur_mm),))
        self._odometry = np.zeros((self.num_envs, 2))

    @property
    def odometry_mm(self) -> NDArray[np.float64]:
        """Sum of the commanded moves since each sub-env's reset (N, 2), mm (a copy)."""
        return self._odometry.copy()

    @property
    def sensor_models(self) -> tuple[Any, ...]:
        return tuple(self._models)

    def _reset_one(self, i: int, g: np.random.Generator) -> None:
        """GlobalLocalizationEnv.reset's draws: calibration seed, start position, particles."""
        from electroloc_gym.sensor_models.map import make_map_sensor_model

        c = self._pool[0]
        cal_seed = self.calibration_seed if self.calibration_seed is not None else int(g.integers(2**31 - 1))
        model = make_map_sensor_model(self.sensor_model_name, self.scene, cal_seed,
                                      position_blur_mm=self.position_blur_mm)
        if self._cal is not None:
            self._cal.set(i, model)
        self._models[i] = model
        self._cidx[i] = 0
        s = self.scene.start_half_width_mm
        self._position[i] = g.uniform(-s, s, size=2)
        self._odometry[i] = 0.0
        h = c.allowed_half_width_mm
        low = np.array([-h, -h])
        uniform_in_box(g, low, -low, self.n_particles, out_xy=(self._soa[i, 0], self._soa[i, 1]))
        self._n_obs[i] = 0
        self._elapsed[i] = 0

    def _move(self, ids: NDArray[np.intp] | None, moves: NDArray[np.float64]) -> None:
        """The carriage moves (kept in the box); every hypothesis moves too (belief.predict)."""
        sel = slice(None) if ids is None else ids
        h = self._pool_half[self._cidx[sel]][:, None]
        self._position[sel] = np.clip(self._position[sel] + moves, -h, h)
        self._odometry[sel] = self._odometry[sel] + moves
        soa = self._soa[sel]
        soa += moves.astype(np.float32)[:, :, None]
        hf = h.astype(np.float32)[:, :, None]
        np.maximum(soa, -hf, out=soa)
        np.minimum(soa, hf, out=soa)
        self._soa[sel] = soa

    def _true_mean(self, position: NDArray[np.float64], target: NDArray[np.float64], cidx: NDArray[np.intp],
                   k: int) -> NDArray[np.float64]:
        return self.scene.expected_reading(np.asarray(position, dtype=np.float64), saturate=False)

    #: The map model's convention: offsets = map origin − carriage hypothesis = −particle.
    _OFFSET_SIGN = np.float32(-1.0)

    def _frame_origin(self, position: NDArray[np.float64]) -> NDArray[np.float32]:
        """The map origin (also the single env's histogram centre)."""
        return np.zeros((len(position), 2), dtype=np.float32)

    def _true_state(self, sel: slice | NDArray[np.intp]) -> NDArray[np.float64]:
        return self._position[sel]

    def _get_obs(self, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        sel = slice(None) if ids is None else ids
        cidx = self._cidx[sel]
        half = self._pool_half[cidx]
        odo = self._odometry[sel]
        if self.observation_mode == "raw":
            return raw_observation(odo, self._reading[sel], half, self._pool_sat[cidx])
        k = len(half)
        obs = belief_observation(
            np.zeros((k, 2)), self._reading[sel], self._soa[sel].transpose(0, 2, 1), None,
            self._n_obs[sel], self.max_observations, half, self._pool_noise[cidx], self._pool_sat[cidx],
            self.success_spread_mm, self._pool_desc[cidx], mean_cov=(self._mean[sel], self._cov[sel]),
            hist=self._counts[sel] / self.n_particles)
        obs[:, 0:2] = np.clip(odo / half[:, None], -1.0, 1.0)
        return obs


def make_global_vector_env(num_envs: int = 1, **kwargs: Any) -> GlobalLocalizationVectorEnv:
    """The ``vector_entry_point`` of ElectroLocGlobal-v0 (fixed maps; see :class:`GlobalLocalizationVectorEnv`)."""
    return GlobalLocalizationVectorEnv(num_envs=num_envs, **kwargs)


def make_electroloc_vector_env(num_envs: int = 1, **kwargs: Any) -> ElectroLocVectorEnv:
    """The ``vector_entry_point`` of ElectroLoc-v0 (``gym.make_vec(..., vectorization_mode="vector_entry_point")``)."""
    return ElectroLocVectorEnv(num_envs=num_envs, **kwargs)

