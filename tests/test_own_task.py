"""A researcher's own task from their own module (examples/own_task.py, ``FrugalLoc-v0``), through the public
API only (:mod:`electroloc_gym.tasks`): Gymnasium's make and native vector env, both env checkers, the
benchmark's CLI with its own column and record field (checked on ``--resume``), a dataset, training's
validation score, and its options' errors. The package names nothing of it.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import electroloc_gym
from electroloc_gym.envs.adapter import CoreEnv
from electroloc_gym.envs.localize import LocalizeEnv
from electroloc_gym.envs.vector import CoreVectorEnv
from electroloc_gym.registry import env_entry, resolve_env_name
from tests.vector_equivalence import assert_native_equals_sync

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
ID = "FrugalLoc-v0"
SMALL = {"n_particles": 200}
ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(EXAMPLES), str(ROOT), os.environ.get("PYTHONPATH", "")]),
    "OMP_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}


@pytest.fixture(scope="module", autouse=True)
def own_task():
    """The researcher's module, outside the package (``import own_task`` with examples/ on the path), registered
    for this module's tests, then removed (the other test modules see the built-in table).
    """
    from electroloc_gym import registry

    sys.path.insert(0, str(EXAMPLES))
    try:
        module = importlib.import_module("own_task")
        yield module
    finally:
        sys.path.remove(str(EXAMPLES))
        module = sys.modules.pop("own_task", None)
        if module is not None:
            registry._TABLE[:] = [e for e in registry._TABLE if e.env_id != ID]
            gym.registry.pop(ID, None)
        if "own_task" in registry._PLUGIN_MODULES:
            registry._PLUGIN_MODULES.remove("own_task")


def test_the_package_names_nothing_of_the_task() -> None:
    """The task occupies no file of the package: its id, class, options and metrics are the example's only."""
    names = ("FrugalLoc", "FrugalTask", "FrugalOptions", "FrugalState", "FRUGAL_METRICS", "travel_mm", "travel_budget")
    hits = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "electroloc_gym").rglob("*.py")
        if any(n in p.read_text(encoding="utf-8") for n in names)
    ]
    assert hits == []


def test_the_entry_gets_generic_env_classes_of_its_own(own_task) -> None:
    entry = env_entry(ID)
    assert entry is own_task.ENTRY and entry.task_class is own_task.FrugalTask
    assert issubclass(entry.env_class, LocalizeEnv) and issubclass(entry.env_class, CoreEnv)
    assert issubclass(entry.vector_class, CoreVectorEnv)
    # set in the task's module, so that Gymnasium's entry points and pickling find them by name
    assert getattr(own_task, entry.env_class.__name__) is entry.env_class
    spec = gym.spec(ID)
    assert spec.entry_point == f"own_task:{entry.env_class.__name__}"
    assert spec.vector_entry_point == f"own_task:{entry.vector_class.__name__}"
    assert entry.arguments[-2:] == ("travel_cost_per_mm", "travel_budget_mm")  # read from FrugalOptions
    # registering the same declaration again is the same entry (a module imported twice)
    bare = own_task.EnvEntry(
        env_id=ID,
        task="frugal",
        task_class=own_task.FrugalTask,
        sensor_models=("calibrated", "analytic"),
        bench=entry.bench,
        summary=entry.summary,
    )
    assert electroloc_gym.register_env(bare) is entry


def test_gym_make_steps_charge_travel_and_the_budget_truncates(own_task) -> None:
    # a success criterion out of reach (0.5 mm), so that the budget ends the episode: back and forth, 10 mm a step
    env = gym.make(ID, **SMALL, success_spread_mm=0.5, travel_cost_per_mm=0.1, travel_budget_mm=40.0)
    _, info = env.reset(seed=3)
    assert info["travel_mm"] == 0.0 and not info["budget_spent"]
    travel, ended, sign = 0.0, False, 1.0
    while not ended:
        before = env.unwrapped.position_mm
        sign = -sign
        _, reward, terminated, truncated, info = env.step(np.array([sign, 0.0], dtype=np.float32))
        moved = float(np.hypot(*(env.unwrapped.position_mm - before)))
        travel += moved
        assert reward == pytest.approx(-1.0 - 0.1 * moved)
        assert info["travel_mm"] == pytest.approx(travel)
        ended = terminated or truncated
    assert travel >= 40.0 and info["budget_spent"] and truncated and not terminated
    assert info["cost"] == pytest.approx(env.unwrapped.max_observations + 0.1 * travel)  # a failure: the cap
    assert own_task.FRUGAL_METRICS.outcome(info) == "failure (travel budget spent)"
    env.close()


