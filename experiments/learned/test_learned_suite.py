"""The learned-baseline suite: end to end on a tiny budget (slow: train with rl-zoo3 on the native vector env,
export, bench, then the rliable report — two algorithms × two seeds × two conditions × two trials), and a
quick smoke test of its front door in the default suite."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import rl_zoo3  # noqa: F401
import rliable  # noqa: F401

from electroloc_gym.registry import env_entry

pytestmark = pytest.mark.zoo  # the zoo extra (rl-zoo3, rliable)

ROOT = Path(__file__).resolve().parents[2]


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=900)


def test_a_failed_training_run_is_one_line(tmp_path):
    """Smoke test: the suite reaches rl-zoo3, whose run fails at once (no envs); one line, exit 2."""
    proc = _run(
        "experiments/learned/learned_suite.py",
        "--out",
        str(tmp_path / "o"),
        "--only",
        "ElectroLoc-v0/ppo",
        "--seeds",
        "1",
        "--timesteps",
        "64",
        "--hyperparams",
        "n_envs=0",
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "learned_suite: ElectroLoc-v0/ppo seed 1 failed:" in proc.stderr


@pytest.mark.slow
def test_suite_trains_exports_benches_and_reports(tmp_path):
    out = tmp_path / "learned"
    suite = [
        "experiments/learned/learned_suite.py",
        "--out",
        str(out),
        "--only",
        "ElectroLoc-v0/ppo,ElectroLoc-v0/a2c",
        "--seeds",
        "1,2",
        "--timesteps",
        "512",
        "--conditions",
        "fresh-steel-12.7,salt-delrin-38.1",
        "--trials",
        "2",
        "--workers",
        "1",
        "--hyperparams",
        "n_envs=2",
    ]
    proc = _run(*suite)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for algo in ("ppo", "a2c"):
        for seed in (1, 2):
            folder = out / "ElectroLoc-v0" / algo / f"seed-{seed}"
            assert (folder / "policy" / "policy.json").is_file()
            records = [json.loads(line) for line in (folder / "bench" / "trials.jsonl").read_text().splitlines()]
            assert len(records) == 4 and {r["condition"] for r in records} == {"fresh-steel-12.7", "salt-delrin-38.1"}
            assert list(folder.glob("zoo/*/*/eval.csv")), "the validation evaluations are kept"
    base = [
        json.loads(line)
        for line in (out / "ElectroLoc-v0" / "_baselines" / "bench" / "trials.jsonl").read_text().splitlines()
    ]
    assert {"rnd-wlk", "min-var", "lookahead"} <= {r["agent"] for r in base}
    runs = json.loads((out / "suite.json").read_text())
    assert len(runs) == 4 and all(r["train_wall_time_s"] > 0 for r in runs)

    # resumable: a second call finds every run and benchmark and trains nothing
    again = _run(*suite)
    assert again.returncode == 0, again.stderr[-2000:]
    assert len(list((out / "ElectroLoc-v0" / "ppo" / "seed-1" / "zoo" / "ppo").glob("ElectroLoc-v0_*/"))) == 1

    report = _run("experiments/learned/learned_report.py", str(out), "--reps", "200")
    assert report.returncode == 0, report.stderr[-2000:]
    text = (out / "report.md").read_text()
    assert "| ElectroLoc-v0 | ppo | 2 |" in text and "| ElectroLoc-v0 | a2c | 2 |" in text
    assert (out / "profile_ElectroLoc-v0.png").is_file() and (out / "curves_ElectroLoc-v0.png").is_file()


def test_suite_bad_arguments_are_one_line(tmp_path):
    for args, word in (
        (["--seeds", "x"], "--seeds"),
        (["--timesteps", "0"], "--timesteps"),
        (["--only", "nope"], "--only"),
        (["--trials", "0"], "--trials"),
    ):
        proc = _run("experiments/learned/learned_suite.py", "--out", str(tmp_path / "o"), *args)
        assert proc.returncode == 2 and word in proc.stderr and "Traceback" not in proc.stderr
        assert not (tmp_path / "o").exists()


def test_suite_lists_every_configuration():
    proc = _run("experiments/learned/learned_suite.py", "--list")
    assert proc.returncode == 0
    for label in ("ppo", "sac", "a2c", "qrdqn", "ppo_lstm-raw", "ppo-framestack-raw"):
        assert f" {label} " in proc.stdout
    from electroloc_gym.registry import ENVS

    assert all(e.env_id in proc.stdout for e in ENVS)  # every env of the table has a configuration


def test_the_off_policy_rows_are_in_the_suite():
    """SAC and CrossQ on the moving target and CrossQ on the still one: five seeds each, picked by --only."""
    only = "ElectroLocTrack-v0/sac,ElectroLocTrack-v0/crossq,ElectroLoc-v0/crossq"
    proc = _run("experiments/learned/learned_suite.py", "--list", "--only", only)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 3 and all("seeds [1, 2, 3, 4, 5]" in line for line in lines)
    assert [line.split()[:3] for line in lines] == [
        ["ElectroLoc-v0", "crossq", "crossq"],
        ["ElectroLocTrack-v0", "sac", "sac"],
        ["ElectroLocTrack-v0", "crossq", "crossq"],
    ]


def test_every_env_takes_its_baseline_agents(tmp_path):
    """The suite's non-learned agents of each env run on that env's benchmark (one trial of one condition),
    so a long reference run cannot end on an agent its env refuses."""
    import importlib.util

    from electroloc_gym.bench import run

    spec = importlib.util.spec_from_file_location("learned_suite", Path(__file__).with_name("learned_suite.py"))
    suite = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("learned_suite", suite)  # its dataclasses look their module up
    spec.loader.exec_module(suite)
    assert set(suite.BASELINE_AGENTS) == set(suite.BENCH_ENV) == {c.env_id for c in suite.SUITE}
    for env_id, agents in suite.BASELINE_AGENTS.items():
        bench_env = suite.BENCH_ENV[env_id]
        conditions = "all" if env_entry(env_id).map_condition is not None else "fresh-steel-38.1"
        result = run(
            agents.split(","), env=bench_env, conditions=conditions, trials=1, workers=1, out=tmp_path / bench_env
        )
        assert result.summary["agents"] == agents.split(","), env_id
        records = [json.loads(line) for line in (result.out / "trials.jsonl").read_text().splitlines()]
        assert {r["agent"] for r in records} == set(agents.split(",")), env_id
