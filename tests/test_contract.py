"""The env contract (docs/environments.md, "Arguments and their ranges"): every observation of every env in
its space for every valid argument; every argument's range checked at construction, so that nothing valid
there fails later; every bad argument, action or seed one ValueError naming it; a refused call changes nothing.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import electroloc_gym  # noqa: F401
from electroloc_gym.contract.params import GAIN_FACTOR_LIMITS, MIN_OBSERVATION_CAP, SIGNAL_LIMITS
from electroloc_gym.engines.numba_core.global_task import MAX_POSITION_BLUR_MM
from electroloc_gym.engines.numba_core.track_task import (
    MAX_TARGET_SPEED_MM,
    MOTION_MODELS,
    MOTION_OPTION_SCOPES,
    TARGET_MOTIONS,
)
from electroloc_gym.engines.numba_core.unknown import RADIUS_LIMITS_MM
from electroloc_gym.envs.vector import sub_env_seeds
from electroloc_gym.world.conditions import PRESET_NAMES

ENV_IDS = ("ElectroLoc-v0", "ElectroLocGlobal-v0", "ElectroLocUnknownTarget-v0", "ElectroLocTrack-v0")


def _make(env_id: str, vector: bool, **kwargs: Any) -> Any:
    if vector:
        return gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    return gym.make(env_id, **kwargs)


def _rollout_in_space(env: Any, seed: int, steps: int, rng: np.random.Generator) -> None:
    """Reset and step with random and extreme actions; every observation in the observation space, every
    reward and the info's numbers finite.
    """
    obs, info = env.reset(seed=seed)
    assert env.observation_space.contains(obs), obs
    space = env.action_space
    for t in range(steps):
        action = space.sample()
        if space.dtype.kind == "f" and t % 3 == 2:  # finite values far outside [−1, 1] are clipped
            action = (np.sign(action) * 1e6).astype(space.dtype)
        obs, reward, terminated, truncated, info = env.step(action)
        assert env.observation_space.contains(obs), (t, obs)
        assert np.all(np.isfinite(reward))
        for key in ("estimate_mm", "spread_mm", "reading_V", "error_mm"):
            assert np.all(np.isfinite(np.asarray(info[key], dtype=float))), key
        if np.ndim(terminated) == 0 and (terminated or truncated):
            obs, info = env.reset(seed=seed + t + 1)
            assert env.observation_space.contains(obs)
    space.seed(int(rng.integers(2**31)))


_factors = st.floats(GAIN_FACTOR_LIMITS[0], GAIN_FACTOR_LIMITS[1])
_radii = st.floats(RADIUS_LIMITS_MM[0], RADIUS_LIMITS_MM[1])
_common = {
    "observation": st.sampled_from(["belief", "raw"]),
    "action_type": st.sampled_from(["continuous", "discrete"]),
    "max_observations": st.integers(MIN_OBSERVATION_CAP, 12),
    "success_spread_mm": st.floats(0.5, 1e3),
}
_target = {
    "condition": st.sampled_from(("random",) + PRESET_NAMES),
    "signal": st.one_of(st.sampled_from(["fitted", "paper", "coverage"]), st.floats(*SIGNAL_LIMITS)),
    "randomize_target": st.booleans(),
    "gain_levels": st.one_of(st.none(), st.lists(_factors, min_size=1, max_size=3, unique=True).map(tuple)),
}
ARGUMENTS = {
    "ElectroLoc-v0": st.fixed_dictionaries({**_common, **_target, "distractors": st.sampled_from([0, 1, 2, [0, 2]])}),
    "ElectroLocGlobal-v0": st.fixed_dictionaries(
        {
            **_common,
            "layout": st.sampled_from(["benchmark", "random"]),
            "position_blur_mm": st.floats(0.0, MAX_POSITION_BLUR_MM),
        }
    ),
    "ElectroLocUnknownTarget-v0": st.fixed_dictionaries(
        {
            **_common,
            **_target,
            "target_draw": st.sampled_from(["prior", "condition"]),
            "contrast": st.sampled_from(["binary", "continuous"]),
            "radius_range_mm": st.lists(_radii, min_size=2, max_size=2, unique=True).map(lambda r: tuple(sorted(r))),
        }
    ),
    "ElectroLocTrack-v0": st.fixed_dictionaries(
        {
            **_common,
            **{k: v for k, v in _target.items() if k != "gain_levels"},
            "target_motion": st.sampled_from(TARGET_MOTIONS),
            "target_speed_mm": st.floats(0.0, MAX_TARGET_SPEED_MM),
            "turn_std_rad": st.floats(0.0, math.pi),
            "motion_model": st.sampled_from(MOTION_MODELS),
            "motion_step_mm": st.one_of(st.none(), st.floats(0.0, MAX_TARGET_SPEED_MM)),
        }
    ).map(lambda kw: _within_scopes(kw)),
}


def _within_scopes(kwargs: dict[str, Any]) -> dict[str, Any]:
    """``kwargs`` without the options that do nothing under another's value (refused: MOTION_OPTION_SCOPES)."""
    return {
        k: v
        for k, v in kwargs.items()
        if not any(k == name and kwargs[mode] != acts for name, mode, acts, _ in MOTION_OPTION_SCOPES)
    }


