"""The command line and the Python API take the same settings: one declaration per command, read by both.

Table-driven over the declarations themselves (:data:`~electroloc_gym.bench.config.BENCH_OPTIONS`,
:data:`~electroloc_gym.dataset.collect.DATASET_OPTIONS`, :data:`~electroloc_gym.train.settings.TRAIN_OPTIONS`): a
setting added to one is checked here without a new line.
"""

from __future__ import annotations

import argparse
import inspect
from collections.abc import Callable
from dataclasses import MISSING
from typing import Any, NamedTuple

import pytest

from electroloc_gym.bench import run as bench_run
from electroloc_gym.bench.config import BENCH_OPTIONS
from electroloc_gym.bench.schema import TIMING_KEYS
from electroloc_gym.cli import build_parser, main
from electroloc_gym.dataset.collect import BUILD_OPTIONS, DATASET_OPTIONS, DatasetRequest, build_dataset
from electroloc_gym.options import Option
from electroloc_gym.train.run import train
from electroloc_gym.train.settings import TRAIN_OPTIONS

#: Options every sub-command gets from the console script (the process's thread count), not a setting.
PROCESS_OPTIONS = {"help", "threads"}
#: Python-only keywords that are no setting (where notes go).
PYTHON_ONLY = {"log"}


class Command(NamedTuple):
    options: tuple[Option, ...]  # its declaration
    params: Callable[[], dict[str, inspect.Parameter]]  # its Python API's keywords
    call: Callable[[str, Any], None]  # the Python API given one setting
    argv: list[str]  # what the command line needs besides the setting
    python_differs: set[str]  # the settings whose Python default is declared to differ
    python_only: frozenset[str] = frozenset()  # the Python API's keywords that are no setting of the run
    cli_only: frozenset[str] = frozenset()  # the command line's options that are no setting of the run


def _bench_call(name: str, value: Any) -> None:
    bench_run(**{name: value})


_REQUEST = {"env_id": "ElectroLoc-v0", "agent": "rnd-wlk", "episodes": 1}


def _dataset_params() -> dict[str, inspect.Parameter]:
    build = dict(inspect.signature(build_dataset).parameters)
    del build["request"], build["notify"], build["names"]  # where notes go and how messages spell: no settings
    return {**inspect.signature(DatasetRequest).parameters, **build}


def _dataset_call(name: str, value: Any) -> None:
    if name in {o.name for o in BUILD_OPTIONS}:
        build_dataset(DatasetRequest(**_REQUEST), **{name: value})
    else:
        DatasetRequest(**{**_REQUEST, name: value})


_TRAIN = {"algo": "ppo", "env_id": "ElectroLoc-v0", "seed": 1}


def _train_call(name: str, value: Any) -> None:
    train(**{**_TRAIN, name: value})  # a bad value is refused before any run starts


COMMANDS = {
    "bench": Command(
        BENCH_OPTIONS, lambda: dict(inspect.signature(bench_run).parameters), _bench_call, [], {"out", "progress"}
    ),
    "dataset": Command(
        DATASET_OPTIONS,
        _dataset_params,
        _dataset_call,
        ["--agent", "rnd-wlk", "--episodes", "1"],
        {"env_id", "progress"},
    ),
    "train": Command(
        TRAIN_OPTIONS,
        lambda: dict(inspect.signature(train).parameters),
        _train_call,
        ["--algo", "ppo", "--seed", "1", "--print-command"],
        {"env_id"},
        python_only=frozenset({"quiet", "threads", "gym_packages"}),
        cli_only=frozenset({"print_command"}),
    ),
}


@pytest.fixture(autouse=True)
def _datasets_elsewhere(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))


def _subparser(command: str) -> argparse.ArgumentParser:
    if command == "train":  # its own parser (the console script hands it the arguments)
        from electroloc_gym.train.__main__ import build_parser as train_parser

        return train_parser()
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[command]


