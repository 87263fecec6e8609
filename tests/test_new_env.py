"""The env table with an entry that names its own env classes: a subclass of ElectroLoc-v0's task with nothing
new, under another id, registered with its single and vector env classes, reaches Gymnasium, the native vector
env, ``electroloc bench`` (its entry's defaults and default agents) and the RLlib creator; an entry without env
classes gets generic ones of its own. A task that is new in kind (its own options, per-env arrays and metrics,
from a module outside the package) is tests/test_own_task.py's."""

from __future__ import annotations

import json
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import electroloc_gym
from electroloc_gym import registry
from electroloc_gym.bench import bench_command as bench_cli
from electroloc_gym.engines.numba_core.electroloc import ElectroLocTask
from electroloc_gym.envs.localize import LocalizeEnv
from electroloc_gym.envs.vector import CoreVectorEnv
from electroloc_gym.registry import BenchEnv, EnvEntry, env_entry
from electroloc_gym.train import rllib


class FewReadingsTask(ElectroLocTask):
    """The tank of ElectroLoc-v0 under another id (a variant to register)."""


class FewReadingsEnv(LocalizeEnv):
    """The single env of the variant."""


class FewReadingsVectorEnv(CoreVectorEnv):
    """The native vector env of the variant."""


BASE = env_entry("ElectroLoc-v0")
ENTRY = EnvEntry(
    env_id="ElectroLocFewReadings-v0",
    task="few-readings",
    task_class=FewReadingsTask,
    env_class=FewReadingsEnv,
    vector_class=FewReadingsVectorEnv,
    sensor_models=BASE.sensor_models,
    defaults={"n_particles": 300, "max_observations": 6},
    bench=(BenchEnv("few-readings", agents=("rnd-wlk",)),),
)


@pytest.fixture
def registered():
    """The variant registered for one test, then removed (the other tests see the built-in table)."""
    electroloc_gym.register_env(ENTRY)
    yield ENTRY
    registry._TABLE.remove(ENTRY)
    gym.registry.pop(ENTRY.env_id)


def test_one_entry_makes_a_new_env(registered, tmp_path, capsys) -> None:
    electroloc_gym.register_env(ENTRY)  # idempotent
    env = gym.make("ElectroLocFewReadings-v0")
    assert env.unwrapped.params.n_particles == 300
    check_env(env.unwrapped)
    vec = gym.make_vec("ElectroLocFewReadings-v0", num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = vec.reset(seed=0)
    assert type(vec.unwrapped) is FewReadingsVectorEnv and obs.shape[0] == 2
    vec.close()
    out = tmp_path / "run"
    argv = [
        "--env",
        "few-readings",
        "--trials",
        "2",
        "--conditions",
        "fresh-steel-12.7",
        "--backend",
        "serial",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-progress",
    ]
    rc = bench_cli.run(_args(argv))
    assert rc == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["config"]["env_id"] == "ElectroLocFewReadings-v0"
    assert summary["config"]["max_observations"] == 6 and summary["config"]["n_particles"] == 300  # the entry's
    rows = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and all(r["readings"] <= 6 for r in rows)
    assert np.isfinite([r["target"][0] for r in rows]).all()
    assert {r["agent"] for r in rows} == {"rnd-wlk"}  # the bench row's default agents


def test_entries_without_env_classes_get_generic_classes_of_their_own(registered) -> None:
    """Two entries of one task class without env classes: each gets its own pair (the table finds an entry by
    its classes, and refuses two entries sharing one)."""
    from electroloc_gym.envs.generic import env_classes

    a = env_classes("ElectroLocFewA-v0", FewReadingsTask)
    b = env_classes("ElectroLocFewB-v0", FewReadingsTask)
    assert a[0] is not b[0] and a[1] is not b[1]
    assert issubclass(a[0], LocalizeEnv) and issubclass(a[1], CoreVectorEnv)
    with pytest.raises(ValueError, match="env_class .* is already in the env table"):
        registry.add_entry(
            EnvEntry(
                env_id="ElectroLocFewShared-v0",
                task="few-shared",
                task_class=FewReadingsTask,
                sensor_models=BASE.sensor_models,
                env_class=FewReadingsEnv,
                vector_class=a[1],
            )
        )
    with pytest.raises(ValueError, match="env_class and vector_class must be env classes"):
        registry.add_entry(
            EnvEntry(env_id="X-v0", task="x", task_class=FewReadingsTask, sensor_models=BASE.sensor_models)
        )
    for cls in (*a, *b):  # generated into this module by name; leave it as it was
        delattr(sys.modules[__name__], cls.__name__)


def test_the_rllib_creator_makes_the_new_env(registered) -> None:
    """RLlib's env runners call :func:`electroloc_gym.train.rllib.make_env`; it reads the live table."""
    env = rllib.make_env({"env_id": "ElectroLocFewReadings-v0"})
    assert type(env.unwrapped) is FewReadingsEnv
    vec = rllib.make_env({"env_id": "ElectroLocFewReadings-v0", "num_envs": 3})
    obs, _ = vec.reset(seed=1)
    assert type(vec.unwrapped) is FewReadingsVectorEnv and obs.shape[0] == 3
    vec.close()
    env.close()


def _args(argv: list[str]):
    import argparse

    parser = argparse.ArgumentParser()
    bench_cli.add_arguments(parser)
    return parser.parse_args(argv)
