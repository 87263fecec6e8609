"""The rules both engines share, written once in the contract: the move and the walls
(``contract/motion.py``), the belief observation's scalars and the info's error and spread
(``contract/belief_summary.py``): numpy and torch give the same values, the numba engine's compiled
assembly follows the declaration, and each engine's results are the shared function's.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401 - registers the ids
from electroloc_gym.contract.belief_summary import (
    BELIEF_SCALARS,
    CORRELATION_FLOOR_MM2,
    LOG_SPREAD_FLOOR_MM,
    N_SCALARS,
    BeliefScalar,
    belief_info_values,
    belief_quantities,
    belief_scalar_values,
    belief_scalars,
)
from electroloc_gym.contract.motion import carriage_after_move_mm, commanded_moves_mm
from electroloc_gym.contract.observation import belief_observation, condition_descriptor
from electroloc_gym.contract.params import DISCRETE_MOVES_MM, EnvParams
from electroloc_gym.envs.actions import ActionParser
from electroloc_gym.kernels import belief_observation_rows
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition


def _statistics(k: int, seed: int) -> dict:
    """Random statistics of k envs, with the corner cases: a collapsed cloud (zero covariance, the floors),
    readings beyond saturation, a carriage at a wall.
    """
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 10, (k, 2, 2))
    cov = a @ a.transpose(0, 2, 1)
    cov[0] = 0.0
    cov[1] = [[1e-14, 0.0], [0.0, 1e-14]]
    reading = rng.normal(0, 4, k)
    reading[2] = 25.0
    carriage = rng.uniform(-60, 60, (k, 2))
    carriage[3] = [50.0, -50.0]
    return {
        "carriage_mm": carriage,
        "reading_V": reading,
        "mean_mm": rng.uniform(-60, 60, (k, 2)),
        "cov_mm2": cov,
        "n_observations": rng.integers(1, 40, k).astype(np.float64),
        "max_observations": 35,
        "half_width_mm": np.full(k, 50.0),
        "noise_std_V": rng.uniform(0.005, 0.5, k),
        "saturation_V": np.full(k, 10.0),
        "success_spread_mm": 10.0,
    }


def _kernel_scalars(st: dict, factors: np.ndarray) -> np.ndarray:
    """The compiled kernel's scalar entries with the given factors."""
    k = len(st["reading_V"])
    out = np.empty((k, N_SCALARS + 64 + 5), dtype=np.float32)
    belief_observation_rows(
        st["carriage_mm"],
        st["reading_V"],
        st["mean_mm"],
        st["cov_mm2"],
        st["n_observations"],
        float(st["max_observations"]),
        st["half_width_mm"],
        st["noise_std_V"],
        st["saturation_V"],
        st["success_spread_mm"],
        np.zeros((k, 64)),
        np.zeros((k, 5), dtype=np.float32),
        factors,
        LOG_SPREAD_FLOOR_MM,
        CORRELATION_FLOOR_MM2,
        out,
    )
    return out[:, :N_SCALARS]


def _declared(entries: tuple[BeliefScalar, ...], st: dict) -> np.ndarray:
    q = belief_quantities(np, st["carriage_mm"], st["reading_V"], st["mean_mm"], st["cov_mm2"], st["n_observations"])
    scales = {
        name: st[name]
        for name in ("half_width_mm", "saturation_V", "noise_std_V", "success_spread_mm", "max_observations")
    }
    return belief_scalar_values(np, q, scales, entries).astype(np.float32)


def test_the_compiled_assembly_follows_the_declaration() -> None:
    st = _statistics(64, 0)
    want = _declared(BELIEF_SCALARS, st)
    np.testing.assert_array_max_ulp(_kernel_scalars(st, np.array([e.factor for e in BELIEF_SCALARS])), want, 1)
    # the kernel's numbers are the declaration's: other factors, the same agreement
    other = tuple(dataclasses.replace(e, factor=e.factor * 1.5) if e.scale else e for e in BELIEF_SCALARS)
    got = _kernel_scalars(st, np.array([e.factor for e in other]))
    np.testing.assert_array_max_ulp(got, _declared(other, st), 1)
    assert not np.array_equal(got, want)


