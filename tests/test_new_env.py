"""docs/design.md's "how to add an environment", followed: one entry and one task module (here, in this
test) make a new env that Gymnasium, the native vector env, ``electroloc bench`` and the RLlib creator accept."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import electroloc_gym
from electroloc_gym import registry
from electroloc_gym.bench import bench_command as bench_cli
from electroloc_gym.engines.numba_core.electroloc import ElectroLocTask
from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.envs.vector import CoreVectorEnv
from electroloc_gym.registry import BenchEnv, EnvEntry, env_entry
from electroloc_gym.train import rllib


class FewReadingsTask(ElectroLocTask):
    """The tank of ElectroLoc-v0 under another id (a variant to register)."""


class FewReadingsEnv(ElectroLocEnv):
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
