"""Gymnasium's own array wrappers on every vector env: numpy envs seen as torch, the torch backend seen as numpy.

Every registered id's vector entry point (and the options that add info keys) under
``gymnasium.wrappers.vector.NumpyToTorch`` and ``ArrayConversion`` (numpy → torch), the torch backend under
``numpy_view`` and ``ArrayConversion`` (torch → numpy), and the single envs under ``NumpyToTorch``: reset and
step run, every value comes back in the other library, equal to the unwrapped env's on the same seeds.
``ArrayConversion`` exists from gymnasium 1.2 (the lowest supported, 1.1, has ``NumpyToTorch`` only).
"""

from __future__ import annotations

import sys
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.envs.torch_vector import numpy_view
from electroloc_gym.registry import ENV_IDS, env_entry
from electroloc_gym.world.conditions import PRESET_NAMES

torch.set_num_threads(1)
HAS_ARRAY_CONVERSION = hasattr(gym.wrappers.vector, "ArrayConversion")
SMALL = {"n_particles": 60, "sensor_model": "analytic"}

#: Every id, and the options that add info keys (distractors, a sensor array, the gain in the action).
VARIANTS = [pytest.param(env_id, {}, id=env_id) for env_id in ENV_IDS] + [
    pytest.param("ElectroLoc-v0", {"condition": "random", "distractors": 2}, id="distractors"),
    pytest.param("ElectroLoc-v0", {"sensor_layout": "grid-2x2"}, id="sensor-array"),
    pytest.param("ElectroLoc-v0", {"gain_levels": (0.5, 1.0, 2.0)}, id="dynamic-gain"),
    pytest.param("ElectroLocGlobal-v0", {"layout": "random"}, id="global-random-layout"),
]


def _to_torch_wrappers() -> list[Any]:
    wrappers: list[Any] = [pytest.param(lambda env: gym.wrappers.vector.NumpyToTorch(env), id="NumpyToTorch")]
    if HAS_ARRAY_CONVERSION:
        wrappers.append(
            pytest.param(
                lambda env: gym.wrappers.vector.ArrayConversion(env, env_xp=np, target_xp=torch), id="ArrayConversion"
            )
        )
    return wrappers


def _assert_same(converted: Any, raw: Any, kind: type, where: str) -> None:
    """``converted`` holds ``raw``'s values as ``kind`` (torch.Tensor or np.ndarray), key by key."""
    if isinstance(raw, dict):
        assert isinstance(converted, dict) and converted.keys() == raw.keys(), where
        for key in raw:
            _assert_same(converted[key], raw[key], kind, f"{where}[{key!r}]")
        return
    assert isinstance(converted, kind), f"{where}: {type(converted).__name__}"
    got = converted.numpy() if isinstance(converted, torch.Tensor) else converted
    want = raw.numpy() if isinstance(raw, torch.Tensor) else np.asarray(raw)
    np.testing.assert_array_equal(got, want, err_msg=where)


@pytest.mark.parametrize("wrap", _to_torch_wrappers())
@pytest.mark.parametrize(("env_id", "kwargs"), VARIANTS)
def test_numpy_vector_envs_through_torch(env_id: str, kwargs: dict[str, Any], wrap) -> None:
    make = lambda: gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **SMALL, **kwargs)  # noqa: E731
    raw, wrapped = make(), wrap(make())
    obs, info = wrapped.reset(seed=3)
    raw_obs, raw_info = raw.reset(seed=3)
    _assert_same(obs, raw_obs, torch.Tensor, "reset obs")
    _assert_same(info, raw_info, torch.Tensor, "reset info")
    assert "condition_index" in info
    raw.action_space.seed(0)
    for t in range(3):
        action = raw.action_space.sample()
        out = wrapped.step(torch.as_tensor(action))
        want = raw.step(action)
        for name, got, ref in zip(("obs", "reward", "terminated", "truncated", "info"), out, want, strict=True):
            _assert_same(got, ref, torch.Tensor, f"step {t} {name}")


