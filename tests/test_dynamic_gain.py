"""Dynamic gain (paper §7): the amplifier gain in the action, its physics, min-var over moves × gains."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from vector_equivalence import assert_native_equals_sync

import electroloc_gym  # noqa: F401
from electroloc_gym.baselines import make_agent
from electroloc_gym.sensor_models import AnalyticSensorModel
from electroloc_gym.world.conditions import Amplifier, get_condition

LEVELS = (0.25, 1.0, 4.0)


@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
@pytest.mark.parametrize("observation", ["belief", "raw"])
def test_spaces_and_check_env(action_type: str, observation: str) -> None:
    env = gym.make(
        "ElectroLoc-v0", gain_levels=LEVELS, n_particles=200, action_type=action_type, observation=observation
    )
    if action_type == "continuous":
        assert env.action_space == gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
    else:
        assert env.action_space == gym.spaces.MultiDiscrete([9, 3])
    assert env.observation_space.shape == ((81,) if observation == "belief" else (4,))
    check_env(env.unwrapped, skip_render_check=True)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(
        gym.make(
            "ElectroLoc-v0", gain_levels=LEVELS, n_particles=200, action_type=action_type, observation=observation
        ),
        warn=True,
    )


def test_every_reading_has_the_chosen_gain() -> None:
    c = get_condition("fresh-steel-38.1")
    env = gym.make("ElectroLoc-v0", gain_levels=LEVELS, condition=c, n_particles=200, sensor_model="analytic")
    _, info = env.reset(seed=0)
    core = env.unwrapped
    assert info["gain"] == c.amplifier.gain and core.gain_index == 1  # reset reads at the preset gain
    for level in (0, 2, 1, 2):
        g = core.gain_action(level)
        _, _, _, _, info = env.step(np.array([0.3, -0.2, g], dtype=np.float32))
        assert core.gain_index == level and info["gain"] == c.amplifier.gain * LEVELS[level]
        # the observation's amplifier entries follow the reading's gain
        obs = env.unwrapped._sim.observation()[0]
        assert obs[78] == np.float32(np.log10(c.amplifier.gain * LEVELS[level]) / 4.0)
    # the gain coordinate is cut into three equal bins of [−1, 1]
    for g, level in ((-1.0, 0), (-0.34, 0), (-0.33, 1), (0.33, 1), (0.34, 2), (1.0, 2), (7.0, 2)):
        env.step(np.array([0.0, 0.0, g], dtype=np.float32))
        assert core.gain_index == level, g


def test_readings_scale_with_the_gain_and_saturate() -> None:
    """The true reading at gain f·G is f times the reading at G; its noise is f·G·σ_s; it clips at ±10 V."""
    c = get_condition("salt-delrin-12.7")
    env = gym.make("ElectroLoc-v0", gain_levels=(1.0, 64.0), condition=c, n_particles=100, sensor_model="analytic")
    env.reset(seed=1)
    core = env.unwrapped
    sim = core._sim
    ids = np.array([0])
    sim.task.set_gain(sim.state, ids, 0)
    low = sim.task.true_mean_V(sim.state, ids)[0]
    assert sim.state.noise_V[0] == c.noise_std_V
    sim.task.set_gain(sim.state, ids, 1)
    assert sim.task.true_mean_V(sim.state, ids)[0] == 64.0 * low
    assert sim.state.noise_V[0] == pytest.approx(64.0 * c.noise_std_V, rel=1e-12)
    # at 64 × G the noise alone (64·G·σ_s ≈ 44 V) drives most readings into the ±10 V clip
    readings = np.array([env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))[4]["reading_V"] for _ in range(8)])
    assert np.all(np.abs(readings) <= 10.0) and np.sum(np.abs(readings) == 10.0) >= 4


def test_information_per_reading_does_not_depend_on_the_gain_without_output_noise() -> None:
    """The mechanism behind the null result: with all noise referred to the electrodes (the paper's
    model) a reading at f·G is f times one at G with f times the noise, so every particle's likelihood
    is the same below saturation; an output noise that does not scale with G breaks the tie.
    """
    c = get_condition("fresh-steel-38.1")
    rng = np.random.default_rng(0)
    off = rng.uniform(-40, 40, (500, 2))
    true_off = np.array([[6.0, -9.0]])
    for out_mV, equal in ((0.0, True), (100.0, False)):
        amp = dataclasses.replace(c.amplifier, output_noise_mV=out_mV)
        base = c.replace(amplifier=amp)
        high = c.replace(amplifier=amp.with_gain(4.0 * amp.gain))
        m0, m1 = AnalyticSensorModel(base), AnalyticSensorModel(high)
        z = 0.3
        r0 = m0.mean_std(true_off)[0] + z * m0.noise_std_V
        r1 = m1.mean_std(true_off)[0] + z * m1.noise_std_V
        ll0 = m0.log_likelihood(r0, off)
        ll1 = m1.log_likelihood(r1, off)
        if equal:
            np.testing.assert_allclose(ll1, ll0, rtol=1e-9, atol=1e-9)
        else:
            assert np.ptp(ll1) > 1.5 * np.ptp(ll0)  # the high gain sharpens the likelihood


def test_output_noise_adds_in_quadrature_and_zero_changes_nothing() -> None:
    amp = Amplifier(gain=100.0, noise_rms_mV=0.5)
    assert amp.noise_std_V == 100.0 * 0.5 * 1e-3
    quiet = dataclasses.replace(amp, output_noise_mV=30.0)
    assert quiet.noise_std_V == pytest.approx(np.hypot(50.0, 30.0) * 1e-3)
    assert quiet.with_gain(200.0).noise_std_V == pytest.approx(np.hypot(100.0, 30.0) * 1e-3)
    with pytest.raises(ValueError, match="output_noise_mV"):
        Amplifier(gain=1.0, noise_rms_mV=1.0, output_noise_mV=-1.0)


def test_min_var_chooses_over_moves_and_gains() -> None:
    env = gym.make("ElectroLoc-v0", gain_levels=LEVELS, condition="salt-delrin-12.7", n_particles=500)
    obs, _ = env.reset(seed=3)
    agent = make_agent("min-var[n_voters=64]", seed=0)
    agent.reset(env.unwrapped)
    seen = set()
    for _ in range(6):
        action, _ = agent.predict(obs)
        assert action.shape == (3,) and len(agent.last_votes) == 3 * agent.n_options
        assert env.unwrapped.gain_action(agent.gain_level) == pytest.approx(float(action[2]))
        seen.add(agent.gain_level)
        obs, _, te, tr, _ = env.step(action)
        if te or tr:
            break
    preset = make_agent("min-var[gain=preset,n_voters=64]", seed=0)
    preset.reset(env.unwrapped)
    a, _ = preset.predict(obs)
    assert a[2] == pytest.approx(env.unwrapped.gain_action(1)) and len(preset.last_votes) == preset.n_options
    with pytest.raises(ValueError, match="gain must be"):
        make_agent("min-var[gain=auto]")


CASES = [
    pytest.param({"n_particles": 300, "gain_levels": LEVELS}, AutoresetMode.NEXT_STEP, id="calibrated"),
    pytest.param(
        {
            "n_particles": 200,
            "gain_levels": (1.0, 8.0),
            "sensor_model": "analytic",
            "condition": "random",
            "action_type": "discrete",
            "max_observations": 8,
        },
        AutoresetMode.SAME_STEP,
        id="analytic-discrete",
    ),
]


@pytest.mark.parametrize(("kwargs", "mode"), CASES)
def test_native_equals_sync_of_single_envs(kwargs: dict[str, Any], mode: AutoresetMode) -> None:
    assert_native_equals_sync("ElectroLoc-v0", kwargs, mode, ("reading_V", "gain"), seed=9, action_seed=4)


@pytest.mark.parametrize(
    ("env_id", "kwargs", "match"),
    [
        ("ElectroLoc-v0", {"gain_levels": (1.0, 1.0)}, "distinct"),
        ("ElectroLoc-v0", {"gain_levels": (0.0, 1.0)}, "gain_levels"),
        ("ElectroLoc-v0", {"gain_levels": 4.0}, "gain_levels"),
        ("ElectroLoc-v0", {"gain_levels": ()}, "gain_levels"),
        ("ElectroLocGlobal-v0", {"gain_levels": (1.0, 2.0)}, "unexpected argument"),
    ],
)
def test_bad_gain_levels(env_id: str, kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **kwargs)


def test_bad_actions() -> None:
    env = gym.make("ElectroLoc-v0", gain_levels=LEVELS, n_particles=100)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        env.step(np.zeros(2, dtype=np.float32))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.0, 0.0, np.nan], dtype=np.float32))
    env = gym.make("ElectroLoc-v0", gain_levels=LEVELS, n_particles=100, action_type="discrete")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="gain level in"):
        env.step(np.array([4, 3]))
    with pytest.raises(ValueError, match="level must be"):
        env.unwrapped.gain_action(3)


def test_reading_at_the_preset_gain_reproduces_the_env_without_dynamic_gain() -> None:
    """min-var[gain=preset] on the dynamic-gain env is min-var on ElectroLoc-v0, bit for bit: the same
    draws, the same calibration at the preset level, the same decisions.
    """
    kw = {"condition": "salt-delrin-38.1", "n_particles": 400}
    plain, dyn = gym.make("ElectroLoc-v0", **kw), gym.make("ElectroLoc-v0", gain_levels=LEVELS, **kw)
    a, b = make_agent("min-var[n_voters=32]", seed=5), make_agent("min-var[gain=preset,n_voters=32]", seed=5)
    o1, _ = plain.reset(seed=12)
    o2, _ = dyn.reset(seed=12)
    a.reset(plain.unwrapped)
    b.reset(dyn.unwrapped)
    assert np.array_equal(o1, o2)
    for _ in range(8):
        u, _ = a.predict(o1)
        v, _ = b.predict(o2)
        assert np.array_equal(u, v[:2])
        o1, _, t1, _, i1 = plain.step(u)
        o2, _, t2, _, i2 = dyn.step(v)
        assert np.array_equal(o1, o2) and i1["reading_V"] == i2["reading_V"] and t1 == t2
        if t1:
            break
