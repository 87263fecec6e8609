"""The env table (electroloc_gym.registry) is what Gymnasium, the core, the adapters and the benchmark read."""

from __future__ import annotations

import dataclasses
import importlib

import gymnasium as gym
import pytest

import electroloc_gym
from electroloc_gym.bench import config as bench_config
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.engines.numba_core.step import make_task
from electroloc_gym.engines.numba_core.task import Task
from electroloc_gym.registry import (
    BENCH_ENVS,
    COMMON_ARGUMENTS,
    ENV_IDS,
    ENVS,
    add_entry,
    bench_env,
    entry_of_class,
    env_entry,
    task_entry,
)


def _load(path: str) -> type:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("entry", list(ENVS), ids=list(ENV_IDS))
def test_every_entry_is_registered_with_its_classes(entry) -> None:
    spec = gym.spec(entry.env_id)
    assert _load(spec.entry_point) is entry.env_class and _load(spec.vector_entry_point) is entry.vector_class
    assert entry_of_class(entry.env_class) is entry and entry_of_class(entry.vector_class) is entry
    assert entry.env_class.entry() is entry and entry.vector_class.entry() is entry
    assert issubclass(entry.task_class, Task)
    assert electroloc_gym.ENV_IDS is ENV_IDS


def test_an_entrys_env_classes_are_its_familys_with_its_task_doc_and_options() -> None:
    """No built-in task writes an env class: each entry's pair is built on its family's, named after the task,
    documented by the task class, with a read-only accessor per option of the task's own."""
    from electroloc_gym.envs import TrackEnv, TrackVectorEnv
    from electroloc_gym.envs.localize import LocalizeEnv, LocalizeVectorEnv
    from electroloc_gym.envs.self_localize import SelfLocalizeEnv, SelfLocalizeVectorEnv

    track, glob = env_entry("ElectroLocTrack-v0"), env_entry("ElectroLocGlobal-v0")
    assert (track.env_class, track.vector_class) == (TrackEnv, TrackVectorEnv)
    assert issubclass(TrackEnv, LocalizeEnv) and issubclass(TrackVectorEnv, LocalizeVectorEnv)
    assert issubclass(glob.env_class, SelfLocalizeEnv) and issubclass(glob.vector_class, SelfLocalizeVectorEnv)
    assert TrackEnv.__doc__ == track.task_class.__doc__ and "## Episode End" in (TrackEnv.__doc__ or "")
    env = gym.make("ElectroLocTrack-v0", n_particles=50, target_speed_mm=2.5, motion_model="static").unwrapped
    assert (env.target_speed_mm, env.motion_model, env.motion_step_mm) == (2.5, "static", None)
    with pytest.raises(AttributeError):
        env.target_speed_mm = 1.0  # read-only: the env was made with it
    assert not hasattr(env_entry("ElectroLoc-v0").env_class, "target_speed_mm")  # another task's option


@pytest.mark.parametrize(
    "path",
    [
        "electroloc_gym.envs.localize:ElectroLocEnv",
        "electroloc_gym.envs.vector:ElectroLocVectorEnv",
        "electroloc_gym.envs.vector:UnknownTargetVectorEnv",
        "electroloc_gym.envs:GlobalEnv",
    ],
)
def test_the_entry_points_0_3_0_recorded_still_resolve(path: str) -> None:
    """A Minari dataset's spec (tests/data/minari) and a pickle name the module that held the class in 0.3.0."""
    from gymnasium.envs.registration import load_env_creator

    cls = load_env_creator(path)
    assert cls.__name__ == path.rpartition(":")[2] and cls.entry().env_id in ENV_IDS


def test_the_minari_fixture_recorded_an_entry_point_that_resolves() -> None:
    import json
    from pathlib import Path

    from gymnasium.envs.registration import load_env_creator

    meta = Path(__file__).parent / "data/minari/electroloc/ElectroLoc-v0/lookahead-v0/data/metadata.json"
    spec = json.loads(json.loads(meta.read_text(encoding="utf-8"))["env_spec"])
    assert spec["entry_point"] == "electroloc_gym.envs.localize:ElectroLocEnv"
    assert load_env_creator(spec["entry_point"]) is env_entry("ElectroLoc-v0").env_class


def test_a_subclass_of_a_registered_env_is_that_env() -> None:
    sub = type("MyEnv", (env_entry("ElectroLoc-v0").env_class,), {})
    assert entry_of_class(sub).env_id == "ElectroLoc-v0"
    with pytest.raises(ValueError, match="no env of the env table"):
        entry_of_class(gym.Env)


