"""The accelerator's reset schedule: the static gather of the resetting envs (``capacity``, with the all-env
path under ``torch.cond`` when more envs reset) gives the all-env path's bits — over crafted reset masks
(none, one, the padding row's env, exactly the capacity, one more, all), over reset-free, reset-heavy and
overflowing steps — and the step with it is captured by ``torch.compile(fullgraph=True)``; the compact
calibration grids read as the coefficient table reads.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from electroloc_gym.engines.torch_core import belief_update as F  # noqa: E402
from electroloc_gym.engines.torch_core import sim  # noqa: E402
from electroloc_gym.engines.torch_core.calibration import coefficients  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402

torch.set_num_threads(1)

N = 12


def _equal_states(a: sim.State, b: sim.State) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, name
        assert torch.equal(a[name], b[name]), name


def _env(**kw) -> TorchElectroLocVectorEnv:
    env = TorchElectroLocVectorEnv(num_envs=N, n_particles=200, **kw)
    env.reset(seed=5)
    return env


@pytest.mark.parametrize(
    "kw", [dict(condition="random", randomize_target=True), dict(calibration_seed=4), dict(sensor_model="analytic")]
)
@pytest.mark.parametrize("resetting", [[], [N - 1], [0, 3, N - 1], [1, 2, 3, 4], [0, 1, 2, 5, 9], list(range(N))])
def test_gathered_reset_draws_are_the_all_env_draws(kw, resetting):
    """capacity = 4: no reset, env N − 1 alone (the padding rows' env), fewer than 4 with env N − 1 among
    them, exactly 4, 5 (overflow: the all-env path) and all twelve — the state equals the all-env path's."""
    env = _env(**kw)
    mask = torch.zeros(N, dtype=torch.bool)
    mask[resetting] = True
    dense = sim.begin_episodes(env.consts, env.state, mask)
    static = sim.begin_episodes(env.consts, env.state, mask, capacity=4)
    _equal_states(dense, static)
    assert torch.equal(dense["episode"], env.state["episode"] + mask.to(torch.int64))
    if resetting and "calibration_seed" not in kw and "sensor_model" not in kw:
        # the draws did change the resetting envs' grids (a new calibration per episode)
        assert not torch.equal(dense["table"][resetting], env.state["table"][resetting])


@pytest.mark.parametrize("max_observations, capacity", [(35, None), (2, None), (2, 2)])
def test_gathered_steps_are_the_all_env_steps(max_observations, capacity):
    """Steps with the static gather against the all-env step, bit for bit: reset-free steps (cap 35, the
    first steps after ``reset``), reset-heavy steps (cap 2: half the envs reset at a step, within the
    capacity of :func:`sim.reset_capacity`) and a capacity forced to overflow (2)."""
    env = _env(condition="random", max_observations=max_observations)
    if max_observations == 2:
        env = _staggered(env)
    k = sim.reset_capacity(N) if capacity is None else capacity
    assert k < N
    dense = static = env.state
    rng = np.random.default_rng(0)
    counts = []
    for _ in range(6):
        a = torch.as_tensor(rng.uniform(-1, 1, (N, 2)).astype(np.float32))
        counts.append(int(dense["done"].sum()))
        dense, *out_d = sim.step(env.consts, dense, a)
        static, *out_s = sim.step(env.consts, static, a, capacity=k)
        _equal_states(dense, static)
        for x, y in zip(out_d, out_s, strict=True):
            assert torch.equal(x, y)
    if max_observations == 35:
        assert counts[:2] == [0, 0] and counts.count(0) >= 4  # mostly reset-free steps
    elif capacity is None:
        assert counts == [N // 2] * 6 and N // 2 <= k  # half the envs reset at every step, without overflow
    else:
        assert max(counts) > k and 0 not in counts  # every step resets more envs than the capacity: overflow


def test_reset_capacity_follows_its_rule():
    assert sim.reset_capacity(1) == 1 and sim.reset_capacity(2) == 2
    for n in (16, 1024, 65536, 262144):
        p = sim.RESET_RATE
        assert sim.reset_capacity(n) == math.ceil(n * p + 4 * math.sqrt(n * p * (1 - p)))
    assert sim.reset_capacity(1024) == 312 and sim.reset_capacity(262144) == 66423
    with pytest.raises(ValueError, match="capacity"):
        sim.begin_episodes(_env().consts, _env().state, torch.ones(N, dtype=torch.bool), capacity=0)


def _staggered(env: TorchElectroLocVectorEnv) -> TorchElectroLocVectorEnv:
    """At a cap of 2 readings every episode ends at its first move; half the envs restarted one step later
    reset at alternate steps: N / 2 resets at every step."""
    env.step(torch.zeros(N, 2))
    env.reset(options={"reset_mask": torch.arange(N) < N // 2})
    return env


def test_step_with_the_static_gather_compiles_as_one_graph():
    """``torch.compile(fullgraph=True)`` captures the step with the gather and its ``torch.cond`` (one
    graph: a break would raise); through ``aot_eager`` (the functionalised graph inductor would take) it gives the
    eager all-env step's bits, on steps within the capacity (N / 2 resets, K = 7) and beyond it (N)."""
    envs = [_env(condition="random", max_observations=2), _staggered(_env(condition="random", max_observations=2))]
    c = envs[0].consts
    step = lambda s, a: sim.step(c, s, a, capacity=7)  # noqa: E731
    compiled = torch.compile(step, fullgraph=True, backend="aot_eager")  # fullgraph: a graph break raises
    counts = []
    for env in envs:
        eager = comp = env.state
        for t in range(4):
            a = torch.full((N, 2), 0.3 * (t % 3 - 1))
            counts.append(int(eager["done"].sum()))
            eager, *out_e = sim.step(c, eager, a)
            comp, *out_c = compiled(comp, a)
            _equal_states(eager, comp)
            for x, y in zip(out_e, out_c, strict=True):
                assert torch.equal(x, y)
    assert N in counts and N // 2 in counts  # overflow, and gathered resets


def test_compact_grids_read_as_the_coefficient_table():
    """The per-env grids (mean and std, float64) looked up with the coefficients formed on the fly give
    the coefficient table's mean and std bit for bit, inside the grid, on its edges and off it."""
    env = _env(condition="random")
    c, s = env.consts, env.state
    k = s["cond"]
    n = c.grid_n
    grids = s["table"].reshape(N, 2, n, n)
    table = coefficients(grids[:, 0], grids[:, 1], c.noise_V[k])
    gen = torch.Generator().manual_seed(0)
    h = (c.half_mm[k] * 2.2).to(torch.float32)[:, None]
    x = (torch.rand(N, 500, generator=gen) * 2 - 1) * h
    y = (torch.rand(N, 500, generator=gen) * 2 - 1) * h
    lo = c.grid_lo_mm[k]
    x[:, :20] = lo[:, None]  # the grid's first line and its last (edges of the bilinear cells)
    x[:, 20:40] = -lo[:, None]
    args = (x, y, lo, c.grid_inv_mm[k], c.grid_points[k] - 1)
    want = F.calibrated_mean_std(*args, n - 1, table)
    got = F.grid_mean_std(*args, n, s["table"], c.noise_V[k])
    inside = (x.abs() <= -lo[:, None]) & (y.abs() <= -lo[:, None])
    assert 0 < int(inside.sum()) < inside.numel()
    for a, b in zip(want, got, strict=True):
        assert torch.equal(a, b)
    assert sim.state_bytes_per_env(c) == env.memory_bytes_per_env()