def test_the_observation_scalars_are_the_declaration_in_both_engines() -> None:
    torch = pytest.importorskip("torch")
    from electroloc_gym.engines.torch_core import belief_update  # noqa: PLC0415 - torch is optional

    st = _statistics(16, 1)
    k = 16
    hist = np.full((k, 64), 1 / 64)
    desc = np.stack([condition_descriptor(get_condition(PRESET_NAMES[i % 8])) for i in range(k)])
    args = [st[n] for n in ("carriage_mm", "reading_V", "mean_mm", "cov_mm2")]
    rest = [st[n] for n in ("half_width_mm", "noise_std_V", "saturation_V")]
    numba_obs = belief_observation(*args, hist, st["n_observations"], 35, *rest, 10.0, desc)
    t = torch.tensor
    torch_obs = belief_update.belief_observation(
        *map(t, args), t(hist), t(st["n_observations"].astype(np.int64)), 35, *map(t, rest), 10.0, t(desc)
    ).numpy()
    want = belief_scalars(np, *args, st["n_observations"], 35, *rest, 10.0).astype(np.float32)
    np.testing.assert_array_max_ulp(numba_obs[:, :N_SCALARS], want, 1)
    np.testing.assert_array_max_ulp(torch_obs[:, :N_SCALARS], want, 1)
    assert want.shape == (k, N_SCALARS) and np.all(np.abs(want) <= 1.0)


def test_a_bad_declaration_is_one_value_error() -> None:
    with pytest.raises(ValueError, match="transform"):
        BeliefScalar("x", "spread_mm", "half_width_mm", transform="exp")
    with pytest.raises(ValueError, match="scale"):
        BeliefScalar("x", "spread_mm", "width")
    with pytest.raises(ValueError, match="factor"):
        BeliefScalar("x", "correlation", None, factor=2.0)


def test_moves_and_walls_are_the_same_in_numpy_and_torch() -> None:
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(2)
    a = rng.uniform(-2, 2, (50, 2))
    idx = rng.integers(0, 9, 50)
    pos = rng.uniform(-55, 55, (50, 2))
    half = rng.uniform(40, 60, 50)[:, None]
    for actions, discrete, table in ((a, False, None), (idx, True, torch.tensor(DISCRETE_MOVES_MM))):
        moves = commanded_moves_mm(np, actions, discrete)
        tmoves = commanded_moves_mm(torch, torch.tensor(actions), discrete, table)
        np.testing.assert_array_equal(tmoves.numpy(), moves)
        after = carriage_after_move_mm(np, pos, moves, half)
        tafter = carriage_after_move_mm(torch, torch.tensor(pos), tmoves, torch.tensor(half))
        np.testing.assert_array_equal(tafter.numpy(), after)
        assert np.all(np.abs(after) <= half) and np.all(np.abs(moves) <= 10.0)
    np.testing.assert_array_equal(commanded_moves_mm(np, a, False), np.clip(a, -1, 1) * 10.0)
    np.testing.assert_array_equal(commanded_moves_mm(np, idx, True), DISCRETE_MOVES_MM[idx])


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_the_numba_engine_moves_by_the_shared_rule(action_type: str) -> None:
    kw = {"n_particles": 100, "action_type": action_type}
    env = gym.make_vec("ElectroLoc-v0", num_envs=4, vectorization_mode="vector_entry_point", **kw)
    env.reset(seed=[1, 2, 3, 4])
    sim = env.unwrapped._sim
    parser = ActionParser(EnvParams.from_kwargs("localize", {"action_type": action_type}, "ElectroLoc-v0"), 4)
    rng = np.random.default_rng(3)
    for _ in range(8):
        act = rng.integers(0, 9, 4) if action_type == "discrete" else rng.uniform(-1.5, 1.5, (4, 2))
        before, half, moving = sim.state.position_mm.copy(), sim.state.half_mm.copy(), ~sim.state.done
        env.step(act)
        moves = commanded_moves_mm(np, act, action_type == "discrete")
        np.testing.assert_array_equal(parser(act)[0], moves)
        want = carriage_after_move_mm(np, before, moves, half[:, None])
        np.testing.assert_array_equal(sim.state.position_mm[moving], want[moving])


def test_the_info_error_and_spread_are_the_shared_function() -> None:
    env = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", n_particles=100)
    env.reset(seed=[4, 5, 6])
    _, _, _, _, info = env.step(np.zeros((3, 2), dtype=np.float32))
    s = env.unwrapped._sim.state
    error, spread, success = belief_info_values(np, s.mean_mm, s.cov_mm2, s.target_mm, 10.0)
    np.testing.assert_array_equal(info["error_mm"], error)
    np.testing.assert_array_equal(info["spread_mm"], spread)
    np.testing.assert_array_equal(info["success"], success)
    torch = pytest.importorskip("torch")
    t = torch.tensor
    te, ts, tsu = belief_info_values(torch, t(s.mean_mm), t(s.cov_mm2), t(s.target_mm), 10.0)
    np.testing.assert_array_equal(te.numpy(), error)
    np.testing.assert_array_equal(ts.numpy(), spread)
    np.testing.assert_array_equal(tsu.numpy(), success)
