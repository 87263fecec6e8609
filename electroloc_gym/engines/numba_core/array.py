"""The ``localize`` task with a sensor array (ElectroLoc-v0's ``sensor_layout=``) and the stationary carriage (§7).

:class:`ArrayLocalizeTask` is ElectroLoc-v0's task. With the paper's one pair at the carriage centre (the
default ``sensor_layout="single"``, or any one-pair layout that is the paper's unit untranslated) every
reading, likelihood and draw is :class:`~electroloc_gym.engines.numba_core.localize_task.LocalizeTask`'s, bit for bit:
its
methods are used unchanged. Any other layout of K pairs (:mod:`electroloc_gym.world.sensor_array`) is the
*array path*:

* **reading**: each step takes K readings, one per pair, each with its own N(0, (G·σ_s)²) noise and the
  ±V_sat clip (the step draws the K noises in pair order from the env's generator), in the field of the
  carriage's emitters (or each unit's own, ``"grid-2x2"``) by :func:`~electroloc_gym.world.sensor_array.array_reading`;
* **calibration**: each pair has its own (``sensor_model="calibrated"``: one
  :class:`~electroloc_gym.sensor_models.pairs.ArrayCalibratedSensorModel` per episode, pair 0 from the
  episode's calibration seed, the others from :func:`~electroloc_gym.sensor_models.pairs.pair_seeds`);
* **fusion, one reading at a time**: the K readings of a step are fused as K successive particle-filter
  updates (pair 0 first), each with its own resampling offset and jitter. So a step of K pairs is exactly
  the filter a single pair runs over K readings, and "readings to localise" compares like with like across
  K. Fusing the K readings in one update (their summed log-likelihood) would jitter once instead of K times;
  the jitter (1 mm per axis) widens the cloud at every update, so one update per step shrinks the spread
  faster for a reason that is not sensing (experiments/array/commutativity.py measured the at-once spread ≈ 1.5 mm
  narrower than one by one on the 38.1 mm spheres). The extra draws of readings 1..K−1 (a resampling
  uniform, then the 2M jitter indices, per reading) come from the env's own generator after the step's;
* **observation**: the paper's layout with pair 0's reading at entries 2–3, then one entry per further pair,
  Φ_k / V_sat (k = 1..K−1): 80 + K entries (``"raw"``: ``[x/H, y/H, Φ_0/V_sat, …, Φ_{K−1}/V_sat]``);
* **info**: ``reading_V`` is pair 0's; ``pair_readings_V`` (K,) every pair's, V; ``n_readings`` = K × the
  snapshots taken (``n_observations`` counts snapshots, the cap ``max_observations`` too);
* **agents**: :meth:`ArrayLocalizeTask.predicted_mean_std` returns (…, K) means and stds (the pair axis
  last) — what :mod:`baselines.min_variance` and :mod:`baselines.lookahead` read to weigh K readings.

``fixed_carriage=True`` (any layout): the carriage stays where it started; the action space is unchanged
and every move is ignored (so Gymnasium and SB3 see the usual Box), and the agents' predictions use the
carriage that does not move. Dynamic gain (``gain_levels``) is for the paper's pair only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.observation import BELIEF_OBS_DIM, HIST_BINS, RAW_OBS_DIM, belief_observation
from electroloc_gym.contract.params import EnvParams, LocalizeOptions
from electroloc_gym.contract.task_spec import Boolean, option
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.engines.numba_core.state import State
from electroloc_gym.engines.numba_core.worlds import group_by_world
from electroloc_gym.kernels import loglik_assimilate
from electroloc_gym.kernels.streams import table_normal_indices
from electroloc_gym.sensor_models.pairs import ArrayAnalyticSensorModel, ArrayCalibratedSensorModel
from electroloc_gym.world.sensor_array import SensorLayout, array_reading, make_sensor_layout, named_layout

__all__ = ["ArrayLocalizeTask", "ArrayOptions", "is_paper_pair"]


def _sensor_layout(name: str, value: Any) -> Any:
    """A layout name (``"single"`` or a known one) as it is; anything else as a ``SensorLayout`` (one error
    naming ``sensor_layout``).
    """
    if not isinstance(value, str):
        return make_sensor_layout(value)
    if value != "single":
        named_layout(value)  # an unknown name: one error naming sensor_layout
    return value


@dataclass(frozen=True)
class ArrayOptions(LocalizeOptions):
    """The sensor array's options (ElectroLoc-v0's), beside the tank's.

    Attributes:
        sensor_layout: the carriage's sensing pairs (§7), a name of
            :data:`electroloc_gym.world.sensor_array.LAYOUT_NAMES`, a
            :class:`~electroloc_gym.world.sensor_array.SensorLayout`, or (K, 2, 2) electrode offsets in mm
            (stored as a ``SensorLayout``); ``"single"``: the paper's one pair.
        fixed_carriage: the carriage never moves (the stationary array); the action space is unchanged and
            its moves are ignored.
    """

    sensor_layout: Any = option(
        "single",
        doc="the carriage's sensing pairs: a layout name, a SensorLayout or (K, 2, 2) offsets",
        check=_sensor_layout,
    )
    fixed_carriage: bool = option(False, doc="the carriage never moves (the stationary array)", check=Boolean())


def is_paper_pair(layout: SensorLayout) -> bool:
    """True for one pair that is the paper's unit at the carriage centre (the ``"single"`` layout's pair)."""
    return layout.n_pairs == 1 and layout.paper_unit_centres[0] == (0.0, 0.0)


class ArrayLocalizeTask(LocalizeTask):
    """ElectroLoc-v0 with ``sensor_layout`` and ``fixed_carriage`` (module docstring).

    Raises:
        ValueError: a layout that does not fit the conditions' carriage, or ``gain_levels`` with an array
            (one error naming ``sensor_layout``).
    """

    Options = ArrayOptions
    options: ArrayOptions

    def __init__(self, params: EnvParams) -> None:
        super().__init__(params)
        self.options = params.options_as(ArrayOptions)
        self.fixed_carriage = self.options.fixed_carriage
        self.sensor_layout = make_sensor_layout(self.options.sensor_layout, self.pool[0].geometry)
        for c in self.pool:
            if c.geometry != self.sensor_layout.geometry:
                raise ValueError(
                    f"sensor_layout: was built for {self.sensor_layout.geometry}, condition {c.name} has {c.geometry}"
                )
        self.array = not is_paper_pair(self.sensor_layout)
        if not self.array:
            return
        if self.dynamic_gain:
            raise ValueError(
                "sensor_layout: an array of pairs reads at the preset gain; gain_levels needs sensor_layout='single'"
            )
        k = self.sensor_layout.n_pairs
        self.n_readings = k
        self.info_keys = ("pair_readings_V", "n_readings")
        self.obs_dim = (BELIEF_OBS_DIM if params.observation == "belief" else RAW_OBS_DIM) + k - 1
        self._array_analytic = [ArrayAnalyticSensorModel(c, self.sensor_layout) for c in self.pool]

    # ---- sizes: the array path fuses from numpy log-likelihoods, no coefficient table --------------
    def table_cells(self) -> int:
        """Coefficient rows per env: the paper's pair's table, none on the array path."""
        return 0 if self.array else super().table_cells()

    # ---- the episode ------------------------------------------------------------------------------
    def begin_episode(self, state: State, i: int, g: np.random.Generator) -> None:
        """As :meth:`LocalizeTask.begin_episode` (the same draws, in the same order); on the array path the
        calibration is built on first use from the drawn seed (one per pair).
        """
        if not self.array:
            super().begin_episode(state, i, g)
            return
        c = self._draw_condition(state, i, g)
        state.cal_seed[i] = self._cal_seed(g)
        state.model[i] = [None] if self.calibrated else [self._array_analytic[int(state.world_key[i])]]
        s = c.start_half_width_mm
        state.target_mm[i] = g.uniform(-s, s, size=2) if self.options.randomize_target else c.target_xy_mm
        self._place(state, i, g, s)

    def move(self, state: State, ids: NDArray[np.intp] | slice, moves_mm: NDArray[np.float64]) -> None:
        """The commanded moves (the carriage stays put with ``fixed_carriage``)."""
        if not self.fixed_carriage:
            super().move(state, ids, moves_mm)

    def _pairs(self, reading: NDArray[np.float64]) -> NDArray[np.float64]:
        """Readings as (k, K) (the state holds (k,) when K = 1)."""
        return reading.reshape(len(reading), self.sensor_layout.n_pairs)

    def true_mean_V(self, state: State, ids: NDArray[np.intp]) -> NDArray[np.float64]:
        """(k,) (paper's pair) or (k, K) noise-free, unsaturated readings of envs ``ids``, V."""
        if not self.array:
            return super().true_mean_V(state, ids)
        offsets = state.target_mm[ids] - state.position_mm[ids]
        out = np.empty((len(ids), self.sensor_layout.n_pairs))
        for c, rows in group_by_world(state, ids):
            out[rows] = array_reading(c, self.sensor_layout, offsets[rows], saturate=False).T
        return out if self.n_readings > 1 else out[:, 0]

    def assimilate(
        self,
        state: State,
        ids: NDArray[np.intp],
        reading: NDArray[np.float64],
        u0: NDArray[np.float64],
        jitter: NDArray[np.uint16],
        normal_table: NDArray[np.float32],
    ) -> int:
        """The paper's pair: :meth:`Task.assimilate`. The array path: K particle-filter updates, one per pair's
        reading (module docstring), each a compiled :func:`~electroloc_gym.kernels.loglik_assimilate`.
        """
        if not self.array:
            return super().assimilate(state, ids, reading, u0, jitter, normal_table)
        s = state
        k = len(ids)
        full = k == s.num_envs
        sel: Any = slice(None) if full else ids
        src = s.particles_mm if full else s.particles_mm[ids]
        origin = self.histogram_origin(s, sel)
        half = s.half_mm[sel].astype(np.float32)
        mean, cov, counts = np.empty((k, 2)), np.empty((k, 2, 2)), np.empty((k, HIST_BINS * HIST_BINS))
        pairs = self._pairs(reading)
        draws = jitter.shape[1]
        for j in range(self.sensor_layout.n_pairs):
            if j > 0:  # reading j's own resampling offset and jitter, from each env's generator
                for r, i in enumerate(ids.tolist()):
                    g = s.gens[i]
                    u0[r] = g.random()
                    jitter[r] = table_normal_indices(g, draws)
            ll = self._pair_log_likelihood(s, ids, src, origin, j, pairs[:, j])
            bad = loglik_assimilate(
                ll, src, origin, u0, jitter, normal_table, half, src, mean, cov, 2 * half, HIST_BINS, counts
            )
            if bad >= 0:
                return bad
        s.mean_mm[sel], s.cov_mm2[sel], s.counts[sel] = mean, cov, counts
        if not full:
            s.particles_mm[ids] = src
        return -1

    def _pair_log_likelihood(
        self,
        state: State,
        ids: NDArray[np.intp],
        src: NDArray[np.float32],
        origin: NDArray[np.float32],
        j: int,
        reading: NDArray[np.float64],
    ) -> NDArray[np.float32]:
        """(k, M) float32 log-likelihoods of pair ``j``'s readings (k,) at every env's particles."""
        off = ((src - origin[:, :, None]) * self.offset_sign).transpose(0, 2, 1)  # (k, M, 2) offsets
        ll = np.empty((len(ids), src.shape[2]), dtype=np.float32)
        if self.calibrated:  # every episode has its own calibration
            for r, i in enumerate(ids.tolist()):
                ll[r] = self.sensor_model(state, i).pair_log_likelihood(j, reading[r], off[r])
            return ll
        for _, rows in group_by_world(state, ids):
            model = self.sensor_model(state, int(ids[rows[0]]))
            ll[rows] = model.pair_log_likelihood(j, reading[rows][:, None], off[rows])
        return ll

    # ---- what is reported -------------------------------------------------------------------------
    def observation(self, state: State, ids: NDArray[np.intp] | None = None) -> NDArray[np.float32]:
        """The paper's observation (pair 0's reading), then Φ_k / V_sat of pairs 1..K−1 (module docstring)."""
        if not self.array:
            return super().observation(state, ids)
        s, sel = state, slice(None) if ids is None else ids
        p = self.params
        half, sat = s.half_mm[sel], s.saturation_V[sel]
        pairs = self._pairs(s.reading_V[sel])
        scaled = np.clip(pairs / sat[:, None], -1.0, 1.0).astype(np.float32)
        if p.observation == "raw":
            ref = np.clip(self.reference_mm(s, sel) / half[:, None], -1.0, 1.0).astype(np.float32)
            return np.concatenate([ref, scaled], axis=1)
        obs = belief_observation(
            self.belief_origin_mm(s, sel),
            pairs[:, 0],
            s.mean_mm[sel],
            s.cov_mm2[sel],
            s.counts[sel] / s.n_particles,
            s.n_observations[sel],
            p.max_observations,
            half,
            s.noise_V[sel],
            sat,
            p.success_spread_mm,
            s.descriptor[sel],
        )
        return np.concatenate([obs, scaled[:, 1:]], axis=1)

    def info(self, state: State, ids: NDArray[np.intp] | None = None) -> dict[str, NDArray]:
        """:meth:`Task.info`; on the array path ``reading_V`` is pair 0's, plus ``pair_readings_V`` and
        ``n_readings``.
        """
        out = super().info(state, ids)
        if self.array:
            pairs = self._pairs(out["reading_V"])
            out["reading_V"] = pairs[:, 0].copy()
            out["pair_readings_V"] = pairs.copy()
            out["n_readings"] = out["n_observations"] * self.sensor_layout.n_pairs
        return out

    # ---- what agents predict ----------------------------------------------------------------------
    def offsets_after_move(self, state: State, i: int, particles: NDArray, moves_mm: NDArray) -> NDArray:
        """Target hypothesis − the carriage after the move (the carriage does not move with ``fixed_carriage``)."""
        if not self.fixed_carriage:
            return super().offsets_after_move(state, i, particles, moves_mm)
        carriage = np.broadcast_to(state.position_mm[i], np.shape(moves_mm)).astype(particles.dtype)
        return particles[..., :2] - carriage[..., None, :]

    def sensor_model(self, state: State, i: int, level: int | None = None) -> Any:
        """The paper's pair: :meth:`LocalizeTask.sensor_model`. The array path: env ``i``'s K-pair model
        (``mean_std`` → (K, …); ``log_likelihood`` of K readings), the calibrated one built on first use.
        """
        if not self.array:
            return super().sensor_model(state, i, level)
        models = state.model[i]
        if models[0] is None:
            models[0] = ArrayCalibratedSensorModel(
                state.world[i], self.sensor_layout, int(state.cal_seed[i]), self.protocol
            )
        return models[0]

    def predicted_mean_std(
        self, state: State, i: int, particles: NDArray, moves_mm: NDArray, level: int | None = None
    ) -> tuple[NDArray, NDArray]:
        """Mean and std (V) of each hypothesis' reading after the moves: (…) for one pair, (…, K) for K ≥ 2
        (the pair axis last).
        """
        mean, std = super().predicted_mean_std(state, i, particles, moves_mm, level)
        if not self.array:
            return mean, std
        if self.n_readings == 1:
            return mean[0], std[0]
        return np.moveaxis(mean, 0, -1), np.moveaxis(std, 0, -1)
