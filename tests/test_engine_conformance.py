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

Not covered here: a step in which an env resets (the reset draws — condition, target, start, particles,
calibration — are not injected), and per-episode calibrations (the engines keep different tables: the
numba engine the coefficients, the torch engine the grids); a fixed ``calibration_seed``'s table is the
same in both (tests/test_torch_backend.py) and is used for the calibrated cases.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.conditions import PRESET_NAMES  # noqa: E402
from electroloc_gym.core import step as numba_step  # noqa: E402
from electroloc_gym.draws import normal_table, table_normal_indices  # noqa: E402
from electroloc_gym.envs.sim_backends import backends_of  # noqa: E402
from electroloc_gym.envs.vector import ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.registry import env_entry  # noqa: E402
from electroloc_gym.torch_core import sim  # noqa: E402
from electroloc_gym.torch_core.rng import STREAMS  # noqa: E402
from electroloc_gym.torch_core.vector_env import TorchElectroLocVectorEnv  # noqa: E402

torch.set_num_threads(1)
N, M = 6, 400
TABLE = normal_table()
#: What the step hands out and the state keeps that every engine must agree on (module docstring).
STATE_KEYS = ("position_mm", "target_mm", "particles_mm", "reading_V", "n_observations", "elapsed")


class _Draws:
    """One env's injected draws, as the numba engine's generator would hand them out."""

    def __init__(self, noise_idx: int, u0: float, jitter: np.ndarray) -> None:
        self.noise_idx, self.u0, self.jitter = noise_idx, u0, jitter

    def normal(self, loc: float, scale: float, size: Any = None) -> float:
        assert size is None and loc == 0.0
        return float(np.float64(TABLE[self.noise_idx]) * scale)

    def random(self) -> float:
        return self.u0


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

        def stream_key(k0, k1, ep, t, stream):  # the stream's id stands for its key
            return torch.full_like(k0, int(stream))

        def normal_pair_indices(key, count):
            if int(key[0]) == STREAMS["noise"]:
                return noise, noise
            assert int(key[0]) == STREAMS["jitter"] and count == M
            return jit[:, 0::2], jit[:, 1::2]

        def uniform53(key, count):
            assert int(key[0]) == STREAMS["resample"] and count == 1
            return u0

        monkeypatch.setattr(sim, "stream_key", stream_key)
        monkeypatch.setattr(sim, "normal_pair_indices", normal_pair_indices)
        monkeypatch.setattr(sim, "uniform53", uniform53)
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


@pytest.mark.parametrize("engine", OTHERS)
@pytest.mark.parametrize("kw", GRID, ids=[f"{i}" for i in range(len(GRID))])
def test_one_step_from_the_same_state_and_draws_is_the_same(engine, kw, monkeypatch):
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
    other = HARNESSES[engine](kw)
    pool = list(PRESET_NAMES) if kw["condition"] == "random" else [kw["condition"]]
    other.load(start, np.array([pool.index(c.name) for c in ref.env.conditions]))  # the engine's pool index
    a = actions()
    draws = [_Draws(int(rng.integers(0, 2**16)), rng.random(), table_normal_indices(rng, 2 * M)) for _ in range(N)]
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
