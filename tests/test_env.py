"""ElectroLoc-v0: API conformance, determinism, robustness, bad inputs and a localisation sanity check."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import electroloc_gym
from electroloc_gym.envs import ElectroLocEnv
from electroloc_gym.world.conditions import Amplifier, Condition, Target, Water

# Warnings we accept from the checkers, and why:
# - gymnasium's check_env warns when an env's observation space bounds are not checked for infinite
#   values; ours are finite, so nothing is expected there. We treat every other warning as a failure.
ALLOWED_WARNINGS: tuple[str, ...] = ()


def _assert_no_unexpected_warnings(record: list[warnings.WarningMessage]) -> None:
    bad = [str(w.message) for w in record if not any(a in str(w.message) for a in ALLOWED_WARNINGS)]
    assert not bad, bad


@pytest.mark.parametrize("env_id", electroloc_gym.ENV_IDS)
@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_gymnasium_check_env(env_id: str, observation: str, sensor_model: str) -> None:
    if env_id == "ElectroLocUnknownTarget-v0" and sensor_model == "calibrated":
        sensor_model = "interpolated"  # its calibrated model: EEVs interpolated between calibrated sizes
    env = gym.make(env_id, observation=observation, sensor_model=sensor_model, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped, skip_render_check=True)
    _assert_no_unexpected_warnings(record)


@pytest.mark.parametrize("env_id", electroloc_gym.ENV_IDS)
@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_sb3_check_env(env_id: str, observation: str, action_type: str) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, observation=observation, action_type=action_type, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    _assert_no_unexpected_warnings(record)


def test_make_by_module_path() -> None:
    env = gym.make("electroloc_gym:ElectroLoc-v0", n_particles=100)
    obs, info = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape


def test_registration_is_idempotent() -> None:
    electroloc_gym._register_builtin()
    electroloc_gym._register_builtin()
    assert "ElectroLoc-v0" in gym.registry


def _rollout(seed: int, n: int = 40, **kwargs):
    env = gym.make("ElectroLoc-v0", **kwargs)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), 0.0, False, False, info)]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append((obs.copy(), r, term, trunc, info))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs.copy(), 0.0, False, False, info))
    return out


@pytest.mark.parametrize(
    "kwargs",
    [dict(), dict(condition="random", sensor_model="analytic"), dict(observation="raw", randomize_target=True)],
)
def test_seeded_rollouts_are_identical(kwargs) -> None:
    a = _rollout(7, **kwargs)
    b = _rollout(7, **kwargs)
    assert len(a) == len(b)
    for (oa, ra, ta, tra, ia), (ob, rb, tb, trb, ib) in zip(a, b):
        np.testing.assert_array_equal(oa, ob)
        assert (ra, ta, tra) == (rb, tb, trb)
        np.testing.assert_equal(ia, ib)


def test_different_seeds_differ() -> None:
    a = _rollout(1, n=5)
    b = _rollout(2, n=5)
    assert any(not np.array_equal(x[0], y[0]) for x, y in zip(a, b))


def test_info_contract_and_types() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=500)
    _, info = env.reset(seed=3)
    assert set(info) >= {
        "position_mm",
        "estimate_mm",
        "error_mm",
        "spread_mm",
        "reading_V",
        "n_observations",
        "success",
    }
    assert info["n_observations"] == 1
    assert isinstance(info["success"], bool) and isinstance(info["error_mm"], float)
    _, r, term, trunc, info = env.step(np.array([0.5, -1.0], dtype=np.float32))
    assert r == -1.0 and info["n_observations"] == 2
    assert isinstance(term, bool) and isinstance(trunc, bool)


def test_moves_are_limited_and_stay_in_box() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=200, max_observations=200, success_spread_mm=1e-6)
    env.reset(seed=0)
    u = env.unwrapped
    lo, hi = u.allowed_box_mm
    prev = u.position_mm
    for a in ([1, 1], [5, -3], [-1, 0.2]) * 20:
        env.step(np.asarray(a, dtype=np.float32))
        pos = u.position_mm
        assert np.all(np.abs(pos - prev) <= 10.0 + 1e-9)
        assert np.all(pos >= lo) and np.all(pos <= hi)
        prev = pos
    for _ in range(12):
        env.step(np.array([1.0, 1.0], dtype=np.float32))
    np.testing.assert_allclose(u.position_mm, hi)  # the move is truncated at the walls


def test_truncates_at_observation_cap() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=200, max_observations=5, success_spread_mm=1e-6)
    env.reset(seed=0)
    flags = [env.step(np.zeros(2, np.float32))[2:4] for _ in range(4)]
    assert flags[-1] == (False, True) and all(f == (False, False) for f in flags[:-1])


def test_discrete_actions() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=200, action_type="discrete")
    env.reset(seed=0)
    p0 = env.unwrapped.position_mm
    env.step(8)  # (+10, +10)
    assert np.allclose(env.unwrapped.position_mm - p0, 10.0)
    with pytest.raises(ValueError, match="action"):
        env.step(9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(condition="fresh-gold-12.7"), "condition"),
        (dict(n_particles=0), "n_particles"),
        (dict(n_particles=-5), "n_particles"),
        (dict(max_observations=0), "max_observations"),
        (dict(observation="pixels"), "observation"),
        (dict(sensor_model="magic"), "sensor_model"),
        (dict(success_spread_mm=-1.0), "success_spread_mm"),
        (dict(signal="loud"), "signal"),
        (dict(action_type="joystick"), "action_type"),
        (dict(render_mode="ascii"), "render_mode"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*render_mode='ascii'.*:UserWarning")  # gymnasium's own warning, before ours
def test_bad_kwargs_raise_clear_errors(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        gym.make("ElectroLoc-v0", **kwargs)


@pytest.mark.parametrize("action", [np.array([np.nan, 0.0]), np.array([0.0, np.inf]), np.zeros(3), np.zeros((2, 2))])
def test_bad_actions_raise(action) -> None:
    env = gym.make("ElectroLoc-v0", n_particles=100)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.unwrapped.step(action)


def test_accessors_are_read_only() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=100)
    env.reset(seed=0)
    u = env.unwrapped
    with pytest.raises(ValueError):
        u.belief.particles[0, 0] = 1.0
    pos = u.position_mm
    pos[0] = 999.0
    assert u.position_mm[0] != 999.0
    assert u.sensor_model.name == "calibrated"
    assert u.condition.name == "fresh-steel-12.7"


def test_random_condition_draws_presets() -> None:
    env = gym.make("ElectroLoc-v0", condition="random", n_particles=100, sensor_model="analytic")
    names = {env.metadata["info_names"]["condition_index"][env.reset(seed=s)[1]["condition_index"]] for s in range(40)}
    assert names == set(electroloc_gym.PRESET_NAMES)


def test_rgb_render_returns_frame() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=300, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0], np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 10  # not blank
    env.close()


_custom_conditions = st.builds(
    lambda r, cond_t, cond_w, gain, noise, half, start_frac, tx, ty, scale: Condition(
        name="custom",
        target=Target(radius_mm=r, conductivity_uScm=cond_t),
        water=Water(cond_w),
        amplifier=Amplifier(gain=gain, noise_rms_mV=noise),
        allowed_half_width_mm=half,
        start_half_width_mm=start_frac * half,
        target_xy_mm=(tx * half, ty * half),
        signal_scale=scale,
    ),
    st.floats(0.5, 40.0),
    st.sampled_from([0.0, 1e-9, 50.0, 1e4, 1e10]),
    st.floats(1.0, 1e5),
    st.floats(1.0, 1e4),
    st.floats(0.01, 5.0),
    st.floats(10.0, 150.0),
    st.floats(0.05, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(-1.0, 1.0),
    st.floats(0.01, 20.0),
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    cond=_custom_conditions,
    seed=st.integers(0, 2**16),
    actions=st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=1, max_size=12),
    sensor_model=st.sampled_from(["analytic", "calibrated"]),
)
def test_no_nan_anywhere_for_custom_conditions(cond, seed, actions, sensor_model) -> None:
    env = ElectroLocEnv(condition=cond, n_particles=200, sensor_model=sensor_model)
    obs, info = env.reset(seed=seed)
    for a in actions:
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        assert np.all(np.isfinite(env.belief.particles))
        assert all(np.all(np.isfinite(v)) for v in info.values() if not isinstance(v, str))
        obs, r, term, trunc, info = env.step(np.asarray(a, dtype=np.float32))
        assert np.isfinite(r)
        if term or trunc:
            break


def _lawnmower(half: float, step: float = 10.0) -> list[np.ndarray]:
    """Waypoints of a boustrophedon over ±half in x rows spaced 20 mm apart."""
    pts = []
    ys = np.arange(-half, half + 1e-9, 20.0)
    for k, y in enumerate(ys):
        xs = np.arange(-half, half + 1e-9, step)
        for x in xs if k % 2 == 0 else xs[::-1]:
            pts.append(np.array([x, y]))
    return pts


def test_fixed_lawnmower_path_localises_target() -> None:
    """Analytic model, fresh-steel-12.7 (fitted signal): a lawn-mower path localises (error < 5 mm) in most of 20
    seeds."""
    good = 0
    for seed in range(20):
        env = ElectroLocEnv(
            condition="fresh-steel-12.7", signal="fitted", sensor_model="analytic", max_observations=200
        )
        env.reset(seed=seed)
        info: dict = {}
        for wp in _lawnmower(40.0):
            # Drive to the next waypoint with moves of at most 10 mm per axis.
            while True:
                delta = wp - env.position_mm
                if np.all(np.abs(delta) < 1e-9):
                    break
                _, _, term, trunc, info = env.step((np.clip(delta, -10, 10) / 10.0).astype(np.float32))
                if term or trunc:
                    break
            if info.get("success") or trunc:
                break
        good += bool(info.get("success")) and info["error_mm"] < 5.0
    assert good >= 15, good


# ---- parameters: one declaration, one clear error ------------------------------------------------
@pytest.mark.parametrize(
    ("env_id", "kwargs", "match"),
    [
        ("ElectroLoc-v0", {"layout": "random"}, "layout"),
        ("ElectroLoc-v0", {"n_particle": 100}, "n_particle"),
        ("ElectroLocGlobal-v0", {"condition": "random"}, "condition"),
        ("ElectroLocGlobal-v0", {"randomize_target": True}, "randomize_target"),
        ("ElectroLoc-v0", {"randomize_target": "false"}, "randomize_target"),
        ("ElectroLoc-v0", {"randomize_target": 1}, "randomize_target"),
        ("ElectroLoc-v0", {"sensor_model": "pooled"}, "sensor_model"),
        ("ElectroLoc-v0", {"calibration": {"grid_pitch_mm": 4.0}}, "grid_pitch_mm"),
        ("ElectroLoc-v0", {"calibration": "fine"}, "calibration"),
        ("ElectroLoc-v0", {"calibration_seed": -1}, "calibration_seed"),
        ("ElectroLoc-v0", {"max_episode_steps": 0}, "max_episode_steps"),
        ("ElectroLoc-v0", {"n_particles": 10**9}, "n_particles"),
        ("ElectroLoc-v0", {"calibration": {"grid_step_mm": 1e-5}}, "grid_step_mm"),
        ("ElectroLocGlobal-v0", {"calibration": {"grid_step_mm": 1e-5}}, "grid_step_mm"),
    ],
)
@pytest.mark.parametrize("vector", [False, True])
def test_every_bad_argument_is_one_clear_error_in_single_and_vector_env(env_id, kwargs, match, vector) -> None:
    with pytest.raises(ValueError, match=match):
        if vector:
            gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
        else:
            env_cls = gym.spec(env_id).entry_point
            module, name = env_cls.split(":")
            getattr(__import__(module, fromlist=[name]), name)(**kwargs)


def test_sizes_that_cannot_fit_are_refused_at_construction_naming_the_limit() -> None:
    with pytest.raises(ValueError, match=r"GiB.*at most \d+ particles per env"):
        ElectroLocEnv(n_particles=10**9)
    with pytest.raises(ValueError, match="calibration grid.*GiB"):
        ElectroLocEnv(calibration={"grid_step_mm": 1e-5})


def test_numpy_scalars_are_accepted_where_numbers_are() -> None:
    env = ElectroLocEnv(
        n_particles=np.int64(100),
        success_spread_mm=np.float32(12.5),
        randomize_target=np.bool_(True),
        max_observations=np.int32(5),
        calibration={"grid_step_mm": np.float32(5.0)},
    )
    assert env.success_spread_mm == 12.5 and isinstance(env.success_spread_mm, float)
    assert env.randomize_target is True and env.n_particles == 100
    env.reset(seed=0)


def test_calibration_protocol_reaches_the_sensor_model() -> None:
    from electroloc_gym.sensor_models import DEFAULT_CALIBRATION

    env = ElectroLocEnv(n_particles=100, calibration={"grid_step_mm": 5.0, "samples_per_point": 4})
    env.reset(seed=0)
    model = env.sensor_model
    assert model.protocol.grid_step_mm == 5.0 and model.protocol.samples_per_point == 4
    assert ElectroLocEnv(n_particles=100).params.calibration is DEFAULT_CALIBRATION


def test_default_signal_is_get_conditions_default() -> None:
    from electroloc_gym.world.conditions import get_condition

    env = ElectroLocEnv(n_particles=100)
    env.reset(seed=0)
    assert env.condition == get_condition("fresh-steel-12.7")


@pytest.mark.parametrize("kwargs", [{"max_observations": 2, "success_spread_mm": 1e-6}, {"success_spread_mm": 1e3}])
def test_stepping_an_ended_episode_raises_call_reset(kwargs) -> None:
    """Truncation and termination alike: the next step is an error until reset."""
    env = ElectroLocEnv(n_particles=100, **kwargs)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
        done = terminated or truncated
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(2, np.float32))
    env.reset()
    env.step(np.zeros(2, np.float32))


def test_numpy_floats_in_a_custom_condition_are_stored_as_floats() -> None:
    target = Target(radius_mm=np.float32(6.35), conductivity_uScm=np.float64(1e10))
    assert isinstance(target.radius_mm, float) and target.radius_mm == float(np.float32(6.35))
    cond = Condition(
        name="np",
        target=target,
        water=Water(np.float32(160.0)),
        amplifier=Amplifier(gain=np.int64(191), noise_rms_mV=np.float32(0.25)),
        allowed_half_width_mm=np.float32(50.0),
        start_half_width_mm=np.float32(40.0),
    )
    values = (cond.allowed_half_width_mm, cond.amplifier.gain, cond.water.conductivity_uScm)
    assert all(isinstance(v, float) for v in values)
    env = ElectroLocEnv(condition=cond, n_particles=100)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="radius_mm"):
        Target(radius_mm=np.bool_(True), conductivity_uScm=1.0)
