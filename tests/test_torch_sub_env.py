"""A torch sub-env through the single env's agent accessors: the predicted readings against the numba
core's sensor models (the same calibration table with a fixed ``calibration_seed``), the accessors'
shapes and units against the single env's, the view following the state, the paper's controllers
running on it, and every bad input.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv  # noqa: E402
from electroloc_gym.sensor_models import AnalyticSensorModel, CalibratedSensorModel  # noqa: E402
from electroloc_gym.sensor_models.calibrated import DEFAULT_CALIBRATION  # noqa: E402
from electroloc_gym.world.conditions import get_condition  # noqa: E402

torch.set_num_threads(1)


def _hypotheses(n: int, seed: int) -> np.ndarray:
    """(n, 2) float32 hypotheses over and beyond the box (some off the calibration grid), mm."""
    return np.random.default_rng(seed).uniform(-140.0, 140.0, (n, 2)).astype(np.float32)


def _carriages(view, moves: np.ndarray) -> np.ndarray:
    h = view.condition.allowed_half_width_mm
    return np.clip(view.position_mm + moves, -h, h).astype(np.float32)


@pytest.mark.parametrize("condition", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_calibrated_prediction_is_the_numba_sensor_model(condition):
    """With a fixed calibration seed the torch core holds the numba core's table: its predictions are the
    numba core's ``CalibratedSensorModel.mean_std`` at the moved carriage, to float32 rounding."""
    env = TorchElectroLocVectorEnv(num_envs=3, condition=condition, calibration_seed=5)
    env.reset(seed=4)
    model = CalibratedSensorModel(get_condition(condition), 5, DEFAULT_CALIBRATION)
    p = _hypotheses(2500, 1)
    moves = np.random.default_rng(2).uniform(-14.0, 14.0, (16, 2))  # beyond ±10 mm: clipped like step
    for i in range(3):
        view = env.sub_env(i)
        mean, std = view.predicted_reading_model(p, moves)
        carriage = _carriages(view, np.clip(moves, -10.0, 10.0))
        want_mean, want_std = model.mean_std(p[None] - carriage[:, None])
        assert mean.shape == std.shape == (16, 2500) and mean.dtype == std.dtype == np.float32
        np.testing.assert_allclose(mean, want_mean, rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(std, want_std, rtol=1e-5, atol=1e-7)
        assert np.all(std > 0)


def test_analytic_prediction_is_the_numba_sensor_model():
    env = TorchElectroLocVectorEnv(num_envs=2, sensor_model="analytic", condition="salt-steel-12.7")
    env.reset(seed=0)
    model = AnalyticSensorModel(get_condition("salt-steel-12.7"))
    p = _hypotheses(1000, 3)
    view = env.sub_env(1)
    move = np.array([3.0, -4.0])
    mean, std = view.predicted_reading_model(p, move)
    want_mean, want_std = model.mean_std(p - _carriages(view, move))
    assert mean.shape == (1000,)
    np.testing.assert_allclose(mean, want_mean, rtol=2e-5, atol=1e-7)
    np.testing.assert_allclose(std, want_std, rtol=1e-6)


def test_accessors_have_the_single_envs_shapes_and_follow_the_state():
    single = gym.make("ElectroLoc-v0").unwrapped
    single.reset(seed=0)
    env = TorchElectroLocVectorEnv(num_envs=2)
    env.reset(seed=0)
    view = env.sub_env(0)
    assert not hasattr(view, "unwrapped") and view.belief_frame == single.belief_frame == "target"
    assert view.belief.particles.shape == single.belief.particles.shape
    assert view.belief.particles.dtype == single.belief.particles.dtype == np.float32
    assert not view.belief.particles.flags.writeable
    np.testing.assert_array_equal(view.belief.weights, single.belief.weights)
    assert view.position_mm.shape == (2,) and view.position_mm.dtype == np.float64
    assert [b.tolist() for b in view.allowed_box_mm] == [b.tolist() for b in single.allowed_box_mm]
    p = single.belief.particles
    for moves in (np.zeros(2), np.zeros((5, 2))):
        got = [a.shape for a in view.predicted_reading_model(p, moves)]
        assert got == [a.shape for a in single.predicted_reading_model(p, moves)]
        assert view.predicted_particles_mm(p, moves).shape == single.predicted_particles_mm(p, moves).shape
    assert view.n_observations == 1
    before = view.belief.particles
    env.step(torch.tensor([[1.0, 0.0], [0.0, 1.0]]))
    assert view.n_observations == 2 and not np.array_equal(before, view.belief.particles)
    np.testing.assert_array_equal(view.position_mm, env.state["position_mm"][0].numpy())
    assert view.last_reading_V == float(env.state["reading_V"][0])


@pytest.mark.parametrize("name", ["min-var", "lookahead", "infotaxis"])
def test_planners_run_on_a_sub_env(name):
    """The planners read only the accessors: each binds to a view and returns actions in range."""
    env = TorchElectroLocVectorEnv(num_envs=2, n_particles=500)
    env.reset(seed=1)
    agents = [make_agent(name, seed=k) for k in range(2)]
    for k, agent in enumerate(agents):
        agent.reset(env.sub_env(k))
    for _ in range(2):
        actions = np.stack([agent.predict(None)[0] for agent in agents])
        assert actions.shape == (2, 2) and np.all(np.abs(actions) <= 1)
        env.step(torch.as_tensor(actions))
    if name == "min-var":
        assert agents[0].last_votes is not None and agents[0].last_votes.sum() == 256


def test_bad_inputs_are_one_clear_error():
    env = TorchElectroLocVectorEnv(num_envs=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.sub_env(0)
    env.reset(seed=0)
    for bad in (2, -1, 1.0, True):
        with pytest.raises(ValueError, match=r"index must be an integer in \[0, 1\]"):
            env.sub_env(bad)
    view = env.sub_env(0)
    p = view.belief.particles
    with pytest.raises(ValueError, match="gain_level must be None"):
        view.predicted_reading_model(p, np.zeros(2), gain_level=0)
    with pytest.raises(ValueError, match=r"particles_mm must have shape \(M, 2\)"):
        view.predicted_reading_model(p[:, :1], np.zeros(2))
    with pytest.raises(ValueError, match=r"moves_mm must have shape \(2,\) or \(C, 2\)"):
        view.predicted_particles_mm(p, np.zeros(3))
    with pytest.raises(ValueError, match="moves_mm must be finite"):
        view.predicted_reading_model(p, np.array([np.nan, 0.0]))