def test_an_entry_is_refused_when_it_clashes() -> None:
    entry = env_entry("ElectroLoc-v0")
    assert add_entry(entry) is False  # the same entry again: nothing to do
    with pytest.raises(ValueError, match="env_id 'ElectroLoc-v0' is already in the env table"):
        add_entry(dataclasses.replace(entry, task="other"))
    with pytest.raises(ValueError, match="must be an EnvEntry"):
        add_entry("ElectroLoc-v0")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="paper_table must be one of"):
        dataclasses.replace(entry, env_id="X-v0", paper_table="table9")
    with pytest.raises(ValueError, match="either the 'condition' argument"):
        dataclasses.replace(entry, env_id="X-v0", map_condition="my-map")


@pytest.mark.parametrize("entry", ENVS, ids=ENV_IDS)
def test_defaults_and_arguments_come_from_the_entry(entry) -> None:
    params = EnvParams.from_kwargs(entry.task, {}, entry.env_id)
    assert params.sensor_model == entry.sensor_models[0]
    assert type(params.options) is entry.task_class.Options
    assert entry.arguments == entry.task_class.Options.names()  # derived from the task's options, not restated
    for key, value in entry.defaults.items():
        assert getattr(params.options if key in entry.arguments else params, key) == value
    task = make_task(params)
    assert type(task) is entry.task_class
    assert not hasattr(task, "name")  # the step cannot ask a task its name
    other = next(a for e in ENVS for a in e.arguments if a not in entry.all_arguments)
    with pytest.raises(ValueError, match=rf"{entry.env_id} got unexpected argument\(s\) \['{other}'\]"):
        EnvParams.from_kwargs(entry.task, {other: None}, entry.env_id)


def test_the_benchmark_reads_the_table() -> None:
    assert bench_config.ENV_CHOICES == {name: e.env_id for name, (e, _) in BENCH_ENVS.items()}
    assert set(bench_config.ENV_CHOICES) == {"target", "global", "unknown-target", "dynamic-gain", "track"}
    assert bench_config.ENV_SENSOR_MODELS == {e.env_id: e.sensor_models for e in ENVS}
    assert bench_config.ENV_N_PARTICLES == {
        "ElectroLoc-v0": 2500,
        "ElectroLocGlobal-v0": 2500,
        "ElectroLocUnknownTarget-v0": 5000,
        "ElectroLocTrack-v0": 2500,
    }
    assert bench_config.MAP_CONDITIONS == ("six-cylinders",)
    env = gym.make("ElectroLocGlobal-v0")
    assert env.reset(seed=0)[1]["condition_index"] == -1 and env.unwrapped.condition.name == "six-cylinders"
    assert bench_env("dynamic-gain")[1].env_kwargs["gain_levels"] == (0.25, 1.0, 4.0)
    assert bench_config.ENV_DEFAULT_AGENTS["global"] == ("rnd-wlk", "min-var")


def test_unknown_names_are_one_clear_error() -> None:
    with pytest.raises(ValueError, match=r"env_id must be one of \['ElectroLoc-v0'"):
        env_entry("ElectroLoc-v9")
    with pytest.raises(ValueError, match=r"task must be one of \['localize', 'global', 'unknown', 'track'\]"):
        task_entry("map")
    with pytest.raises(ValueError, match=r"--env must be one of"):
        bench_env("tank")


def test_the_shared_arguments_are_the_shared_fields_and_the_options_are_the_tasks() -> None:
    """``COMMON_ARGUMENTS`` (the data layer's list) is ``EnvParams``' shared fields; gym.make's kwargs split into
    them and the task's ``Options``; options of another task are refused naming the class."""
    assert COMMON_ARGUMENTS == EnvParams.shared_names()
    params = EnvParams.from_kwargs("track", {"target_speed_mm": 3, "n_particles": 50}, "ElectroLocTrack-v0")
    assert params.n_particles == 50 and params.options.target_speed_mm == 3.0
    assert not hasattr(params, "target_speed_mm") and params.gain_levels is None
    glob = EnvParams.from_kwargs("global", {}, "ElectroLocGlobal-v0")
    with pytest.raises(ValueError, match=r"^options must be a TrackOptions \(the 'track' task's options\), got"):
        EnvParams(task="track", options=glob.options)
    assert EnvParams(task="unknown", sensor_model="analytic").options == task_entry("unknown").task_class.Options()