@pytest.mark.parametrize("env_id", ENV_IDS)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), seed=st.integers(0, 2**20), vector=st.booleans())
def test_every_observation_is_in_its_space_for_valid_arguments(env_id: str, data: Any, seed: int, vector: bool) -> None:
    kwargs = data.draw(ARGUMENTS[env_id])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium's checker on float spaces of extreme actions
        env = _make(env_id, vector, n_particles=40, sensor_model="analytic", **kwargs)
        _rollout_in_space(env, seed, 6, np.random.default_rng(seed))


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("ElectroLoc-v0", {"gain_levels": GAIN_FACTOR_LIMITS}),
        ("ElectroLoc-v0", {"gain_levels": GAIN_FACTOR_LIMITS, "sensor_model": "analytic"}),
        ("ElectroLoc-v0", {"signal": SIGNAL_LIMITS[1], "condition": "salt-steel-12.7"}),
        ("ElectroLocGlobal-v0", {"position_blur_mm": MAX_POSITION_BLUR_MM}),
        ("ElectroLocTrack-v0", {"target_speed_mm": MAX_TARGET_SPEED_MM, "turn_std_rad": math.pi}),
        ("ElectroLocTrack-v0", {"target_motion": "random_walk", "motion_step_mm": MAX_TARGET_SPEED_MM}),
        ("ElectroLocUnknownTarget-v0", {"radius_range_mm": RADIUS_LIMITS_MM, "gain_levels": GAIN_FACTOR_LIMITS}),
        (
            "ElectroLocUnknownTarget-v0",
            {"sensor_model": "interpolated", "eev_radii_mm": RADIUS_LIMITS_MM, "radius_range_mm": RADIUS_LIMITS_MM},
        ),
    ],
)
def test_the_ends_of_the_ranges_run_with_every_sensor_model(env_id: str, kwargs: dict) -> None:
    env = gym.make(env_id, n_particles=100, calibration_seed=3, **kwargs)
    _rollout_in_space(env, 0, 5, np.random.default_rng(0))


def test_unknown_target_radius_entry_stays_in_the_box_for_big_spheres() -> None:
    """The reproducer: radius_range_mm=(5, 50) put entry 76 (radius / 25 mm) at 1.2066."""
    env = gym.make("ElectroLocUnknownTarget-v0", radius_range_mm=(5, 50))
    obs = env.reset(seed=0)[0]
    assert obs[76] == 1.0 and env.observation_space.contains(obs)


