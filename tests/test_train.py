"""The project's training additions: shaping, the evaluation callback's guards, the export's default path,
the front door's arguments, resumable runs."""

from __future__ import annotations

import json
import os
import pickle
import shlex
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytestmark = pytest.mark.zoo  # the zoo extra (rl-zoo3, SB3)

from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv  # noqa: E402
from train_fixtures import run_zoo, zoo_argv  # noqa: E402

import electroloc_gym  # noqa: E402, F401
from electroloc_gym.train.callbacks import BenchEvalCallback  # noqa: E402
from electroloc_gym.train.export import export_run  # noqa: E402
from electroloc_gym.train.wrappers import (  # noqa: E402
    VecPotentialShaping,
    activate_shaping,
    check_shaping,
    spread_potential,
)

ROOT = Path(__file__).resolve().parents[1]
KW = {"n_particles": 200, "max_observations": 12}


def _dummy(n=3, seed=4):
    venv = DummyVecEnv([lambda: Monitor(gym.make("ElectroLoc-v0", **KW)) for _ in range(n)])
    venv.seed(seed)
    return venv


def test_shaping_telescopes_and_is_off_until_training_switches_it_on():
    """Shaped return = unshaped return − Φ(s₀) on success (γ = 1); inactive: the env's own reward."""
    shaped = VecPotentialShaping(_dummy(), coef=1.0, gamma=1.0)
    plain = _dummy()
    assert not shaped.active and activate_shaping(shaped) == 1 and shaped.active
    shaped.reset(), plain.reset()
    phi0 = [spread_potential(i["spread_mm"], 10.0, 1.0) for i in shaped.unwrapped.reset_infos]
    ret_s, ret_p, checked = np.zeros(3), np.zeros(3), 0
    rng = np.random.default_rng(0)
    for _ in range(60):
        a = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        _, rs, ds, infos = shaped.step(a)
        _, rp, dp, _ = plain.step(a)
        assert np.array_equal(ds, dp)
        ret_s += rs
        ret_p += rp
        for i in np.flatnonzero(ds):
            if infos[i]["success"]:
                assert ret_s[i] == pytest.approx(ret_p[i] - phi0[i], abs=1e-4)
                checked += 1
            assert infos[i]["episode"]["r"] == pytest.approx(ret_p[i])  # the monitor logs the unshaped return
            phi0[i] = spread_potential(shaped.unwrapped.reset_infos[i]["spread_mm"], 10.0, 1.0)
            ret_s[i] = ret_p[i] = 0.0
    assert checked >= 1
    off = VecPotentialShaping(_dummy(), coef=1.0, gamma=0.99)
    off.reset()
    plain = _dummy()
    plain.reset()
    a = np.zeros((3, 2), np.float32)
    assert np.array_equal(off.step(a)[1], plain.step(a)[1])


@pytest.mark.parametrize(
    "coef, gamma, pattern",
    [(-1.0, 0.99, "coef must be a number ≥ 0"), (float("nan"), 0.99, "coef"), (1.0, 1.5, "gamma must be in")],
)
def test_bad_shaping_arguments_are_one_line(coef, gamma, pattern):
    with pytest.raises(ValueError, match=pattern):
        check_shaping(coef, gamma)


@pytest.mark.parametrize(
    "kwargs, pattern",
    [
        ({"eval_freq": 0}, "eval_freq must be an integer ≥ 1"),
        ({"n_episodes": 1.5}, "n_episodes must be"),
        ({"seed": -1}, "seed must be an integer ≥ 0"),
        ({"select": "success"}, r"select must be one of \['score', 'mean_readings', 'mean_return'\]"),
    ],
)
def test_bad_callback_arguments_are_one_line(kwargs, pattern):
    with pytest.raises(ValueError, match=pattern):
        BenchEvalCallback(**kwargs)


@pytest.mark.parametrize(
    "argv, pattern",
    [
        (
            ["--algo", "td3", "--seed", "1"],
            "--algo must be one of ['a2c', 'crossq', 'ppo', 'ppo_lstm', 'qrdqn', 'sac'], got 'td3'",
        ),
        (["--algo", "ppo", "--seed", "-1"], "--seed must be an integer in [0, 4294967295] (NumPy's seed range)"),
        (["--algo", "ppo", "--seed", str(2**64)], "--seed must be an integer in [0, 4294967295] (NumPy's seed range)"),
        (["--algo", "ppo", "--seed", "1", "--env", "Nope-v0"], "--env must be a registered env id (ElectroLoc-v0,"),
        (  # registered, but the algorithm's file has no section for it: rl-zoo3 could not run it
            ["--algo", "a2c", "--seed", "1", "--env", "ElectroLocTrack-v0", "--print-command"],
            "--env must be an env id with a section in a2c.yml (['ElectroLoc-v0',",
        ),
        (["--algo", "ppo", "--seed", "1", "--env", "CartPole-v1"], "--env must be an env id with a section in ppo.yml"),
        (["--algo", "ppo", "--seed", "1", "--timesteps", "0"], "timesteps must be an integer in [1,"),
        (["--algo", "ppo", "--seed", "1", "--timesteps", str(10**30)], "timesteps must be an integer in [1,"),
        (
            ["--algo", "ppo", "--seed", "1", "--env-kwargs", "observation"],
            "--env-kwargs: 'observation' must be key=value",
        ),
        (["--algo", "ppo", "--seed", "1", "--env-kwargs", "distractors=9"], "refused by ElectroLoc-v0"),
        (["--algo", "ppo", "--seed", "1", "--env-kwargs", "fixed_carriage='yes'"], "fixed_carriage must be"),
        (["--algo", "ppo"], "the following arguments are required: --seed"),
        (["--algo", "ppo", "--seed", "x"], "argument --seed: must be an integer in ASCII digits, got 'x'"),
    ],
)
def test_the_front_door_names_each_bad_argument_in_one_line(argv, pattern, capsys):
    from electroloc_gym.cli import main

    try:
        code = main(["train", *argv])
    except SystemExit as exc:  # argparse's own one-line errors
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and pattern in err