def _parser_options(command: str) -> dict[str, argparse.Action]:
    return {a.dest: a for a in _subparser(command)._actions if a.dest not in PROCESS_OPTIONS}


def _cases() -> list[tuple[str, Option, Any]]:
    return [(cmd, opt, bad) for cmd, c in COMMANDS.items() for opt in c.options for bad in opt.bad]


@pytest.mark.parametrize("command", list(COMMANDS))
def test_the_command_line_and_python_take_the_same_settings_with_the_same_defaults(command) -> None:
    c = COMMANDS[command]
    declared = {o.name: o for o in c.options}
    parsed = {k: v for k, v in _parser_options(command).items() if k not in c.cli_only}
    assert set(parsed) == set(declared)
    for name, action in parsed.items():
        opt = declared[name]
        assert action.option_strings == [opt.option], name
        if opt.default is MISSING:
            assert action.required, name
        else:
            assert action.default == opt.default and not action.required, name
    params = c.params()
    assert set(params) - PYTHON_ONLY - c.python_only == set(declared)
    for name, opt in declared.items():
        want = inspect.Parameter.empty if opt.api_default is MISSING else opt.api_default
        assert params[name].default == want, name
    # Where Python's default differs, the declaration says so (an output folder, a progress bar, a required env).
    assert {n for n, o in declared.items() if o.api_default is not o.default} == c.python_differs


@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_checked_setting_declares_values_it_refuses(command) -> None:
    assert [o.name for o in COMMANDS[command].options if o.check is not None and not o.bad] == []


def _cli_text(opt: Option, value: Any) -> str | None:
    """``value`` as the command line writes it (None: the command line cannot write it)."""
    if opt.kind in ("switch", "negated") or isinstance(value, bool):
        return None
    if opt.kind == "int":
        return str(value) if isinstance(value, int) else None
    return value if isinstance(value, str) else None


@pytest.mark.parametrize("command,opt,bad", _cases(), ids=[f"{c}-{o.name}-{b!r}" for c, o, b in _cases()])
def test_a_bad_value_is_the_same_one_line_error_from_both(command, opt, bad, capsys, tmp_path) -> None:
    with pytest.raises(ValueError) as exc:
        COMMANDS[command].call(opt.name, bad)
    python_line = str(exc.value)
    assert "\n" not in python_line
    text = _cli_text(opt, bad)
    if text is None:  # a value the command line cannot write (a switch's, a list)
        return
    argv = [command, *COMMANDS[command].argv, f"{opt.option}={text}"]
    if command == "bench" and opt.name != "out":
        argv += ["--out", str(tmp_path / "never")]
    capsys.readouterr()
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, (argv, err)
    prefix = f"electroloc {command}: error: "
    assert err.startswith(prefix), err
    assert err[len(prefix) :].rstrip("\n").replace(opt.option, opt.name) == python_line
    assert not (tmp_path / "never").exists()


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_switch_given_a_value_is_one_line(command, capsys) -> None:
    for opt in COMMANDS[command].options:
        if opt.kind in ("switch", "negated"):
            with pytest.raises(SystemExit) as exc:
                main([command, *COMMANDS[command].argv, f"{opt.option}=x"])
            assert exc.value.code == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and opt.option in err, err


@pytest.mark.parametrize("extra", [{"sensor_layout": "line-4"}, {"distractors": 1}])
def test_python_runs_what_the_command_line_runs(extra, tmp_path, capsys) -> None:
    """The settings the Python API lacked reach the run: both front ends store the same config.json."""
    import json

    settings = {"conditions": "fresh-steel-12.7", "trials": 1, "n_particles": 100, "max_observations": 4, **extra}
    settings["backend"] = "serial"
    bench_run("rnd-wlk", out=tmp_path / "py", **settings)
    flags = {o.name: o.option for o in BENCH_OPTIONS}
    argv = ["bench", "--agents", "rnd-wlk", "--out", str(tmp_path / "cli"), "--no-progress"]
    assert main(argv + [a for k, v in settings.items() for a in (flags[k], str(v))]) == 0, capsys.readouterr().err
    stored = [json.loads((tmp_path / d / "config.json").read_text()) for d in ("py", "cli")]
    assert stored[0] == stored[1] and all(stored[0][k] == v for k, v in extra.items())