def test_gym_make_imports_the_module_by_name_in_a_fresh_process() -> None:
    """Gymnasium's convention: ``gym.make("own_task:FrugalLoc-v0")`` imports own_task, whose import registers."""
    code = (
        "import gymnasium as gym; env = gym.make('own_task:FrugalLoc-v0', n_particles=100); "
        "env.reset(seed=0); info = env.step(env.action_space.sample())[4]; "
        "print(type(env.unwrapped).__module__, info['travel_mm'] >= 0)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, cwd="/", timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["own_task", "True"]


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"travel_cost_per_mm": -1.0}, "travel_cost_per_mm must be"),
        ({"travel_cost_per_mm": "cheap"}, "travel_cost_per_mm must be"),
        ({"travel_budget_mm": 0.0}, "travel_budget_mm must be"),
        ({"travel_budget_mm": float("nan")}, "travel_budget_mm must be"),
        ({"travel_cost": 0.1}, "travel_cost"),
    ],
)
def test_bad_options_are_one_line_naming_the_option(kwargs, words) -> None:
    with pytest.raises(ValueError) as err:
        gym.make(ID, **kwargs)
    text = str(err.value)
    assert words in text and "\n" not in text


def test_native_vector_env_equals_a_sync_vector_env_of_single_envs(own_task) -> None:
    vec = gym.make_vec(ID, num_envs=2, vectorization_mode="vector_entry_point", **SMALL)
    assert type(vec.unwrapped) is own_task.ENTRY.vector_class
    vec.close()
    assert_native_equals_sync(
        ID,
        {**SMALL, "travel_budget_mm": 60.0},
        AutoresetMode.NEXT_STEP,
        ("travel_mm", "cost", "budget_spent", "error_mm"),
        n=3,
        steps=25,
        min_ended=1,
    )


def test_gymnasium_and_sb3_env_checkers() -> None:
    check_env(gym.make(ID, **SMALL).unwrapped)
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3.check_env(gym.make(ID, **SMALL).unwrapped, warn=True)


def _bench(out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    argv = ["--env", "own_task:frugal", "--agents", "rnd-wlk", "--conditions", "fresh-steel-12.7"]
    argv += ["--trials", "2", "--n-particles", "200", "--out", str(out), "--no-progress", *extra]
    return subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", "bench", *argv],
        capture_output=True,
        text=True,
        env=ENV,
        cwd="/",
        timeout=300,
    )


