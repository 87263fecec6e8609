"""Whole-step conformance: from the same state and the same draws, one step of each registered engine gives
the same next state, observation, reward, flags and info, within tolerances stated per quantity.

The reference engine (numba) is reset and stepped a few times; its state — the carriage, the target, the
condition, the particles, the belief's moments and histogram, the counters — is loaded into every other
engine, and both take one step with the same actions and the same injected draws (each env's reading
noise as a normal-table index, its resampling offset, its 2M jitter indices: what the numba engine's
generator and the torch engine's counter-based streams would give). A harness per engine
(:data:`HARNESSES`, keyed by the registered backend names) says how to load a state, inject draws and
read the results, so a third engine registers a harness and runs the suite unchanged.

Tolerances (the engines round differently: the torch engine's likelihoods and resampling pointers are
its own float32/float64 kernels): the carriage exactly; the reading to 1e-9 V; the resampled particles
equal for ≥ 99.9 % (a pointer within rounding of a cumulative weight may pick its neighbour), the mean
to 1e-3 mm, the covariance to 1e-3 relative, the histogram counts to twice the differing particles; the
observation to 1e-4 (it is computed from those); reward, terminated, truncated and the counters exactly.

Autoreset steps: some envs are marked ended (their done flag, as the step that ended them leaves it), so
this step resets them (next-step autoreset) and every env reads once. Their reset draws are injected too —
the condition's index, the target's and the start's uniforms, the particles' uniforms (on the 2⁻²⁴ grid of
the torch engine's float32 draws) — and the same tolerances hold for them; their reward is 0 and their flags
false in both engines.

Per-episode calibrations (``calibration_seed=None``, the default): the engines keep different layouts —
the numba engine each env's float32 bilinear coefficients (and its episode's calibration seed), the torch
engine each env's float64 mean and std grids, padded to the pool's largest. The reference's state hands
out each env's calibration as its (n, n) float64 mean and std grids (the numba engine's own statistics of
its episode, checked to round to its coefficient table bit for bit) and each harness loads them in its own
layout; the grids after the step are compared too, loaded ones exactly. A reset's calibration draws are
injected like the others: the calibration seed the numba engine's generator hands out, and for an engine
that draws the readings itself the same readings' normal-table indices (those the numba engine takes from
``default_rng(seed)``); its grids then agree to 1e-12 relative (each engine sums the samples its own way).

The agent accessors (:data:`ACCESSORS`, what the controllers read): from the same loaded state, each
engine's agent view of env i — the numba single env holding the reference's row i (its predictions checked
equal to the vector env's own), the torch engine's ``sub_env(i)`` — gives the same belief (particles,
weights, mean, covariance, spread), carriage (position, box, move bounds), reading count, last reading,
hypotheses after a move and predicted readings (mean and std of the agent's sensor model at the moved
carriage, for the belief's particles and hypotheses off the calibration grid, one move and 16): the
predicted readings to 5·10⁻⁵ of the env's reading noise G·σ_s (each engine's float32 sensor model: the
analytic physics cancels to a few float32 ulps of the largest reading), the rest exactly, dtypes and shapes
included. A harness's ``view(i)`` is its engine's agent view of env i.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.engines.numba_core import step as numba_step  # noqa: E402
from electroloc_gym.engines.numba_core.state import State  # noqa: E402
from electroloc_gym.engines.numba_core.worlds import SEED_BOUND  # noqa: E402
from electroloc_gym.engines.torch_core import sim  # noqa: E402
from electroloc_gym.engines.torch_core.calibration import grids_from_draws  # noqa: E402
from electroloc_gym.engines.torch_core.rng import STREAMS  # noqa: E402
from electroloc_gym.envs import ElectroLocEnv, ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.agent_view import agent_view  # noqa: E402
from electroloc_gym.envs.sim_backends import backends_of  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402
from electroloc_gym.kernels.streams import normal_table, table_normal_indices  # noqa: E402
from electroloc_gym.protocol import MAX_STEP_MM  # noqa: E402
from electroloc_gym.registry import env_entry  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES  # noqa: E402

torch.set_num_threads(1)
N, M = 6, 400
TABLE = normal_table()
#: What the step hands out and the state keeps that every engine must agree on (module docstring).
STATE_KEYS = ("position_mm", "target_mm", "particles_mm", "reading_V", "n_observations", "elapsed")


def per_episode_calibration(kw: dict[str, Any]) -> bool:
    """Whether the case draws a calibration per episode (the state then carries each env's grids)."""
    return kw.get("sensor_model", "calibrated") == "calibrated" and kw.get("calibration_seed") is None


class _Reset:
    """One env's injected reset draws: the condition's pool index, the calibration's seed, the target's and
    the start's two uniforms each, the particles' (M, 2) uniforms (x, y)."""

    def __init__(self, rng: np.random.Generator, pool: int) -> None:
        self.cond = int(rng.integers(0, pool))
        self.cal_seed = int(rng.integers(0, SEED_BOUND))
        self.target_u, self.start_u = rng.random(2), rng.random(2)
        self.particles_u = rng.integers(0, 2**24, (M, 2)) / 2.0**24  # the torch engine's float32 grid

    def calibration_indices(self, samples: int, points: int) -> np.ndarray:
        """(samples, n, n) the calibration readings' normal-table indices: the numba engine's from the seed
        (:func:`~electroloc_gym.world.sensor.add_calibration_noise` with ``default_rng(cal_seed)``)."""
        rng = np.random.default_rng(self.cal_seed)
        return table_normal_indices(rng, samples * points * points).reshape(samples, points, points)


class _Draws:
    """One env's injected draws, as the numba engine's generator would hand them out: a reset's (when it
    resets this step, in :meth:`ElectroLocTask.begin_episode`'s order), then the reading's."""

    def __init__(
        self, noise_idx: int, u0: float, jitter: np.ndarray, reset: _Reset, randomize_target: bool = False
    ) -> None:
        self.noise_idx, self.u0, self.jitter, self.reset = noise_idx, u0, jitter, reset
        self._boxes = [reset.target_u, reset.start_u] if randomize_target else [reset.start_u]

    def integers(self, high: int) -> int:
        if high == SEED_BOUND:  # the calibration's seed (after the condition's index)
            return self.reset.cal_seed
        assert self.reset.cond < high
        return self.reset.cond

    def uniform(self, low: float, high: float, size: int) -> np.ndarray:
        assert size == 2
        return low + (high - low) * self._boxes.pop(0)  # numpy's construction of uniform(low, high)

    def normal(self, loc: float, scale: float, size: Any = None) -> float:
        assert size is None and loc == 0.0
        return float(np.float64(TABLE[self.noise_idx]) * scale)

    def random(self, size: Any = None) -> Any:
        if size is None:
            return self.u0
        assert tuple(size) == (M, 2)
        return self.reset.particles_u.copy()


class NumbaHarness:
    """The reference engine: the native vector env's simulation, its generators replaced by the draws."""

    def __init__(self, kw: dict[str, Any]) -> None:
        self.kw = kw
        self.env = ElectroLocVectorEnv(num_envs=N, n_particles=M, **kw)

    def state(self) -> dict[str, Any]:
        """The state's arrays; with a per-episode calibration also ``"calibration"``: each env's (mean, std)
        (n, n) float64 grids, V — its episode's sensor model's, which round to its coefficient rows."""
        s = self.env._sim.state
        out: dict[str, Any] = {k: np.array(getattr(s, k)) for k in STATE_KEYS}
        out.update(mean_mm=s.mean_mm.copy(), cov_mm2=s.cov_mm2.copy(), counts=s.counts.copy(), done=s.done.copy())
        if per_episode_calibration(self.kw):
            task, grids = self.env._sim.task, []
            for i in range(N):
                model = task.sensor_model(s, i)
                rows = s.table[s.table_row[i] : s.table_row[i] + model._coef.shape[0]]
                np.testing.assert_array_equal(rows, model._coef.astype(np.float32))  # the state's table
                grids.append((model.mean_table_V.copy(), model.std_table_V.copy()))
            out["calibration"] = grids
        return out

    def view(self, i: int) -> Any:
        """Env ``i``'s agent view: a single env holding row ``i`` of the vector env's state."""
        single = ElectroLocEnv(n_particles=M, **self.kw)
        single.reset(seed=0)
        src, dst = self.env._sim.state, single._sim.state
        scratch = ("gens", "seeds", "table_row", "table", "jitter_idx", "started", "worlds_drawn", "distractor_scenes")
        for f in dataclasses.fields(State):
            if f.name in scratch:
                continue
            if f.name == "task":  # the task's own arrays: row i of each, over the task's fields
                dst.task.put([0], src.task.take([i]))
                continue
            v = getattr(src, f.name)
            getattr(dst, f.name)[0] = list(v[i]) if isinstance(v[i], list) else v[i]
        rows = src.table.shape[0] // N
        dst.table[dst.table_row[0] : dst.table_row[0] + rows] = src.table[src.table_row[i] : src.table_row[i] + rows]
        return agent_view(single)

    def step(self, actions: np.ndarray, draws: list[_Draws], monkeypatch: pytest.MonkeyPatch) -> tuple:
        s = self.env._sim.state
        s.gens = list(draws)
        monkeypatch.setattr(numba_step, "table_normal_indices", lambda g, count: g.jitter)
        out = self.env.step(actions)
        monkeypatch.undo()
        return out


class TorchHarness:
    """The torch engine on the CPU (eager), its state loaded from the reference's and its streams replaced."""

    def __init__(self, kw: dict[str, Any]) -> None:
        self.env = TorchElectroLocVectorEnv(num_envs=N, n_particles=M, **kw)
        self.env.reset(seed=0)

    def load(self, ref: dict[str, Any], cond: np.ndarray) -> None:
        s = dict(self.env.state)
        for k in (*STATE_KEYS, "mean_mm", "cov_mm2", "counts", "done"):
            s[k] = torch.as_tensor(np.ascontiguousarray(ref[k])).to(s[k].dtype)
        s["cond"] = torch.as_tensor(cond, dtype=torch.int64)
        if "calibration" in ref:  # (n_j, n_j) grids into the (2, n²) layout, padded to the pool's largest n
            n = self.env.consts.grid_n
            table = torch.zeros_like(s["table"]).reshape(N, 2, n, n)
            for i, (mean, std) in enumerate(ref["calibration"]):
                k = mean.shape[0]
                table[i, 0, :k, :k] = torch.from_numpy(mean)
                table[i, 1, :k, :k] = torch.from_numpy(std)
            s["table"] = table.reshape(N, 2, n * n)
        self.env._state = s

    def state(self) -> dict[str, Any]:
        s, c = self.env.state, self.env.consts
        out: dict[str, Any] = {k: s[k].numpy().copy() for k in (*STATE_KEYS, "mean_mm", "cov_mm2", "counts", "done")}
        if sim.per_episode_calibration(c):
            n = c.grid_n
            grids = s["table"].reshape(N, 2, n, n)
            points = c.grid_points[s["cond"]].tolist()
            out["calibration"] = [
                (g[0, :k, :k].numpy().copy(), g[1, :k, :k].numpy().copy()) for g, k in zip(grids, points)
            ]
        return out

    def view(self, i: int) -> Any:
        """Env ``i``'s agent view: the engine's ``sub_env(i)``."""
        return self.env.sub_env(i)

    def step(self, actions: np.ndarray, draws: list[_Draws], monkeypatch: pytest.MonkeyPatch) -> tuple:
        noise = torch.tensor([[d.noise_idx] for d in draws], dtype=torch.int64)
        u0 = torch.tensor([[d.u0] for d in draws], dtype=torch.float64)
        jit = torch.tensor(np.stack([d.jitter for d in draws]).astype(np.int64))
        pool = self.env.consts.pool
        cond_bits = torch.tensor([[-(-(d.reset.cond << 32) // pool)] for d in draws])  # (bits · pool) >> 32 = cond
        uniforms = {
            STREAMS["target"]: torch.tensor(np.stack([d.reset.target_u for d in draws])),
            STREAMS["start"]: torch.tensor(np.stack([d.reset.start_u for d in draws])),
        }
        particles = torch.tensor(np.stack([d.reset.particles_u.T.reshape(-1) for d in draws]))  # x then y
        resetting = torch.nonzero(self.env.state["done"]).reshape(-1)

        def rows(key):  # every env's draws, or the resetting envs' (gathered)
            return torch.arange(N) if key.shape[0] == N else resetting

        def stream_key(k0, k1, ep, t, stream):  # the stream's id stands for its key
            return torch.full_like(k0, int(stream))

        def normal_pair_indices(key, count):
            if int(key[0]) == STREAMS["noise"]:
                return noise, noise
            assert int(key[0]) == STREAMS["jitter"] and count == M
            return jit[:, 0::2], jit[:, 1::2]

        def uniform53(key, count):
            if int(key[0]) == STREAMS["resample"]:
                assert count == 1
                return u0
            assert count == 2
            return uniforms[int(key[0])][rows(key)]

        def uniform24(key, count):
            assert int(key[0]) == STREAMS["particles"] and count == 2 * M
            return particles[rows(key)]

        def bits32(key, count):
            assert int(key[0]) == STREAMS["condition"] and count == 1
            return cond_bits[rows(key)]

        def calibration_grids(c, cond, k0, k1, episode):  # the same readings' draws as the numba engine's
            assert cond.shape[0] == resetting.shape[0]
            n, samples = c.grid_n, c.samples_per_point
            idx = torch.zeros(resetting.shape[0], samples, n, n, dtype=torch.int64)
            for r, (e, k) in enumerate(zip(resetting.tolist(), c.grid_points[cond].tolist())):
                idx[r, :, :k, :k] = torch.from_numpy(draws[e].reset.calibration_indices(samples, k).astype(np.int64))
            mean, std = grids_from_draws(c, cond, lambda t: idx[:, t])
            return torch.stack([mean, std], dim=1).reshape(-1, 2, n * n)

        monkeypatch.setattr(sim, "stream_key", stream_key)
        monkeypatch.setattr(sim, "normal_pair_indices", normal_pair_indices)
        monkeypatch.setattr(sim, "uniform53", uniform53)
        monkeypatch.setattr(sim, "uniform24", uniform24)
        monkeypatch.setattr(sim, "bits32", bits32)
        monkeypatch.setattr(sim, "calibration_grids", calibration_grids)
        out = self.env.step(torch.as_tensor(actions))
        monkeypatch.undo()
        return tuple(v.numpy() if isinstance(v, torch.Tensor) else v for v in out[:4]) + (
            {k: v.numpy() for k, v in out[4].items()},
        )


#: A harness per registered engine of ElectroLoc-v0 (the test below fails on an engine without one).
HARNESSES = {"numba": NumbaHarness, "torch": TorchHarness}
OTHERS = [e for e in backends_of(env_entry("ElectroLoc-v0")) if e != "numba"]

GRID = [
    *({"condition": name, "sensor_model": "analytic"} for name in PRESET_NAMES),
    {"condition": "random", "sensor_model": "analytic", "randomize_target": True},
    {"condition": "fresh-steel-12.7", "calibration_seed": 3},
    {"condition": "salt-delrin-38.1", "calibration_seed": 5, "observation": "raw"},
    {"condition": "random", "sensor_model": "analytic", "action_type": "discrete"},
    {"condition": "fresh-steel-12.7", "calibration_seed": 3, "action_type": "discrete", "max_episode_steps": 2},
    # a calibration per episode (the default): the reference's grids loaded, a reset's draws injected
    {"condition": "fresh-delrin-38.1"},
    {"condition": "random", "randomize_target": True},
    {"condition": "salt-steel-12.7", "observation": "raw", "action_type": "discrete", "max_episode_steps": 2},
]


def test_every_registered_engine_has_a_harness():
    assert set(backends_of(env_entry("ElectroLoc-v0"))) == set(HARNESSES)


def _loaded(engine: str, kw: dict[str, Any], ended: list[int]) -> tuple:
    """The reference one step into its episodes (the envs ``ended`` marked ended) and ``engine``'s harness
    holding the same state; returns both harnesses, the reference's state, the actions' generator and the pool.
    """
    ref = NumbaHarness(kw)
    rng = np.random.default_rng(7)
    discrete = kw.get("action_type") == "discrete"

    def actions() -> np.ndarray:
        return rng.integers(0, 9, N) if discrete else rng.uniform(-1, 1, (N, 2)).astype(np.float32)

    for seed in range(11, 60):  # one step into the episode, every env still in it (the first such seed)
        ref.env.reset(seed=seed)
        ref.env.step(actions())
        start = ref.state()
        if not start["done"].any():
            break
    assert not start["done"].any()
    ref.env._sim.state.done[ended] = True
    start = ref.state()
    other = HARNESSES[engine](kw)
    pool = list(PRESET_NAMES) if kw["condition"] == "random" else [kw["condition"]]
    other.load(start, np.array([pool.index(c.name) for c in ref.env.conditions]))  # the engine's pool index
    return ref, other, start, rng, pool, actions


def _one_step_of_both(engine: str, kw: dict[str, Any], monkeypatch: pytest.MonkeyPatch, ended: list[int]) -> tuple:
    """From the same state (the envs ``ended`` marked ended: this step resets them) and the same draws, one
    step of the reference and of ``engine``; returns both results, checked equal within the module's
    tolerances.
    """
    ref, other, start, rng, pool, actions = _loaded(engine, kw, ended)
    a = actions()
    draws = [
        _Draws(
            int(rng.integers(0, 2**16)),
            rng.random(),
            table_normal_indices(rng, 2 * M),
            _Reset(rng, len(pool)),
            kw.get("randomize_target", False),
        )
        for _ in range(N)
    ]
    obs_r, rew_r, te_r, tr_r, info_r = ref.step(a, draws, monkeypatch)
    obs_o, rew_o, te_o, tr_o, info_o = other.step(a, draws, monkeypatch)
    got, want = other.state(), ref.state()

    np.testing.assert_array_equal(got["position_mm"], want["position_mm"])  # the move and the walls
    np.testing.assert_array_equal(got["target_mm"], want["target_mm"])
    np.testing.assert_allclose(got["reading_V"], want["reading_V"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got["n_observations"], want["n_observations"])
    np.testing.assert_array_equal(got["elapsed"], want["elapsed"])
    same = (got["particles_mm"] == want["particles_mm"]).all(axis=1)
    assert same.mean(axis=1).min() > 0.999  # resampling indices equal away from ties
    np.testing.assert_allclose(got["mean_mm"], want["mean_mm"], rtol=0, atol=1e-3)
    np.testing.assert_allclose(got["cov_mm2"], want["cov_mm2"], rtol=1e-3, atol=1e-3)
    assert (np.abs(got["counts"] - want["counts"]).sum(axis=1) <= 2 * (~same).sum(axis=1)).all()
    np.testing.assert_allclose(obs_o, obs_r, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(rew_o, rew_r)
    np.testing.assert_array_equal(te_o, te_r)
    np.testing.assert_array_equal(tr_o, tr_r)
    np.testing.assert_array_equal(got["done"], want["done"])
    for key in ("position_mm", "estimate_mm", "error_mm", "spread_mm", "reading_V"):
        np.testing.assert_allclose(info_o[key], info_r[key], rtol=1e-6, atol=1e-3, err_msg=key)
    np.testing.assert_array_equal(info_o["n_observations"], info_r["n_observations"])
    np.testing.assert_array_equal(info_o["success"], info_r["success"])
    np.testing.assert_array_equal(info_o["condition_index"], info_r["condition_index"])
    if per_episode_calibration(kw):  # the loaded grids kept, a reset's drawn from the same readings
        for i, (g_o, g_r) in enumerate(zip(got["calibration"], want["calibration"], strict=True)):
            for o, r in zip(g_o, g_r, strict=True):
                if i in ended:
                    np.testing.assert_allclose(o, r, rtol=1e-12, atol=1e-15)
                else:
                    np.testing.assert_array_equal(o, r)
    return (obs_r, rew_r, te_r, tr_r, info_r, want), (obs_o, rew_o, te_o, tr_o, info_o, got), draws, ref.env


@pytest.mark.parametrize("engine", OTHERS)
@pytest.mark.parametrize("kw", GRID, ids=[f"{i}" for i in range(len(GRID))])
def test_one_step_from_the_same_state_and_draws_is_the_same(engine, kw, monkeypatch):
    _one_step_of_both(engine, kw, monkeypatch, ended=[])


@pytest.mark.parametrize("engine", OTHERS)
@pytest.mark.parametrize("kw", GRID, ids=[f"{i}" for i in range(len(GRID))])
def test_an_autoreset_step_from_the_same_state_and_draws_is_the_same(engine, kw, monkeypatch):
    ended = [1, 4]
    ref, other, draws, env = _one_step_of_both(engine, kw, monkeypatch, ended=ended)
    for _obs, rew, te, tr, _info, state in (ref, other):
        assert (rew[ended] == 0.0).all() and not te[ended].any() and not tr[ended].any()
        assert (rew[[0, 2, 3, 5]] == -1.0).all()
        assert (state["elapsed"][ended] == 0).all() and (state["n_observations"][ended] == 1).all()
    for i in ended:  # the injected reset draws are the episode's: its condition and its start
        c = env.conditions[i]
        pool = list(PRESET_NAMES) if kw["condition"] == "random" else [kw["condition"]]
        assert c.name == pool[draws[i].reset.cond]
        h = c.start_half_width_mm
        np.testing.assert_array_equal(ref[5]["position_mm"][i], -h + (h - -h) * draws[i].reset.start_u)
    if per_episode_calibration(kw):
        np.testing.assert_array_equal(env._sim.state.cal_seed[ended], [draws[i].reset.cal_seed for i in ended])


# ---- the agent accessors ------------------------------------------------------------------------------------------


class Probe:
    """What the accessors are asked: the belief's own particles and hypotheses beyond the box (off the
    calibration grid), float32 mm; one move and 16 moves beyond ±10 mm (clipped like ``step``; some into a
    wall), mm."""

    def __init__(self, view: Any, seed: int) -> None:
        rng = np.random.default_rng(seed)
        self.particles = np.concatenate([view.belief.particles, rng.uniform(-140, 140, (200, 2)).astype(np.float32)])
        self.move = np.array([3.0, -4.0])
        self.moves = rng.uniform(-14.0, 14.0, (16, 2))


def _prediction(which: int, single: bool) -> Callable[[Any, Probe], Any]:
    def read(view: Any, probe: Probe) -> Any:
        return view.predicted_reading_model(probe.particles, probe.move if single else probe.moves)[which]

    return read


#: The agent accessors the controllers read (agent_view's names), each as how it is read from an engine's agent
#: view and its tolerance, in units of the env's reading noise G·σ_s (0: equal; dtype and shape equal always):
#: the predicted readings are each engine's own sensor model in float32 (the analytic physics cancels to a few
#: float32 ulps of the row's largest value, ≤ 10⁻⁵ G·σ_s), the rest read the loaded state.
ACCESSORS: dict[str, tuple[Callable[[Any, Probe], Any], float]] = {
    "belief.particles": (lambda v, p: v.belief.particles, 0.0),
    "belief.weights": (lambda v, p: v.belief.weights, 0.0),
    "belief.uniform_weights": (lambda v, p: v.belief.uniform_weights, 0.0),
    "belief.mean()": (lambda v, p: v.belief.mean(), 0.0),
    "belief.covariance()": (lambda v, p: v.belief.covariance(), 0.0),
    "belief.spread()": (lambda v, p: v.belief.spread(), 0.0),
    "position_mm": (lambda v, p: v.position_mm, 0.0),
    "allowed_box_mm": (lambda v, p: np.stack(v.allowed_box_mm), 0.0),
    "move_bounds_mm": (lambda v, p: np.stack(v.move_bounds_mm), 0.0),
    "n_observations": (lambda v, p: v.n_observations, 0.0),
    "last_reading_V": (lambda v, p: v.last_reading_V, 0.0),
    "predicted_particles_mm(move)": (lambda v, p: v.predicted_particles_mm(p.particles, p.move), 0.0),
    "predicted_particles_mm(moves)": (lambda v, p: v.predicted_particles_mm(p.particles, p.moves), 0.0),
    "predicted_reading_model(move) mean": (_prediction(0, True), 5e-5),
    "predicted_reading_model(move) std": (_prediction(1, True), 5e-5),
    "predicted_reading_model(moves) mean": (_prediction(0, False), 5e-5),
    "predicted_reading_model(moves) std": (_prediction(1, False), 5e-5),
}

ACCESSOR_GRID = [
    {"condition": "fresh-steel-12.7", "sensor_model": "analytic"},
    {"condition": "random", "sensor_model": "analytic", "randomize_target": True},
    {"condition": "salt-delrin-38.1", "calibration_seed": 5},
    {"condition": "fresh-delrin-12.7"},
    {"condition": "random"},
]


@pytest.mark.parametrize("engine", OTHERS)
@pytest.mark.parametrize("kw", ACCESSOR_GRID, ids=[f"{i}" for i in range(len(ACCESSOR_GRID))])
def test_the_agent_accessors_of_the_same_state_are_the_same(engine, kw):
    ref, other, _start, _rng, _pool, _actions = _loaded(engine, kw, ended=[])
    s, task = ref.env._sim.state, ref.env._sim.task
    for i in range(N):
        want_view, got_view = ref.view(i), other.view(i)
        probe = Probe(want_view, i)
        noise_V = want_view.condition.noise_std_V
        for name, (read, tolerance) in ACCESSORS.items():
            want, got = np.asarray(read(want_view, probe)), np.asarray(read(got_view, probe))
            assert (got.dtype, got.shape) == (want.dtype, want.shape), name
            if tolerance == 0.0:
                np.testing.assert_array_equal(got, want, err_msg=name)
            else:
                np.testing.assert_allclose(got, want, rtol=0, atol=tolerance * noise_V, err_msg=name)
        # the single env reads the vector env's row: its predictions are the vector env's own
        for moves in (probe.move, probe.moves):
            want = task.predicted_mean_std(s, i, probe.particles, np.clip(moves, -MAX_STEP_MM, MAX_STEP_MM), None)
            for a, b in zip(want_view.predicted_reading_model(probe.particles, moves), want, strict=True):
                np.testing.assert_array_equal(a, b)