@pytest.mark.parametrize(
    "settings, words",
    [
        ({"env": "unknown-target", "sensor_model": "calibrated"}, "must be one of ['analytic', 'interpolated'] on"),
        ({"env": "global", "distractors": 1}, "must be 0 on ElectroLocGlobal-v0"),
        ({"agents": "rnd-wlk,min-var", "trials": 100_000}, "must be at most 62,500 with 2 agent(s) × 8 condition(s)"),
    ],
)
def test_a_refusal_of_settings_together_names_each_as_its_front_end_does(settings, words, tmp_path, capsys) -> None:
    """What one setting's check cannot see (the env's sensor models, its distractors, the trials planned in all) is
    refused by the run's settings together, and still names the setting as the front end spells it."""
    flags = {o.name: o.option for o in BENCH_OPTIONS}
    setting = next(k for k in settings if k not in ("env", "agents"))
    argv = ["bench", "--out", str(tmp_path / "cli"), *(a for k, v in settings.items() for a in (flags[k], str(v)))]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"error: {flags[setting]} {words}" in err, err
    with pytest.raises(ValueError) as info:
        bench_run(**{k: v for k, v in settings.items() if k != "agents"}, agents=settings.get("agents"), out=tmp_path)
    assert str(info.value).startswith(f"{setting} {words}"), info.value
    assert not (tmp_path / "cli").exists() and not any(tmp_path.iterdir())


def _bench_twice(front: str, out: Any) -> None:
    for _ in range(2):  # the second run finds the first one's trials
        if front == "cli":
            argv = ["bench", "--agents", "rnd-wlk", "--conditions", "fresh-steel-12.7", "--trials", "1"]
            code = main([*argv, "--max-observations", "2", "--no-progress", "--out", str(out)])
            if code:
                raise ValueError(code)
        else:
            bench_run("rnd-wlk", conditions="fresh-steel-12.7", trials=1, max_observations=2, out=out)


def _dataset_twice(front: str, out: Any) -> None:
    for _ in range(2):  # the second run finds the first one's dataset
        if front == "cli":
            if main(["dataset", "--agent", "rnd-wlk", "--episodes", "1", "--no-progress"]):
                raise ValueError
        else:
            build_dataset(DatasetRequest(**_REQUEST))


def _bench_into_a_file(front: str, out: Any) -> None:
    out.write_text("a file")
    if front == "cli":
        if main(["bench", "--agents", "rnd-wlk", "--out", str(out / "sub")]):
            raise ValueError
    else:
        bench_run("rnd-wlk", out=out / "sub")


@pytest.mark.parametrize(
    "act, words",
    [
        (_bench_twice, "pass {resume} to continue that run or choose another {out}"),
        (_dataset_twice, "pass {force} to replace it or {resume} to check its episodes"),
        (_bench_into_a_file, "{out} '"),
    ],
    ids=["bench-existing-run", "dataset-existing-id", "bench-out-under-a-file"],
)
def test_a_refusal_during_the_run_names_the_settings_as_its_front_end_does(act, words, tmp_path, capsys) -> None:
    """A run's own refusals (an existing run, a folder that cannot be made) name the settings that would change it
    as the front end that took them spells them: ``--resume`` on the command line, ``resume=True`` from Python."""
    spelled = {
        "cli": {"resume": "--resume", "force": "--force", "out": "--out"},
        "python": {"resume": "resume=True", "force": "force=True", "out": "out"},
    }
    for front in spelled:
        with pytest.raises(ValueError) as info:
            act(front, tmp_path / front)
        said = capsys.readouterr().err.strip().splitlines()[-1] if front == "cli" else str(info.value)
        assert words.format(**spelled[front]) in said, (front, said)
        other = spelled["python" if front == "cli" else "cli"]
        assert not any(f" {name} " in f" {said} " for name in other.values() if name not in spelled[front].values())