def test_same_step_final_info_through_torch() -> None:
    kw = {**SMALL, "max_observations": 2, "autoreset_mode": "same_step"}
    make = lambda: gym.make_vec("ElectroLoc-v0", num_envs=2, vectorization_mode="vector_entry_point", **kw)  # noqa: E731
    raw, wrapped = make(), gym.wrappers.vector.NumpyToTorch(make())
    wrapped.reset(seed=1)
    raw.reset(seed=1)
    zeros = np.zeros((2, 2), dtype=np.float32)
    for _ in range(2):  # the second step reaches the cap: every sub-env ends and resets within it
        out, want = wrapped.step(torch.as_tensor(zeros)), raw.step(zeros)
    assert bool(want[3].all()) and "final_info" in want[4]
    _assert_same(out[4]["final_info"], want[4]["final_info"], torch.Tensor, "final_info")
    _assert_same(out[4]["final_obs"], want[4]["final_obs"], torch.Tensor, "final_obs")


def _torch_backend_ids() -> list[str]:
    return [env_id for env_id in ENV_IDS if "torch" in env_entry(env_id).backends]


def _torch_views() -> list[Any]:
    if not HAS_ARRAY_CONVERSION:  # gymnasium 1.1: numpy_view refuses in one line (tests/test_torch_backend.py)
        return []
    return [
        pytest.param(numpy_view, id="numpy_view"),
        pytest.param(
            lambda env: gym.wrappers.vector.ArrayConversion(env, env_xp=torch, target_xp=np), id="ArrayConversion"
        ),
    ]


@pytest.mark.parametrize("view", _torch_views())
@pytest.mark.parametrize("env_id", _torch_backend_ids())
def test_the_torch_backend_through_numpy(env_id: str, view) -> None:
    make = lambda: gym.make_vec(  # noqa: E731
        env_id, num_envs=2, vectorization_mode="vector_entry_point", backend="torch", device="cpu", **SMALL
    )
    raw, wrapped = make(), view(make())
    obs, info = wrapped.reset(seed=3)
    raw_obs, raw_info = raw.reset(seed=3)
    _assert_same(obs, raw_obs, np.ndarray, "reset obs")
    _assert_same(info, raw_info, np.ndarray, "reset info")
    rng = np.random.default_rng(0)
    for t in range(3):
        action = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        out = wrapped.step(action)
        want = raw.step(torch.as_tensor(action))
        for name, got, ref in zip(("obs", "reward", "terminated", "truncated", "info"), out, want, strict=True):
            _assert_same(got, ref, np.ndarray, f"step {t} {name}")


def test_the_torch_backend_id_list_is_not_empty() -> None:
    assert _torch_backend_ids() == ["ElectroLoc-v0"]


def _single_to_torch_wrappers() -> list[Any]:
    wrappers: list[Any] = [pytest.param(gym.wrappers.NumpyToTorch, id="NumpyToTorch")]
    if HAS_ARRAY_CONVERSION:
        wrappers.append(
            pytest.param(
                lambda env: gym.wrappers.ArrayConversion(env, env_xp=np, target_xp=torch), id="ArrayConversion"
            )
        )
    return wrappers


@pytest.mark.parametrize("wrap", _single_to_torch_wrappers())
@pytest.mark.parametrize("env_id", list(ENV_IDS))
def test_single_envs_through_torch(env_id: str, wrap) -> None:
    raw, wrapped = gym.make(env_id, **SMALL), wrap(gym.make(env_id, **SMALL))
    obs, info = wrapped.reset(seed=2)
    raw_obs, raw_info = raw.reset(seed=2)
    _assert_same(obs, raw_obs, torch.Tensor, "reset obs")
    assert isinstance(info["condition_index"], torch.Tensor)
    assert int(info["condition_index"]) == raw_info["condition_index"]
    action = raw.action_space.sample()
    obs, reward, terminated, truncated, info = wrapped.step(torch.as_tensor(action))
    raw_obs, raw_reward, *_ = raw.step(action)
    _assert_same(obs, raw_obs, torch.Tensor, "step obs")
    assert float(reward) == raw_reward and isinstance(info["spread_mm"], torch.Tensor)
    assert all(isinstance(v, torch.Tensor) for v in info.values()), {k: type(v).__name__ for k, v in info.items()}