def test_a_log_folder_under_a_file_is_one_line(tmp_path, capsys):
    from electroloc_gym.cli import main

    (tmp_path / "a-file").write_text("")
    code = main(
        ["train", "--algo", "ppo", "--seed", "1", "--log-folder", str(tmp_path / "a-file" / "x"), "--print-command"]
    )
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "is a file" in err


@pytest.mark.parametrize("entry", ["electroloc train", "python -m electroloc_gym.train"])
def test_a_file_system_error_of_training_is_one_line_from_either_entry(entry, tmp_path, capsys, monkeypatch):
    """A disk that refuses a write is the same one line and exit 2 from the console script and from ``python -m``."""
    import errno
    import runpy
    import sys

    import electroloc_gym.train.run as train_run
    from electroloc_gym.cli import main

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(train_run, "train", full_disk)
    monkeypatch.delitem(sys.modules, "electroloc_gym.train.__main__", raising=False)  # imported anew: patched
    argv = ["--algo", "ppo", "--seed", "1", "--log-folder", str(tmp_path / "logs")]
    if entry == "electroloc train":
        code = main(["train", *argv])
    else:
        monkeypatch.setattr(sys, "argv", ["electroloc_gym.train", *argv])
        with pytest.raises(SystemExit) as info:
            runpy.run_module("electroloc_gym.train", run_name="__main__")
        code = info.value.code
    err = capsys.readouterr().err
    assert code == 2 and err.strip().splitlines() == [
        "electroloc train: error: cannot write: No space left on device"
    ], err