def _runs_with_names(tmp_path: Any) -> dict[str, Callable[[Any], Any]]:
    from electroloc_gym.bench.config import BenchConfig
    from electroloc_gym.bench.ray_backend import check_ray_address
    from electroloc_gym.bench.runner import run_benchmark
    from electroloc_gym.demo import demo

    config = BenchConfig(agents=("rnd-wlk",), conditions=("fresh-steel-12.7",), trials=1, max_observations=2)
    return {
        "run_benchmark": lambda names: run_benchmark(config, tmp_path / "b", progress=False, log=None, names=names),
        "build_dataset": lambda names: build_dataset(DatasetRequest(**_REQUEST), names=names),
        "demo": lambda names: demo(out=tmp_path / "d.png", names=names),
        "check_ray_address": lambda names: check_ray_address(None, names),
    }


@pytest.mark.parametrize("names", ["--out", {"no_such_setting": "--x"}, {"out": 1}, {"out": ""}])
@pytest.mark.parametrize("function", ["run_benchmark", "build_dataset", "demo", "check_ray_address"])
def test_the_words_a_front_end_passes_are_checked_before_anything_runs(function, names, tmp_path) -> None:
    """``names`` (how a function's messages spell its settings) is None or a mapping of its settings to text: else
    one line naming it, before anything is written."""
    if function == "check_ray_address" and names == {"out": 1}:
        names = {"address": 1}  # its settings are the backend and the address
    with pytest.raises(ValueError, match=r"^names must be None or a mapping of settings \[.*\] to text, got "):
        _runs_with_names(tmp_path)[function](names)
    assert not any(tmp_path.rglob("*")), list(tmp_path.rglob("*"))


def test_numpy_integers_are_the_integers_they_hold(tmp_path) -> None:
    """A numpy integer passes an integer setting's check as the int it holds, and the run stores that int: the
    same records and config.json as plain ints (never a refusal after the folder is made)."""
    import json

    import numpy as np

    from electroloc_gym.bench.records import read_trials

    ints = {"trials": 1, "seed": 5, "n_particles": 100, "max_observations": 4, "distractors": 1, "workers": 1}
    for folder, cast in (("np", np.int64), ("int", int)):
        bench_run(
            "rnd-wlk", conditions="fresh-steel-12.7", out=tmp_path / folder, **{k: cast(v) for k, v in ints.items()}
        )
    stored = [json.loads((tmp_path / d / "config.json").read_text()) for d in ("np", "int")]
    assert stored[0] == stored[1]
    records = [read_trials(tmp_path / d / "trials.jsonl") for d in ("np", "int")]
    assert [{k: v for k, v in r.items() if k not in TIMING_KEYS} for r in records[0]] == [
        {k: v for k, v in r.items() if k not in TIMING_KEYS} for r in records[1]
    ]
    request = DatasetRequest(**{**_REQUEST, "episodes": np.int64(2), "seed": np.int64(3)})
    assert type(request.episodes) is int and type(request.seed) is int


def test_a_request_rebuilt_with_replace_keeps_its_checks() -> None:
    """``version`` None stays None (0 in the id), so ``dataclasses.replace`` with an id is not refused."""
    from dataclasses import replace

    request = DatasetRequest(**_REQUEST)
    assert request.id.endswith("-v0") and replace(request, dataset_id="test/x-v3").id == "test/x-v3"
    with pytest.raises(ValueError, match="version sets the default id's version; dataset_id carries its own -vN"):
        DatasetRequest(**_REQUEST, version=1, dataset_id="test/x-v3")
