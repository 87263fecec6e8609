"""rl-zoo3 drives training: each algorithm's shipped file trains a few hundred steps on the native vector env,
exports pickle-free, and the export runs in ``electroloc bench``."""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.zoo  # the zoo extra (rl-zoo3, sb3-contrib)

from train_fixtures import run_zoo, zoo_argv  # noqa: E402

from electroloc_gym.cli import main as cli_main  # noqa: E402
from electroloc_gym.policy import load_policy  # noqa: E402
from electroloc_gym.train.export import export_run  # noqa: E402


@pytest.mark.parametrize("algo", ["ppo", "a2c", "sac", "crossq", "ppo_lstm", "qrdqn"])
def test_each_algorithm_file_trains_exports_and_benches(algo, tmp_path, monkeypatch, capsys):
    run = run_zoo(zoo_argv(algo, tmp_path / "logs"), monkeypatch)
    out = capsys.readouterr().out
    assert "reward shaping on" in out and "NativeVecEnv" not in out
    summary = json.loads((run / "summary.json").read_text())
    assert summary["finished"] and summary["timesteps"] >= 256
    assert summary["algo"] == {"ppo_lstm": "recurrentppo"}.get(algo, algo)
    assert summary["best"]["episodes"] == 2 and summary["wall_time_s"] > 0
    rows = (run / "eval.csv").read_text().splitlines()
    assert rows[0].startswith("timesteps,") and len(rows) == 3  # at the start and at the end
    dest = export_run(run, tmp_path / "policy")
    agent = load_policy(dest)
    expected_mode = "raw" if algo == "ppo_lstm" else "belief"
    assert agent.env_kwargs == {
        "observation": expected_mode,
        "action_type": "discrete" if algo == "qrdqn" else "continuous",
    }
    assert "rl_zoo3.train" in (dest / "command.txt").read_text()
    bench = tmp_path / "bench"
    assert (
        cli_main(
            [
                "bench",
                "--agents",
                str(dest),
                "--conditions",
                "fresh-steel-12.7",
                "--trials",
                "2",
                "--n-particles",
                "300",
                "--backend",
                "serial",
                "--no-progress",
                "--out",
                str(bench),
            ]
        )
        == 0
    )
    table = json.loads((bench / "summary.json").read_text())
    assert "policy" in json.dumps(table)


@pytest.mark.parametrize("algo", ["sac", "crossq"])
def test_the_off_policy_learners_train_validate_and_bench_on_the_moving_target(algo, tmp_path, monkeypatch):
    """SAC and CrossQ on ElectroLocTrack-v0 through the shipped files: validated by the task's own score (the
    mean tracking error), the chosen checkpoint in best/ pickle-free, exported, and run by `electroloc bench
    --env track`."""
    run = run_zoo(zoo_argv(algo, tmp_path / "logs", env_id="ElectroLocTrack-v0"), monkeypatch)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["finished"] and summary["env_id"] == "ElectroLocTrack-v0" and summary["algo"] == algo
    assert "tracking error" in summary["chosen_by"]
    header = (run / "eval.csv").read_text().splitlines()[0].split(",")
    assert "wall_time_s" in header and "mean_tracking_error_mm" in header
    assert summary["best"]["mean_tracking_error_mm"] > 0
    assert json.loads((run / "best" / "policy.json").read_text())["algo"] == algo
    dest = export_run(run, tmp_path / "policy")
    assert load_policy(dest).meta["observation"]["env_id"] == "ElectroLocTrack-v0"
    bench = tmp_path / "bench"
    argv = ["bench", "--env", "track", "--agents", str(dest), "--trials", "1", "--n-particles", "300"]
    assert cli_main([*argv, "--backend", "serial", "--no-progress", "--out", str(bench)]) == 0
    assert "policy" in (bench / "summary.json").read_text()


def test_a_frame_stacked_raw_policy_trains_and_benches_as_trained(tmp_path, monkeypatch):
    """rl-zoo3's frame_stack (VecFrameStack outside VecNormalize): the export stacks normalised frames the same way."""
    run = run_zoo(
        zoo_argv("ppo", tmp_path / "logs", timesteps=128, env_kwargs={"observation": "raw"}, hyper={"frame_stack": 4}),
        monkeypatch,
    )
    agent = load_policy(run)
    assert agent.frame_stack == 4 and agent.obs_dim == 3 and agent.normalize_frames
    assert json.loads((run / "summary.json").read_text())["best"]["episodes"] == 2


def test_the_hook_swaps_dummy_vec_env_for_the_native_vector_env(tmp_path, monkeypatch):
    """One VecMonitor file (native batched env) with the hook; one Monitor file per env without it (DummyVecEnv)."""
    native = run_zoo(zoo_argv("ppo", tmp_path / "logs", timesteps=64), monkeypatch)
    assert sorted(p.name for p in native.glob("*.monitor.csv")) == ["0.monitor.csv"]
    monkeypatch.setattr("rl_zoo3.exp_manager.ExperimentManager.default_vec_env_cls", None)
    dummy = run_zoo(zoo_argv("ppo", tmp_path / "logs", timesteps=64, native=False), monkeypatch)
    assert sorted(p.name for p in dummy.glob("*.monitor.csv")) == [f"{i}.monitor.csv" for i in range(4)]
    assert (dummy / "best" / "policy.json").is_file()  # the callback and the shaping work on DummyVecEnv too


def test_enjoy_reports_the_task_measures_and_the_unshaped_return(tmp_path, monkeypatch, capsys):
    from electroloc_gym.train.zoo import main as zoo_main

    run = run_zoo(zoo_argv("ppo", tmp_path / "logs", timesteps=64), monkeypatch)
    capsys.readouterr()
    assert (
        zoo_main(
            [
                "enjoy",
                "--algo",
                "ppo",
                "--env",
                "ElectroLoc-v0",
                "-f",
                str(tmp_path / "logs"),
                "--exp-id",
                run.name.rsplit("_", 1)[1],
                "--no-render",
                "-n",
                "40",
                "--deterministic",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    reports = [ln for ln in out.splitlines() if ln.startswith("[electroloc] episode:")]
    rewards = [float(ln.split(":")[1]) for ln in out.splitlines() if ln.startswith("Episode Reward:")]
    assert reports and len(reports) == len(rewards)
    for line, reward in zip(reports, rewards):
        readings = int(line.split("episode:")[1].split("readings")[0])
        assert "(unshaped)" in line and "error" in line and "success" in line
        assert reward == pytest.approx(-(readings - 1))  # −1 per reading after the first: no shaping in enjoy


def test_zoo_runner_names_a_bad_script(capsys):
    from electroloc_gym.train.zoo import main as zoo_main

    assert zoo_main(["nope"]) == 2
    assert capsys.readouterr().err.strip().startswith("error: SCRIPT must be one of")
