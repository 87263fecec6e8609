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

Not covered here: per-episode calibrations (the engines keep different tables: the numba engine the
coefficients, the torch engine the grids); a fixed ``calibration_seed``'s table is the same in both
(tests/test_torch_backend.py) and is used for the calibrated cases.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.engines.numba_core import step as numba_step  # noqa: E402
from electroloc_gym.engines.torch_core import sim  # noqa: E402
from electroloc_gym.engines.torch_core.rng import STREAMS  # noqa: E402
from electroloc_gym.envs.sim_backends import backends_of  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.vector import ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.kernels.streams import normal_table, table_normal_indices  # noqa: E402
from electroloc_gym.registry import env_entry  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES  # noqa: E402

torch.set_num_threads(1)
N, M = 6, 400
TABLE = normal_table()
#: What the step hands out and the state keeps that every engine must agree on (module docstring).
STATE_KEYS = ("position_mm", "target_mm", "particles_mm", "reading_V", "n_observations", "elapsed")


class _Reset:
    """One env's injected reset draws: the condition's pool index, the target's and the start's two
    uniforms each, the particles' (M, 2) uniforms (x, y)."""

    def __init__(self, rng: np.random.Generator, pool: int) -> None:
        self.cond = int(rng.integers(0, pool))
        self.target_u, self.start_u = rng.random(2), rng.random(2)
        self.particles_u = rng.integers(0, 2**24, (M, 2)) / 2.0**24  # the torch engine's float32 grid


class _Draws:
    """One env's injected draws, as the numba engine's generator would hand them out: a reset's (when it
    resets this step, in :meth:`ElectroLocTask.begin_episode`'s order), then the reading's."""

    def __init__(
        self, noise_idx: int, u0: float, jitter: np.ndarray, reset: _Reset, randomize_target: bool = False
    ) -> None:
        self.noise_idx, self.u0, self.jitter, self.reset = noise_idx, u0, jitter, reset
        self._boxes = [reset.target_u, reset.start_u] if randomize_target else [reset.start_u]

    def integers(self, high: int) -> int:
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
        self.env = ElectroLocVectorEnv(num_envs=N, n_particles=M, **kw)

    def state(self) -> dict[str, np.ndarray]:
        s = self.env._sim.state
        out = {k: np.array(getattr(s, k)) for k in STATE_KEYS}
        out.update(mean_mm=s.mean_mm.copy(), cov_mm2=s.cov_mm2.copy(), counts=s.counts.copy(), done=s.done.copy())
        return out

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

    def load(self, ref: dict[str, np.ndarray], cond: np.ndarray) -> None:
        s = dict(self.env.state)
        for k in (*STATE_KEYS, "mean_mm", "cov_mm2", "counts", "done"):
            s[k] = torch.as_tensor(np.ascontiguousarray(ref[k])).to(s[k].dtype)
        s["cond"] = torch.as_tensor(cond, dtype=torch.int64)
        self.env._state = s

    def state(self) -> dict[str, np.ndarray]:
        s = self.env.state
        return {k: s[k].numpy().copy() for k in (*STATE_KEYS, "mean_mm", "cov_mm2", "counts", "done")}

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

        monkeypatch.setattr(sim, "stream_key", stream_key)
        monkeypatch.setattr(sim, "normal_pair_indices", normal_pair_indices)
        monkeypatch.setattr(sim, "uniform53", uniform53)
        monkeypatch.setattr(sim, "uniform24", uniform24)
        monkeypatch.setattr(sim, "bits32", bits32)
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
]


def test_every_registered_engine_has_a_harness():
    assert set(backends_of(env_entry("ElectroLoc-v0"))) == set(HARNESSES)


def _one_step_of_both(engine: str, kw: dict[str, Any], monkeypatch: pytest.MonkeyPatch, ended: list[int]) -> tuple:
    """From the same state (the envs ``ended`` marked ended: this step resets them) and the same draws, one
    step of the reference and of ``engine``; returns both results, checked equal within the module's
    tolerances.
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
