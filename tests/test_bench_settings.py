"""A benchmark run's settings are one object: built once (command line or Python), carried by every trial."""

from __future__ import annotations

import argparse

import pytest

from electroloc_gym.baselines.agent import AGENT_NAMES, agent_class, belief_agents
from electroloc_gym.bench import bench_command as bench_cli
from electroloc_gym.bench.api import prepare
from electroloc_gym.bench.config import (
    BENCH_ENVS,
    BENCH_OPTIONS,
    ENV_MAX_OBSERVATIONS,
    ENV_N_PARTICLES,
    ENV_SENSOR_MODELS,
    MAX_READINGS,
    BenchConfig,
    SettingError,
    make_trial_specs,
)
from electroloc_gym.bench.stored_run import record_rules
from electroloc_gym.contract.params import MIN_OBSERVATION_CAP


def _cli_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_cli.add_arguments(parser)
    return parser.parse_args(argv)


def _cli_config(args: argparse.Namespace) -> BenchConfig:
    """The run the command line prepares (agents rnd-wlk): the front end's own path."""
    values = {o.name: getattr(args, o.name) for o in BENCH_OPTIONS} | {"agents": "rnd-wlk", "out": None}
    return prepare(values, lambda o: o.option, lambda line: None)[0]


@pytest.mark.parametrize("env", list(BENCH_ENVS))
def test_the_defaults_are_the_env_tables(env) -> None:
    entry, row = BENCH_ENVS[env]
    config = BenchConfig.build(["rnd-wlk"], env=env)
    assert config.env_id == entry.env_id
    assert config.max_observations == ENV_MAX_OBSERVATIONS[entry.env_id]
    assert config.n_particles == ENV_N_PARTICLES[entry.env_id]
    assert config.sensor_model == ENV_SENSOR_MODELS[entry.env_id][0]
    gains = row.env_kwargs.get("gain_levels")
    assert config.gain_levels == (None if gains is None else tuple(float(g) for g in gains))


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["--env", "unknown-target", "--conditions", "fresh-steel-12.7", "--max-observations", "7"],
        ["--env", "dynamic-gain", "--n-particles", "300", "--trials", "4", "--seed", "9"],
        ["--sensor-layout", "line-4", "--distractors", "2", "--signal", "paper", "--sensor-model", "analytic"],
        ["--env", "global", "--max-observations", "12"],
    ],
)
def test_the_command_line_builds_what_python_builds(argv) -> None:
    args = _cli_args(argv)
    from_cli = _cli_config(args)
    from_python = BenchConfig.build(
        ["rnd-wlk"],
        env=args.env,
        conditions=args.conditions,
        trials=args.trials,
        seed=args.seed,
        sensor_model=args.sensor_model,
        signal=args.signal,
        max_observations=args.max_observations,
        n_particles=args.n_particles,
        sensor_layout=args.sensor_layout,
        distractors=args.distractors,
    )
    assert from_cli == from_python


@pytest.mark.parametrize("cap", [1, 0, -3, MAX_READINGS + 1, True, 2.0])
def test_the_cap_is_checked_once_and_named_by_each_front_end(cap) -> None:
    allowed = rf"an integer in \[{MIN_OBSERVATION_CAP}, {MAX_READINGS}\]"
    with pytest.raises(SettingError, match=rf"max_observations must be {allowed}") as exc:
        BenchConfig(agents=("rnd-wlk",), max_observations=cap)
    assert exc.value.setting == "max_observations" and exc.value.got is cap
    if isinstance(cap, int) and not isinstance(cap, bool):
        args = _cli_args(["--max-observations", str(cap)])
        with pytest.raises(ValueError) as cli_exc:
            _cli_config(args)
        want = f"--max-observations must be an integer in [{MIN_OBSERVATION_CAP}, {MAX_READINGS}], got {cap}"
        assert str(cli_exc.value) == want


def test_every_trial_carries_the_run_settings_unchanged() -> None:
    config = BenchConfig.build(
        ["rnd-wlk", "zero-crossing"], conditions="fresh-steel-12.7,salt-delrin-38.1", trials=2, max_observations=9
    )
    specs = make_trial_specs(config)
    assert len(specs) == 8 and all(spec.config is config for spec in specs)
    spec = specs[0]
    agent = agent_class("rnd-wlk")()
    assert spec.env_kwargs(agent, builtin=True) == config.env_kwargs(agent, spec.condition, builtin=True)
    assert config.record_settings() == {
        k: v for k, v in config.identity().items() if k not in ("seed", "success_spread_mm")
    }


def test_the_zero_crossing_cap_is_what_it_declares() -> None:
    config = BenchConfig.build(["rnd-wlk", "zero-crossing[max_observations=60]"], max_observations=6)
    rules = record_rules(config)
    assert rules.caps == {"rnd-wlk": 6, "zero-crossing[max_observations=60]": 60}
    zc = agent_class("zero-crossing")(max_observations=60)
    declared = config.env_kwargs(zc, builtin=True)
    assert declared["max_observations"] == 60
    assert rules.criteria["zero-crossing[max_observations=60]"] == declared["success_spread_mm"]
    assert rules.criteria["rnd-wlk"] == config.success_spread_mm


def test_belief_agents_are_every_registered_table4_controller() -> None:
    names = belief_agents()
    assert set(names) < set(AGENT_NAMES) and "zero-crossing" not in names
    assert all(agent_class(n).table_layout == "table4" for n in names)
    assert all(agent_class(n).table_layout != "table4" for n in set(AGENT_NAMES) - set(names))
