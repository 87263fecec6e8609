"""The CPU's step schedule and the compiled capture: the gathered resets against the one-graph step (bit for
bit), the vector env's compiled wiring against its eager step, and ``torch.compile(fullgraph=True)`` of
the one-graph step and of the CPU's compiled unit (``backend="eager"``: the capture, without code
generation).
"""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from electroloc_gym.engines.torch_core import sim  # noqa: E402
from electroloc_gym.envs.torch_vector import OWN_IN_PLACE, TorchElectroLocVectorEnv  # noqa: E402

torch.set_num_threads(1)


@pytest.mark.parametrize("kw", [dict(condition="random", randomize_target=True), dict(sensor_model="analytic")])
def test_gathered_resets_give_the_dense_step_bit_for_bit(kw):
    """The CPU's eager step (reset draws for the resetting envs only) against the one-graph step (every env's
    draws, kept where an env resets): the same state, bit for bit, over steps where some envs reset."""
    env = TorchElectroLocVectorEnv(num_envs=6, n_particles=300, max_observations=4, **kw)
    assert env.gather_resets  # on the CPU
    env.reset(seed=11)
    dense = gathered = env.state
    rng = np.random.default_rng(2)
    resets = 0
    for _ in range(12):
        a = torch.as_tensor(rng.uniform(-1, 1, (6, 2)).astype(np.float32))
        resets += int(dense["done"].sum())
        dense, *out_d = sim.step(env.consts, dense, a, gather=False)
        gathered, *out_g = sim.step(env.consts, gathered, a, gather=True)
        assert dense.keys() == gathered.keys()
        for name in dense:
            assert torch.equal(dense[name], gathered[name]), name
        for x, y in zip(out_d, out_g, strict=True):
            assert torch.equal(x, y)
    assert resets >= 6  # the cap of 4 readings ends every episode: the reset path ran, more than once


def test_compiled_cpu_step_is_the_eager_step_when_the_backend_is_eager():
    """compile=True on the CPU: the gathered resets, then the captured :func:`sim.advance`. With dynamo's
    ``eager`` backend the captured graph runs the same operations, so the states agree bit for bit."""
    kw = dict(num_envs=5, n_particles=200, max_observations=3, condition="random")
    compiled = TorchElectroLocVectorEnv(compile=True, compile_backend="eager", **kw)
    eager = TorchElectroLocVectorEnv(**kw)
    for env in (compiled, eager):
        env.reset(seed=8)
    rng = np.random.default_rng(0)
    for _ in range(8):
        a = torch.as_tensor(rng.uniform(-1, 1, (5, 2)).astype(np.float32))
        for x, y in zip(compiled.step(a)[:4], eager.step(a)[:4], strict=True):
            assert torch.equal(x, y)
        for name in eager.state:
            assert torch.equal(compiled.state[name], eager.state[name]), name
    assert int(eager.state["episode"].min()) >= 1  # the cap of 3 readings: every sub-env reset on the way


def test_a_cpu_step_leaves_what_it_returned_unchanged():
    """The CPU step updates only the calibration tables in place: the observations, infos and state tensors
    of earlier steps (the particles, the means, …), which a user may keep, are not written to by later
    steps and resets."""
    env = TorchElectroLocVectorEnv(num_envs=4, n_particles=200, max_observations=2)
    obs, info = env.reset(seed=3)
    kept = []
    for _ in range(6):
        state = {k: v for k, v in env.state.items() if k != "table"}
        kept.append(
            ([obs, *info.values(), *state.values()], [t.clone() for t in [obs, *info.values(), *state.values()]])
        )
        obs, _, _, _, info = env.step(torch.zeros(4, 2))
    assert OWN_IN_PLACE == ("table",)
    assert int(env.state["episode"].min()) >= 2  # every sub-env reset on the way
    for live, snapshot in kept:
        for x, y in zip(live, snapshot, strict=True):
            assert torch.equal(x, y)


def test_step_compiles_without_graph_break():
    env = TorchElectroLocVectorEnv(
        num_envs=2, n_particles=64, compile=True, compile_backend="eager", condition="random"
    )
    env.reset(seed=0)
    for _ in range(3):
        env.step(torch.zeros(2, 2))
    explain = torch._dynamo.explain(lambda s, a: sim.step(env.consts, s, a))(env.state, torch.zeros(2, 2))
    assert explain.graph_break_count == 0 and explain.graph_count == 1
    # the CPU's compiled unit: the step after the (eagerly gathered) resets
    reset = env.state["done"]
    advance = torch._dynamo.explain(lambda s, a, r: sim.advance(env.consts, s, a, r))
    explain = advance(env.state, torch.zeros(2, 2), reset)
    assert explain.graph_break_count == 0 and explain.graph_count == 1