def test_the_front_door_prints_the_exact_rl_zoo3_command(capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    from electroloc_gym.train.__main__ import main

    assert (
        main(
            [
                "--algo",
                "ppo",
                "--seed",
                "3000",
                "--env-kwargs",
                "observation=raw",
                "--hyperparams",
                "frame_stack=16",
                "--print-command",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert out.startswith(
        "python -m rl_zoo3.train --algo ppo --env ElectroLoc-v0 --gym-packages electroloc_gym.train.zoo --conf-file "
    )
    words = shlex.split(out)
    tail = ["--env-kwargs", "observation:'raw'", "--hyperparams", "frame_stack:16"]
    assert words[words.index("--env-kwargs") :] == tail
    assert (
        words[words.index("--conf-file") + 1] == "electroloc_gym/train/hyperparams/ppo.yml"
    )  # relative to the repository root


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    try:
        run = run_zoo(zoo_argv("ppo", tmp_path_factory.mktemp("zoo") / "logs", timesteps=128), mp)
    finally:
        mp.undo()
    return run


def test_a_run_folder_is_never_shared(tiny_run, monkeypatch):
    """A second run into a folder that holds a run's eval.csv is refused; the first run's files are intact."""
    from electroloc_gym.utils.fileio import FolderBusyError, FolderLock

    before = (tiny_run / "eval.csv").read_text()
    from stable_baselines3 import PPO

    from electroloc_gym.train.native_vec import make_native_vec_env

    venv = make_native_vec_env("ElectroLoc-v0", 2, seed=0, env_kwargs=KW, monitor_file=str(tiny_run / "0.monitor.csv"))
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, device="cpu")
    with pytest.raises(ValueError, match="already holds another run's eval.csv"):
        model.learn(16, callback=BenchEvalCallback(n_episodes=1))
    assert (tiny_run / "eval.csv").read_text() == before
    with FolderLock(tiny_run, ".bench_eval.lock", "busy"):  # a run writing there holds this lock
        with pytest.raises(FolderBusyError):
            FolderLock(tiny_run, ".bench_eval.lock", "busy").acquire()


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_the_export_default_path_opens_no_pickle(tiny_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    marker = tmp_path / "pwned"
    for pkl in run.rglob("*.pkl"):
        pkl.write_bytes(pickle.dumps(_Payload(marker)))
    for z in run.glob("*.zip"):
        z.write_bytes(pickle.dumps(_Payload(marker)))
    args = run / "ElectroLoc-v0" / "args.yml"  # rl-zoo3 reads it with yaml.UnsafeLoader; the export does not
    args.write_text(args.read_text() + f"  - - evil\n    - !!python/object/apply:os.system ['touch {marker}']\n")
    dest = export_run(run, tmp_path / "out")
    meta = json.loads((dest / "policy.json").read_text())
    assert meta["provenance"]["command"].startswith("python -m rl_zoo3.train")
    assert meta["provenance"]["checkpoint_chosen_by"].startswith("fewest mean readings")
    assert {p.name for p in dest.iterdir()} >= {
        "policy.json",
        "policy.safetensors",
        "eval.csv",
        "summary.json",
        "command.txt",
        "config.yml",
    }
    from electroloc_gym.bench.agents import make_bench_agent

    make_bench_agent(str(run))  # a run folder resolves to its best/ export
    assert not marker.exists()
    with pytest.raises(ValueError, match="--trust-pickle"):
        export_run(run, tmp_path / "o2", zip_path=run / "ElectroLoc-v0.zip")
    assert not marker.exists()


def test_export_errors_are_one_line(tmp_path, capsys):
    from electroloc_gym.train.export import main

    assert main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == f"error: run folder {str(tmp_path / 'missing')!r} does not exist"
    (tmp_path / "r").mkdir()
    assert main([str(tmp_path / "r"), "--out", str(tmp_path / "o")]) == 2
    assert "has no summary.json" in capsys.readouterr().err


def test_a_finished_run_is_found_instead_of_retrained(tiny_run):
    from electroloc_gym.train.run import find_finished_run

    summary = json.loads((tiny_run / "summary.json").read_text())
    log_folder = tiny_run.parent.parent
    assert find_finished_run(log_folder, "ppo", "ElectroLoc-v0", summary["argv"]) == tiny_run
    assert find_finished_run(log_folder, "ppo", "ElectroLoc-v0", [*summary["argv"], "--seed", "8"]) is None


def test_summary_records_honest_timing(tiny_run):
    s = json.loads((tiny_run / "summary.json").read_text())
    assert s["finished"] and s["timesteps"] >= 128
    assert 0 < s["evaluation_time_s"] < s["wall_time_s"]
    assert s["fps_training_only"] > s["fps_with_evaluation"] > 0
    assert s["argv"][:2] == ["-m", "rl_zoo3.train"]


def test_learning_curves_from_a_run(tiny_run, tmp_path):
    from electroloc_gym.train.curves import main

    assert main([str(tiny_run), "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").stat().st_size > 1000


@pytest.mark.parametrize(
    "text, words",
    [
        ("", "no rows"),
        ("timesteps,success_rate\n1,0.5\n", "missing column(s) ['mean_readings', 'median_readings']"),
        ("timesteps,success_rate,mean_readings,median_readings\n1,0.5,x,3\n", "a non-number in column 'mean_readings'"),
        ("timesteps,success_rate,mean_readings,median_readings\n1,nan,3,3\n", "non-finite evaluation in column"),
    ],
)
def test_the_eval_csv_reader_refuses_a_damaged_log_in_one_line(tmp_path, text, words) -> None:
    from electroloc_gym.train.curves import read_eval_csv

    (tmp_path / "eval.csv").write_text(text, encoding="utf-8")
    with pytest.raises(ValueError) as err:
        read_eval_csv(tmp_path)
    assert words in str(err.value) and str(tmp_path) in str(err.value) and "\n" not in str(err.value)
    (tmp_path / "eval.csv").write_text("timesteps,success_rate,mean_readings,median_readings\n5,1,4,4\n")
    assert read_eval_csv(tmp_path) == {
        "timesteps": [5.0],
        "success_rate": [1.0],
        "mean_readings": [4.0],
        "median_readings": [4.0],
    }


@pytest.mark.parametrize("verbose", [0, 1])
def test_a_training_process_leaves_no_sb3_folder_in_the_temporary_folder(verbose, tmp_path, monkeypatch):
    """SB3's logger makes a folder even when it writes no file; the training process's environment points it at
    the run's log folder (a user's own ``SB3_LOGDIR`` wins), so the system's temporary folder stays as it was."""
    import tempfile

    from stable_baselines3.common.utils import configure_logger

    from electroloc_gym.train.run import child_env

    system_tmp, logs = tmp_path / "tmp", tmp_path / "logs" / "ppo"
    system_tmp.mkdir()
    logs.mkdir(parents=True)
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    for name, value in child_env(logs, 1).items():
        monkeypatch.setenv(name, value)
    logger = configure_logger(verbose=verbose)
    assert logger.dir == str(logs)
    assert list(system_tmp.iterdir()) == [] and list(logs.iterdir()) == []
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "mine"))
    assert child_env(logs, 1)["SB3_LOGDIR"] == str(tmp_path / "mine")
    monkeypatch.delenv("SB3_LOGDIR")  # without it, SB3 makes a dated folder in the temporary folder
    assert configure_logger(verbose=verbose).dir.startswith(str(system_tmp / "SB3-"))