def test_bench_cli_runs_the_task_with_its_own_column_and_record_field(tmp_path) -> None:
    """``electroloc bench --env own_task:frugal`` in a fresh process, on two spawned workers (which import the
    module again); its table and records are the task's own; ``--resume`` checks the record field.
    """
    out = tmp_path / "run"
    proc = _bench(out, "--workers", "2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = (out / "table.md").read_text(encoding="utf-8")
    assert "## Travel (frugal localisation)" in table and "Travel median (mm)" in table
    lines = (out / "trials.jsonl").read_text(encoding="utf-8").splitlines()
    records = [json.loads(line) for line in lines]
    assert len(records) == 2 and {r["env_id"] for r in records} == {ID}
    for r in records:
        assert set(r["shape"]) == {"travel_mm", "cost", "budget_spent"} and r["shape"]["travel_mm"] > 0
    # a record whose travel is impossible is set aside on --resume and its trial runs again
    bad = dict(records[0], shape={**records[0]["shape"], "travel_mm": -5.0})
    (out / "trials.jsonl").write_text("\n".join([json.dumps(bad), lines[1]]) + "\n", encoding="utf-8")
    proc = _bench(out, "--workers", "1", "--resume")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "set 1 line(s) aside" in proc.stdout and "'shape' must be" in proc.stdout
    again = [json.loads(line) for line in (out / "trials.jsonl").read_text(encoding="utf-8").splitlines()]
    assert sorted(r["shape"]["travel_mm"] for r in again) == sorted(r["shape"]["travel_mm"] for r in records)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["bench", "--env", "no_such_module_xyz:frugal"], "--env 'no_such_module_xyz:frugal': cannot import module"),
        (["bench", "--env", "own_task:nope"], "--env must be one of"),
        (["bench", "--env", "own task:frugal"], "is malformed"),
        (["dataset", "--agent", "rnd-wlk", "--episodes", "1", "--env", "no_such_module_xyz:X-v0"], "cannot import"),
    ],
)
def test_a_bad_module_env_name_is_one_line(argv, words, tmp_path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", *argv, "--out", str(tmp_path / "o")]
        if argv[0] == "bench"
        else [sys.executable, "-m", "electroloc_gym.cli", *argv],
        capture_output=True,
        text=True,
        env={**ENV, "MINARI_DATASETS_PATH": str(tmp_path / "minari")},
        cwd="/",
        timeout=300,
    )
    err = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(err) == 1 and words in err[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_resolve_env_name_imports_the_module_and_remembers_it() -> None:
    assert resolve_env_name("own_task:FrugalLoc-v0") == ID
    assert resolve_env_name("ElectroLoc-v0") == "ElectroLoc-v0"
    from electroloc_gym.registry import plugin_modules

    assert "own_task" in plugin_modules()


@pytest.mark.minari
def test_a_dataset_of_the_task_keeps_its_info(tmp_path, monkeypatch, own_task) -> None:
    from electroloc_gym.cli import main

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    argv = ["dataset", "--env", "own_task:FrugalLoc-v0", "--agent", "rnd-wlk", "--episodes", "2", "--no-progress"]
    assert main(argv) == 0
    import minari

    ds = minari.load_dataset(f"electroloc/{ID}/rnd-wlk-v0")
    ep = next(ds.iterate_episodes())
    assert ds.total_episodes == 2 and "travel_mm" in ep.infos
    assert ep.infos["travel_mm"][0] == 0.0 and np.all(np.diff(ep.infos["travel_mm"]) >= 0)
    env = ds.recover_environment()  # by the entry point string: own_task's generic env
    assert type(env.unwrapped) is own_task.ENTRY.env_class


def test_training_chooses_checkpoints_by_the_tasks_own_score(tmp_path) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from electroloc_gym.train.callbacks import BenchEvalCallback, eval_fields, score_column
    from electroloc_gym.train.native_vec import make_native_vec_env

    assert score_column(ID) == ("mean_cost", True)
    assert {"mean_cost", "median_travel_mm"} <= set(eval_fields(ID))
    venv = make_native_vec_env(ID, 2, seed=0, env_kwargs=SMALL, monitor_file=str(tmp_path / "0.monitor.csv"))
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, device="cpu", seed=0)
    callback = BenchEvalCallback(eval_freq=16, n_episodes=2)
    model.learn(16, callback=callback)
    assert callback.select_key == "mean_cost" and callback.smaller
    header = (tmp_path / "eval.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert "mean_cost" in header and "median_travel_mm" in header
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert "lowest mean readings plus travel cost" in summary["chosen_by"]


def test_train_cli_passes_the_module_to_rl_zoo3(capsys, tmp_path) -> None:
    from electroloc_gym.train.__main__ import main

    argv = ["--algo", "ppo", "--seed", "1", "--env", "own_task:FrugalLoc-v0", "--print-command"]
    assert main(argv) == 2  # the shipped file has no section for a researcher's env: rl-zoo3 could not run it
    assert "--env must be an env id with a section in ppo.yml" in capsys.readouterr().err
    conf = tmp_path / "frugal.yml"  # the researcher's own hyper-parameters
    conf.write_text("FrugalLoc-v0:\n  policy: MlpPolicy\n  n_timesteps: 1000\n", encoding="utf-8")
    assert main([*argv, "--conf-file", str(conf)]) == 0
    words = capsys.readouterr().out.split()
    assert words[words.index("--env") + 1] == ID
    assert words[words.index("--gym-packages") + 1 : words.index("--gym-packages") + 3] == [
        "electroloc_gym.train.zoo",
        "own_task",
    ]


def test_the_example_runs_as_a_script() -> None:
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / "own_task.py")], capture_output=True, text=True, env=ENV, cwd="/", timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.startswith(f"{ID}: ") and "travel" in proc.stdout
