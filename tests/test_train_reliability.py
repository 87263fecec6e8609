"""Training runs that never mix or lose results: refusals, --force, --resume records, bad hyper-parameters."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from train_fixtures import TINY_YAML  # noqa: E402

from electroloc_gym.train.__main__ import main  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
ENV = ["--env-kwargs", "condition=random", "n_particles=100", "sensor_model=analytic"]
QUIET = ["--no-progress", "--no-tensorboard", "--verbose", "0"]


def _args(hp: Path, out: Path, *extra: str) -> list[str]:
    return [*ENV, "--n-envs", "2", "--hyperparams", str(hp), "--out", str(out), "--eval-freq", "128",
            "--eval-episodes", "2", "--checkpoint-freq", "128", *QUIET, *extra]


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> tuple[Path, Path]:
    """A finished 256-step run (evaluations at 0, 128, 256; checkpoints at 128, 256)."""
    tmp = tmp_path_factory.mktemp("rel")
    hp = tmp / "tiny.yml"
    hp.write_text(TINY_YAML)
    out = tmp / "run"
    assert main(_args(hp, out, "--timesteps", "256")) == 0
    return hp, out


@pytest.fixture
def run(base, tmp_path) -> tuple[Path, Path]:
    hp, out = base
    d = tmp_path / "run"
    shutil.copytree(out, d, ignore=shutil.ignore_patterns(".lock"))
    return hp, d


def _eval_rows(out: Path) -> list[int]:
    return [int(r.split(",")[0]) for r in (out / "eval.csv").read_text().splitlines()[1:]]


def _strict(path: Path):
    def bad(c):
        raise AssertionError(f"{path}: non-standard JSON constant {c}")
    return json.loads(path.read_text(), parse_constant=bad)


# ------------------------------------------------------------------------------- one run per folder
def test_an_existing_run_is_refused_without_resume_or_force(run, capsys):
    hp, out = run
    before = (out / "eval.csv").read_text()
    assert main(_args(hp, out, "--timesteps", "128")) == 2
    err = capsys.readouterr().err
    assert "already holds a training run" in err and "--resume" in err and "--force" in err
    assert (out / "eval.csv").read_text() == before


def test_force_deletes_the_run_and_starts_over(run):
    hp, out = run
    (out / "checkpoints" / "step_999999").mkdir()
    assert main(_args(hp, out, "--timesteps", "128", "--force")) == 0
    assert _eval_rows(out) == [0, 128]
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["step_128"]
    assert len(_strict(out / "args.json")["segments"]) == 1


def test_foreign_folders_and_files_are_never_used(tmp_path, capsys):
    hp = tmp_path / "tiny.yml"
    hp.write_text(TINY_YAML)
    other = tmp_path / "photos"
    other.mkdir()
    (other / "holiday.jpg").write_bytes(b"x")
    for extra in ([], ["--force"]):
        assert main(_args(hp, other, "--timesteps", "128", *extra)) == 2
        assert "not a training run folder" in capsys.readouterr().err
    assert [p.name for p in other.iterdir()] == ["holiday.jpg"]
    assert main(_args(hp, tmp_path / "tiny.yml", "--timesteps", "128")) == 2
    assert "existing file" in capsys.readouterr().err
    assert main(_args(hp, Path(""), "--timesteps", "128")) == 2


def test_a_run_in_use_is_refused(run, capsys):
    hp, out = run
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        assert main(_args(hp, out, "--resume", "--timesteps", "64")) == 2
        assert "in use by another training process" in capsys.readouterr().err
    finally:
        os.close(fd)


# ------------------------------------------------------------------------------------- --resume
def test_resume_records_the_whole_run_and_uses_its_own_config(run, capsys):
    hp, out = run
    cfg_before = (out / "config.yml").read_text()
    # A different YAML on resume is refused, naming what differs.
    other = out.parent / "other.yml"
    other.write_text(TINY_YAML.replace("n_epochs: 1", "n_epochs: 3"))
    assert main(["--out", str(out), "--resume", "--hyperparams", str(other), "--timesteps", "64", *QUIET]) == 2
    assert "contradict" in (err := capsys.readouterr().err) and "n_epochs" in err
    for bad in (["--n-envs", "3"], ["--env-kwargs", "n_particles=200"], ["--eval-episodes", "5"]):
        assert main(["--out", str(out), "--resume", *bad, "--timesteps", "64", *QUIET]) == 2
    assert main(["--out", str(out), "--resume", *QUIET]) == 2  # the budget (256) is used up
    assert "pass --timesteps" in capsys.readouterr().err
    # The same options as the run's own are accepted; the saved config is what is used and recorded.
    assert main(_args(hp, out, "--resume", "--timesteps", "128")) == 0
    assert main(["--out", str(out), "--resume", "--timesteps", "128", "--eval-freq", "128", *QUIET]) == 0
    cfg_after = (out / "config.yml").read_text()
    assert cfg_after.replace("n_timesteps: 512", "n_timesteps: 256") == cfg_before
    segs = _strict(out / "args.json")["segments"]
    assert [(s["timesteps_start"], s["timesteps_end"], s["status"]) for s in segs] == [
        (0, 256, "finished"), (256, 384, "finished"), (384, 512, "finished")]
    summary = _strict(out / "summary.json")
    assert summary["timesteps"] == 512 and summary["segments"] == 3
    assert summary["wall_time_s"] == pytest.approx(sum(s["wall_time_s"] for s in segs), abs=0.2)
    assert _eval_rows(out) == [0, 128, 256, 384, 512]
    cmd = (out / "command.txt").read_text()
    assert cmd.count("python -m electroloc_gym.train") == 3 and "3 segment(s)" in cmd
    assert json.loads((out / "policy.json").read_text())["provenance"]["timesteps"] == 512


@pytest.mark.parametrize("best_score, replaced", [(0.5, False), (1e9, True)])
def test_resume_keeps_the_best_score_of_the_run(run, best_score, replaced):
    hp, out = run
    meta = json.loads((out / "best" / "policy.json").read_text())
    meta["evaluation"]["mean_steps"] = best_score  # a better (or worse) best than anything a tiny run reaches
    (out / "best" / "policy.json").write_text(json.dumps(meta))
    weights = (out / "best" / "policy.safetensors").read_bytes()
    assert main(_args(hp, out, "--resume", "--timesteps", "128")) == 0
    assert ((out / "best" / "policy.safetensors").read_bytes() != weights) == replaced
    summary = _strict(out / "summary.json")
    assert (summary["best_mean_steps"] == best_score) == (not replaced)


def test_a_killed_run_resumes_from_its_last_checkpoint_without_mixing(run):
    """As after SIGKILL past the 128 checkpoint: no final model, evaluations and a checkpoint past it."""
    hp, out = run
    for name in ("model.zip", "policy.json", "policy.safetensors", "summary.json"):
        (out / name).unlink()
    shutil.rmtree(out / "checkpoints" / "step_256")
    rec = json.loads((out / "args.json").read_text())
    rec["segments"][0]["status"] = "running"
    (out / "args.json").write_text(json.dumps(rec))
    (out / "checkpoints" / "step_192").mkdir()  # an abandoned later checkpoint (no model: not resumable)
    assert main(["--out", str(out), "--resume", *QUIET]) == 0  # the rest of the budget: 128 → 256
    assert _eval_rows(out) == [0, 128, 256]
    set_aside = out / "superseded" / "segment-2"
    assert (set_aside / "eval.csv").read_text().splitlines()[1].startswith("256,")
    assert (set_aside / "checkpoints" / "step_192").is_dir()
    segs = _strict(out / "args.json")["segments"]
    assert [s["status"] for s in segs] == ["killed", "finished"]
    assert segs[1]["resumed_from"].endswith("step_128/model.zip") and segs[1]["timesteps_end"] == 256


def test_resume_from_a_checkpoint_into_a_new_folder(run, tmp_path):
    hp, out = run
    new = tmp_path / "branch"
    assert main(["--out", str(new), "--resume", str(out / "checkpoints" / "step_128"), "--timesteps", "64",
                 *QUIET]) == 0
    (seg,) = _strict(new / "args.json")["segments"]
    assert seg["timesteps_start"] == 128 and seg["timesteps_end"] >= 192
    # Resuming a model into another existing run would mix two runs.
    assert main(["--out", str(out), "--resume", str(new), "--timesteps", "64", *QUIET]) == 2


# ------------------------------------------------------------------------------ bad hyper-parameters
@pytest.mark.parametrize("yaml_line, pattern", [
    ("policy_kwargs: {net_arc: [32]}", r"policy_kwargs has unknown key\(s\) \['net_arc'\].*allowed: .*net_arch"),
    ("n_steps: abc", r"n_steps must be an integer ≥ 1, got 'abc'"),
    ("batch_size: 0", r"batch_size must be an integer ≥ 1, got 0"),
    ("batch_size: 1", r"batch_size must be an integer ≥ 2 for ppo"),
    ("gamma: 2.0", r"gamma must be a number in \[0, 1\], got 2.0"),
    ("learning_rate: -1", r"learning_rate must be a number > 0"),
    ("n_epochs: 1.5", r"n_epochs must be an integer"),
    ("normalize_advantage: maybe", r"normalize_advantage must be bool"),
    ("policy_kwargs: {net_arch: [0]}", r"net_arch must be a list of layer sizes"),
    ("env_kwargs: {bogus: 1}", r"bogus"),
    ("env_kwargs: {n_particles: -5}", r"n_particles"),
])
def test_bad_hyperparameters_fail_before_any_training(tmp_path, capsys, yaml_line, pattern):
    hp = tmp_path / "bad.yml"
    hp.write_text(f"ElectroLoc-v0:\n  n_steps: 64\n  {yaml_line}\n")
    out = tmp_path / "out"
    assert main(["--hyperparams", str(hp), "--out", str(out), "--timesteps", "64", *QUIET]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert pytest.importorskip("re").search(pattern, err), err
    assert not out.exists()


def test_bad_env_and_kwargs_on_the_command_line(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["--env", "Nope-v0", "--out", str(out), *QUIET]) == 2
    assert "'Nope-v0' is not a registered Gymnasium env" in capsys.readouterr().err
    assert main(["--env-kwargs", "nonsense_kw=1", "--out", str(out), *QUIET]) == 2
    assert "nonsense_kw" in capsys.readouterr().err
    assert main(["--eval-env-kwargs", "observation=sideways", "--out", str(out), *QUIET]) == 2
    assert "--eval-env-kwargs" in capsys.readouterr().err
    assert not out.exists()


def test_the_cli_shows_one_line_and_no_traceback(tmp_path):
    hp = tmp_path / "bad.yml"
    hp.write_text("ElectroLoc-v0:\n  gamma: 2.0\n")
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-m", "electroloc_gym.cli", "train", "--hyperparams", str(hp), "--out",
                           str(tmp_path / "o")], capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.strip().count("\n") == 0, proc.stderr
    assert "gamma must be a number in [0, 1]" in proc.stderr


def test_summary_json_is_strict_even_without_successes(run):
    from electroloc_gym.train.rundir import strict_json

    hp, out = run
    _strict(out / "summary.json")
    _strict(out / "args.json")
    text = strict_json({"median_steps_success": float("nan"), "best": float("inf")})
    assert json.loads(text) == {"median_steps_success": None, "best": None}


@pytest.mark.slow
def test_sigkill_then_resume_finishes_the_run_without_mixing(tmp_path):
    """Kill a real training process after its first checkpoint, resume, and check the records."""
    import signal
    import time

    hp = tmp_path / "tiny.yml"
    hp.write_text(TINY_YAML)
    out = tmp_path / "run"
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "electroloc_gym.train", *_args(hp, out, "--timesteps", "2048")]
    cmd[cmd.index("--checkpoint-freq") + 1] = "256"
    proc = subprocess.Popen(cmd, env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 300
        while not list(out.glob("checkpoints/step_*/policy.json")) and time.time() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (out / "summary.json").exists()
    assert main(["--out", str(out), "--resume", *QUIET]) == 0
    segs = _strict(out / "args.json")["segments"]
    assert [s["status"] for s in segs] == ["killed", "finished"] and segs[1]["timesteps_end"] >= 2048
    rows = _eval_rows(out)
    assert rows == sorted(set(rows)) and rows[0] == 0 and rows[-1] >= 2048  # no evaluation twice, in order
    assert _strict(out / "summary.json")["timesteps"] >= 2048