@pytest.mark.parametrize("vector", [False, True])
@pytest.mark.parametrize(
    "env_id, kwargs, match",
    [
        ("ElectroLoc-v0", {"gain_levels": (1e-60,)}, r"gain_levels must be a finite number ≥ 0.001 and ≤ 1000"),
        ("ElectroLoc-v0", {"gain_levels": (1e-60, 1.0)}, r"gain_levels must be a finite number ≥ 0.001"),
        ("ElectroLoc-v0", {"gain_levels": (1e40,), "sensor_model": "analytic"}, r"gain_levels .* ≤ 1000, got 1e\+40"),
        ("ElectroLocGlobal-v0", {"position_blur_mm": 1e40}, r"position_blur_mm must be a finite number ≥ 0 and ≤ 100"),
        (
            "ElectroLocUnknownTarget-v0",
            {"eev_radii_mm": (1e-20, 20), "sensor_model": "interpolated"},
            r"eev_radii_mm must be a finite number ≥ 1 and ≤ 50, got 1e-20",
        ),
        ("ElectroLocUnknownTarget-v0", {"radius_range_mm": (5, 1e20)}, r"radius_range_mm .* ≤ 50, got 1e\+20"),
        ("ElectroLoc-v0", {"signal": 1e40}, r"signal must be a finite number ≥ 0.001 and ≤ 1000"),
        ("ElectroLoc-v0", {"gain_levels": np.array(2.0)}, r"gain_levels must be a tuple of one or more numbers"),
        ("ElectroLocUnknownTarget-v0", {"radius_range_mm": np.array(2.0)}, r"radius_range_mm must be a tuple of 2"),
        ("ElectroLocUnknownTarget-v0", {"eev_radii_mm": np.array(2.0)}, r"eev_radii_mm must be a tuple of one or more"),
        (
            "ElectroLoc-v0",
            {"condition": {}},
            r"condition \(a dict of Condition fields\) is invalid: missing Condition "
            r"field\(s\) \['allowed_half_width_mm', 'amplifier', 'name'",
        ),
        ("ElectroLoc-v0", {"condition": {"target": 5}}, r"condition \(a dict of Condition fields\) is invalid"),
    ],
)
def test_values_that_used_to_fail_later_are_refused_at_construction(
    env_id: str, kwargs: dict, match: str, vector: bool
) -> None:
    with pytest.raises(ValueError, match=match):
        _make(env_id, vector, **kwargs)


@pytest.mark.parametrize(
    "action",
    [
        "abc",
        {"dx": 1},
        np.array(["0.1", "0.2"]),
        np.array([1 + 1j, 0]),
        [0.1, "x"],
        [[0.1], [0.2, 0.3]],
        True,
        None,
        object(),
    ],
)
@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_bad_actions_are_one_value_error(action: Any, action_type: str) -> None:
    env = gym.make("ElectroLoc-v0", sensor_model="analytic", n_particles=50, action_type=action_type)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions? must be"):
        env.unwrapped.step(action)
    vec = _make("ElectroLoc-v0", True, sensor_model="analytic", n_particles=50, action_type=action_type)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions? must be"):
        vec.step([action, action])
    assert env.unwrapped.n_observations == 1  # nothing was stepped


@pytest.mark.parametrize(
    "seed", [1.5, True, "123", b"1", [0, -1, 2], [0, 1], [0, 1.0, 2], np.array([[1, 2, 3]]), -1, {"a": 1}]
)
def test_a_refused_vector_reset_changes_nothing(seed: Any) -> None:
    kw = {"sensor_model": "analytic", "n_particles": 60}
    vec = _make("ElectroLoc-v0", False, **kw)  # noqa: F841 - the registry is loaded
    env = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    ref = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    env.reset(seed=5)
    ref.reset(seed=5)
    with pytest.raises(ValueError, match=r"^seed must be None, an integer ≥ 0 or a sequence of 3 seeds"):
        env.reset(seed=seed)
    assert env.np_random_seed == ref.np_random_seed == tuple(sub_env_seeds(5, 3))
    actions = np.random.default_rng(0).uniform(-1, 1, (5, 3, 2))
    for a in actions:
        np.testing.assert_array_equal(env.step(a)[0], ref.step(a)[0])


def test_render_mode_of_the_wrong_type_is_one_clear_error() -> None:
    for mode in (1, b"human", "human ", ["rgb_array"]):
        with pytest.raises(ValueError, match=r"render_mode must be one of \['human', 'rgb_array'\] or None"):
            gym.make("ElectroLoc-v0", render_mode=mode)


