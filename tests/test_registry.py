"""The env table (electroloc_gym.registry) is what Gymnasium, the core, the adapters and the benchmark read."""

from __future__ import annotations

import importlib

import gymnasium as gym
import pytest

import electroloc_gym
from electroloc_gym.bench import config as bench_config
from electroloc_gym.core.params import EnvParams
from electroloc_gym.core.step import make_task
from electroloc_gym.core.task import Task
from electroloc_gym.registry import BENCH_ENVS, ENV_IDS, ENVS, bench_env, env_entry, task_entry


def _load(path: str) -> type:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("entry", ENVS, ids=ENV_IDS)
def test_every_entry_is_registered_with_its_classes(entry) -> None:
    spec = gym.spec(entry.env_id)
    assert spec.entry_point == entry.entry_point and spec.vector_entry_point == entry.vector_entry_point
    assert _load(entry.entry_point)._ENV_ID == entry.env_id
    assert _load(entry.vector_entry_point)._ENV_ID == entry.env_id
    assert issubclass(_load(entry.task_class), Task)
    assert electroloc_gym.ENV_IDS == ENV_IDS


@pytest.mark.parametrize("entry", ENVS, ids=ENV_IDS)
def test_defaults_and_arguments_come_from_the_entry(entry) -> None:
    params = EnvParams.from_kwargs(entry.task, {}, entry.env_id)
    assert params.sensor_model == entry.sensor_models[0]
    for key, value in entry.defaults.items():
        assert getattr(params, key) == value
    task = make_task(params)
    assert type(task) is _load(entry.task_class)
    assert not hasattr(task, "name")  # the step cannot ask a task its name
    other = next(a for e in ENVS for a in e.arguments if a not in entry.all_arguments)
    with pytest.raises(ValueError, match=rf"{entry.env_id} got unexpected argument\(s\) \['{other}'\]"):
        EnvParams.from_kwargs(entry.task, {other: None}, entry.env_id)


def test_the_benchmark_reads_the_table() -> None:
    assert bench_config.ENV_CHOICES == {name: e.env_id for name, (e, _) in BENCH_ENVS.items()}
    assert set(bench_config.ENV_CHOICES) == {"target", "global", "unknown-target", "dynamic-gain"}
    assert bench_config.ENV_SENSOR_MODELS == {e.env_id: e.sensor_models for e in ENVS}
    assert bench_config.ENV_N_PARTICLES == {"ElectroLoc-v0": 2500, "ElectroLocGlobal-v0": 2500,
                                            "ElectroLocUnknownTarget-v0": 5000}
    assert bench_config.GLOBAL_CONDITION == "six-cylinders"
    assert bench_env("dynamic-gain")[1].env_kwargs["gain_levels"] == bench_config.DYNAMIC_GAIN_LEVELS
    assert bench_config.ENV_DEFAULT_AGENTS["global"] == ("rnd-wlk", "min-var")


def test_unknown_names_are_one_clear_error() -> None:
    with pytest.raises(ValueError, match=r"env_id must be one of \['ElectroLoc-v0'"):
        env_entry("ElectroLoc-v9")
    with pytest.raises(ValueError, match=r"task must be one of \['localize', 'global', 'unknown'\]"):
        task_entry("map")
    with pytest.raises(ValueError, match=r"--env must be one of"):
        bench_env("tank")