def test_numpy_view_names_what_is_missing(monkeypatch) -> None:
    for name in list(sys.modules):  # gymnasium's conversion modules import array_api_compat when first loaded
        if name == "array_api_compat" or (name.startswith("gymnasium.wrappers") and "array_conversion" in name):
            monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "array_api_compat", None)  # as if not installed
    env = gym.make_vec("ElectroLoc-v0", num_envs=1, vectorization_mode="vector_entry_point", backend="torch", **SMALL)
    with pytest.raises(RuntimeError) as info:
        numpy_view(env)
    if HAS_ARRAY_CONVERSION:  # the wrapper is there; its dependency is not
        assert str(info.value) == (
            "numpy_view needs array-api-compat (Gymnasium's ArrayConversion wrapper imports it): "
            'pip install -c constraints.txt "electroloc-gym[train]"'
        )
    else:  # gymnasium 1.1: no wrapper to import
        assert "numpy_view needs gymnasium >= 1.2" in str(info.value)


#: Gymnasium's three ways to build a vector env of an id.
VECTOR_MODES = ("sync", "async", "vector_entry_point")


def _close(*envs: Any) -> None:
    for env in envs:
        env.close()


@pytest.mark.parametrize("wrap", _to_torch_wrappers())
@pytest.mark.parametrize("mode", VECTOR_MODES)
@pytest.mark.parametrize("env_id", list(ENV_IDS))
def test_every_vector_mode_through_torch(env_id: str, mode: str, wrap) -> None:
    """Every id in every vector mode under the numpy → torch wrappers: the info is numeric (the condition and
    any other name as an index into ``metadata["info_names"]``), so every entry converts, equal to the
    unwrapped env's (async compared with sync: the same sub-envs on the same seeds).
    """
    make = lambda m: gym.make_vec(env_id, num_envs=2, vectorization_mode=m, **SMALL)  # noqa: E731
    raw, wrapped = make("sync" if mode == "async" else mode), wrap(make(mode))
    try:
        obs, info = wrapped.reset(seed=3)
        raw_obs, raw_info = raw.reset(seed=3)
        _assert_same(obs, raw_obs, torch.Tensor, "reset obs")
        _assert_same(info, raw_info, torch.Tensor, "reset info")
        names = wrapped.metadata["info_names"]
        assert names["condition_index"] == PRESET_NAMES and info["condition_index"].dtype == torch.int64
        assert all(key in info for key in names), (sorted(names), sorted(info))
        raw.action_space.seed(0)
        for t in range(2):
            action = raw.action_space.sample()
            out = wrapped.step(torch.as_tensor(action))
            want = raw.step(action)
            for name, got, ref in zip(("obs", "reward", "terminated", "truncated", "info"), out, want, strict=True):
                _assert_same(got, ref, torch.Tensor, f"step {t} {name}")
    finally:
        _close(raw, wrapped)


@pytest.mark.parametrize("env_id", list(ENV_IDS))
def test_single_env_info_is_numeric_with_names_by_index(env_id: str) -> None:
    """The single env's info holds numbers and arrays only; a name is an index into ``metadata["info_names"]``."""
    env = gym.make(env_id, **SMALL)
    _, info = env.reset(seed=1)
    _, _, _, _, step_info = env.step(env.action_space.sample())
    for got in (info, step_info):
        odd = {k: type(v).__name__ for k, v in got.items() if not isinstance(v, (int, float, np.ndarray, np.generic))}
        assert not odd, odd
    names = env.unwrapped.metadata["info_names"]
    index, name = info["condition_index"], env.unwrapped.condition.name
    assert (names["condition_index"][index] if index >= 0 else name not in names["condition_index"]) in (name, True)
    for key, choices in names.items():
        assert 0 <= info[key] < len(choices) or (key == "condition_index" and info[key] == -1)