# ---- the cap of readings: the reset takes the first, so the smallest cap is MIN_OBSERVATION_CAP ----------
CAP_ERROR = rf"^max_observations must be an integer ≥ {MIN_OBSERVATION_CAP} \(the reset takes the first reading"


@pytest.mark.parametrize("vector", [False, True])
@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("cap", [1, 0])
def test_a_cap_below_the_resets_reading_plus_one_is_one_error(env_id: str, vector: bool, cap: int) -> None:
    with pytest.raises(ValueError, match=CAP_ERROR + rf".*, got {cap}$"):
        _make(env_id, vector, n_particles=20, sensor_model="analytic", max_observations=cap)


def test_the_torch_engine_refuses_cap_one_with_the_same_error() -> None:
    pytest.importorskip("torch")
    with pytest.raises(ValueError, match=CAP_ERROR + r".*, got 1$"):
        gym.make_vec("ElectroLoc-v0", 2, vectorization_mode="vector_entry_point", backend="torch", max_observations=1)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_the_smallest_cap_is_a_whole_episode_of_that_many_readings(env_id: str) -> None:
    kw = {"n_particles": 40, "sensor_model": "analytic", "max_observations": MIN_OBSERVATION_CAP}
    spread = {} if env_id == "ElectroLocTrack-v0" else {"success_spread_mm": 1e-6}  # never a success: the cap ends it
    env = gym.make(env_id, **kw, **spread)
    env.reset(seed=0)
    steps, ended = 0, False
    while not ended:
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        steps, ended = steps + 1, terminated or truncated
    assert truncated and info["n_observations"] == MIN_OBSERVATION_CAP and steps == MIN_OBSERVATION_CAP - 1


def test_the_smallest_cap_on_the_torch_engine() -> None:
    pytest.importorskip("torch")
    kw = {"n_particles": 40, "sensor_model": "analytic", "success_spread_mm": 1e-6}
    vec = gym.make_vec(
        "ElectroLoc-v0",
        2,
        vectorization_mode="vector_entry_point",
        backend="torch",
        **kw,
        max_observations=MIN_OBSERVATION_CAP,
    )
    vec.reset(seed=0)
    for _ in range(MIN_OBSERVATION_CAP - 2):
        _, _, terminated, truncated, _ = vec.step(vec.action_space.sample())
        assert not (np.asarray(terminated) | np.asarray(truncated)).any()
    _, _, terminated, truncated, info = vec.step(vec.action_space.sample())
    assert np.asarray(truncated).all() and not np.asarray(terminated).any()
    assert np.asarray(info["n_observations"]).tolist() == [MIN_OBSERVATION_CAP] * 2


def test_bench_refuses_cap_one_before_any_trial_and_runs_the_smallest_cap(capsys, tmp_path) -> None:
    import json

    from electroloc_gym.bench.config import MAX_READINGS
    from electroloc_gym.cli import main

    base = ["bench", "--trials", "1", "--conditions", "fresh-steel-12.7", "--agents", "rnd-wlk"]
    base += ["--sensor-model", "analytic", "--n-particles", "100", "--backend", "serial", "--workers", "1"]
    base += ["--no-progress"]
    assert main([*base, "--max-observations", "1", "--out", str(tmp_path / "one")]) == 2
    out, err = capsys.readouterr()
    line = f"--max-observations must be an integer in [{MIN_OBSERVATION_CAP}, {MAX_READINGS}], got 1"
    assert err.strip().splitlines() == [f"electroloc bench: error: {line}"] and not out, err
    assert not (tmp_path / "one").exists()  # refused before any trial: nothing written
    run = tmp_path / "two"
    assert main([*base, "--max-observations", str(MIN_OBSERVATION_CAP), "--out", str(run)]) == 0, capsys.readouterr()
    (record,) = [json.loads(x) for x in (run / "trials.jsonl").read_text().splitlines()]
    assert record["readings"] == MIN_OBSERVATION_CAP and record["ended_by"] == "cap"
