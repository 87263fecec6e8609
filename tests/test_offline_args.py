"""The offline trainers' settings and datasets: every bad option or dataset is one line before anything is trained
or written (experiments/offline/common.py's ``prepare``), and a dataset's env must be the trainer's."""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path

import pytest

minari = pytest.importorskip("minari")  # the dev extra installs it; the numpy lower-bound session deselects these
torch = pytest.importorskip("torch")

pytestmark = pytest.mark.minari

ROOT = Path(__file__).resolve().parents[1]
OFFLINE = ROOT / "experiments" / "offline"
SMALL = ROOT / "tests" / "data" / "minari"
SMALL_ID = "electroloc/ElectroLoc-v0/lookahead-v0"
QUICK = ["--steps", "2", "--eval-every", "2", "--eval-episodes", "1"]


@pytest.fixture(scope="module")
def trainers():
    sys.path.insert(0, str(OFFLINE))
    import bc
    import common
    import td3_bc

    yield common, bc, td3_bc
    sys.path.remove(str(OFFLINE))


@pytest.fixture()
def store(tmp_path, monkeypatch):
    """A datasets root holding the committed small dataset and copies of it under other ids, edited."""
    root = tmp_path / "minari"
    shutil.copytree(SMALL, root)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))

    def copy(ds_id: str, edit) -> str:
        folder = root / ds_id
        shutil.copytree(root / SMALL_ID, folder)
        meta_path = folder / "data" / "metadata.json"
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
        meta["dataset_id"] = ds_id
        edit(meta)
        meta_path.write_text(json.dumps(meta), encoding="utf-8")
        return ds_id

    return copy


def _error(capsys, main, argv: list[str]) -> str:
    """Run a trainer's command line; it must exit 2 with one line on stderr (argparse's error). Returns it."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and err[0].startswith("usage:") and "Traceback" not in "".join(err), err
    errors = [line for line in err if ": error: " in line]
    assert errors == [err[-1]], err  # the usage, then one error line
    return err[-1].split(": error: ", 1)[1]


# ---- options ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv,pattern",
    [
        (["--datasets", ""], "--datasets names no dataset"),
        (["--datasets", " , "], "--datasets names no dataset"),
        (["--datasets", "mine/missing-v0"], "no dataset 'mine/missing-v0' in "),
        (["--datasets", "../x"], "'../x' is not a Minari dataset id"),
        (["--datasets", "mine/noversion"], "'mine/noversion' is not a Minari dataset id"),
        (["--datasets", f"{SMALL_ID},{SMALL_ID}"], "more than once"),
        (["--datasets", f"{SMALL_ID},"], "'' is not a Minari dataset id"),
        (["--lr", "nan"], r"--lr must be a finite number in \(0, 1\], got nan"),
        (["--lr", "-1"], r"--lr must be a finite number in \(0, 1\], got -1.0"),
        (["--lr", "1e30"], r"--lr must be a finite number in \(0, 1\]"),
        (["--lr", "0"], r"--lr must be a finite number in \(0, 1\]"),
        (["--lr", "inf"], r"--lr must be a finite number in \(0, 1\]"),
        (["--env-id", "Nope-v0"], r"--env-id must be one of \['ElectroLoc-v0'"),
        (["--seed", "-1"], r"--seed must be an integer in \[0, 4294967295\], got -1"),
        (["--steps", "0"], r"--steps must be an integer in \[1, "),
        (["--batch-size", "10000000"], r"--batch-size must be an integer in \[1, 1000000\]"),
        (["--eval-episodes", "0"], r"--eval-episodes must be an integer in \[1, "),
        (["--out", ""], "--out must name a folder"),
    ],
)
def test_bad_options_are_one_line_before_anything_is_written(trainers, store, capsys, tmp_path, argv, pattern):
    common, bc, _ = trainers
    argv = ["--datasets", SMALL_ID, "--out", str(tmp_path / "out"), *QUICK, *argv]
    msg = _error(capsys, bc.main, argv)
    assert re.search(pattern, msg), msg
    assert not (tmp_path / "out").exists()


def test_integers_in_other_scripts_are_refused(trainers, store, capsys, tmp_path):
    _, bc, _ = trainers
    msg = _error(capsys, bc.main, ["--seed", "３", "--out", str(tmp_path / "out")])
    assert "--seed" in msg and "ASCII digits" in msg


@pytest.mark.parametrize(
    "argv,pattern",
    [
        (["--discount", "2"], r"--discount must be a finite number in \[0, 1\]"),
        (["--tau", "0"], r"--tau must be a finite number in \(0, 1\]"),
        (["--alpha", "nan"], r"--alpha must be a finite number in \(0, 1000\]"),
        (["--policy-noise", "-0.1"], r"--policy-noise must be a finite number in \[0, 1\]"),
        (["--noise-clip", "inf"], r"--noise-clip must be a finite number in \[0, 1\]"),
        (["--policy-freq", "0"], r"--policy-freq must be an integer in \[1, "),
    ],
)
def test_td3_bc_options_are_checked_too(trainers, store, capsys, tmp_path, argv, pattern):
    _, _, td3_bc = trainers
    msg = _error(capsys, td3_bc.main, ["--datasets", SMALL_ID, "--out", str(tmp_path / "out"), *QUICK, *argv])
    assert re.search(pattern, msg), msg
    assert not (tmp_path / "out").exists()


def test_an_out_under_a_file_or_that_is_a_file_is_refused_before_training(trainers, store, capsys, tmp_path):
    _, bc, _ = trainers
    blocker = tmp_path / "file"
    blocker.write_text("keep", encoding="utf-8")
    msg = _error(capsys, bc.main, ["--datasets", SMALL_ID, "--out", str(blocker / "sub"), *QUICK])
    assert f"is under {str(blocker)!r}, which is a file" in msg
    msg = _error(capsys, bc.main, ["--datasets", SMALL_ID, "--out", str(blocker), *QUICK])
    assert "is a file, not a folder" in msg
    (tmp_path / "out" / "policy").mkdir(parents=True)
    (tmp_path / "out" / "curve.json").mkdir()
    msg = _error(capsys, bc.main, ["--datasets", SMALL_ID, "--out", str(tmp_path / "out"), *QUICK])
    assert "holds 'curve.json' as a folder" in msg
    assert blocker.read_text(encoding="utf-8") == "keep"


# ---- the datasets' env ------------------------------------------------------------------------------------------
def _global(meta):
    meta["electroloc"]["env_id"] = "ElectroLocGlobal-v0"


def test_a_dataset_of_another_env_is_refused(trainers, store, capsys, tmp_path):
    _, bc, _ = trainers
    other = store("mine/global-v0", _global)
    msg = _error(capsys, bc.main, ["--datasets", other, "--out", str(tmp_path / "out"), *QUICK])
    assert msg == f"--datasets: {other!r} was collected on ElectroLocGlobal-v0, not --env-id ElectroLoc-v0"
    assert not (tmp_path / "out").exists()


def test_datasets_of_different_envs_are_not_mixed(trainers, store, capsys, tmp_path):
    _, _, td3_bc = trainers
    other = store("mine/global-v0", _global)
    argv = ["--datasets", f"{SMALL_ID},{other}", "--out", str(tmp_path / "out"), *QUICK]
    msg = _error(capsys, td3_bc.main, argv)
    assert msg.startswith("--datasets mixes datasets of different envs:") and "ElectroLocGlobal-v0" in msg


@pytest.mark.parametrize(
    "edit,pattern",
    [
        (lambda m: m["electroloc"].update(complete=False), "is not complete"),
        (lambda m: m.pop("electroloc"), "was not made by `electroloc dataset`"),
        (lambda m: m["electroloc"].update(env_id=3), "was not made by `electroloc dataset`"),
        (
            lambda m: m.update(observation_space=m["observation_space"].replace("-1.0", "-2.0")),
            "has the observation space Box",
        ),
        (
            lambda m: m.update(action_space=m["action_space"].replace('"high": [1.0, 1.0]', '"high": [2.0, 2.0]')),
            "has the action space Box",
        ),
    ],
)
def test_datasets_that_do_not_fit_the_trainers_env_are_refused(trainers, store, capsys, tmp_path, edit, pattern):
    _, bc, _ = trainers
    ds_id = store("mine/edited-v0", edit)
    msg = _error(capsys, bc.main, ["--datasets", ds_id, "--out", str(tmp_path / "out"), *QUICK])
    assert pattern in msg and repr(ds_id) in msg


def test_a_damaged_dataset_header_is_one_line(trainers, store, capsys, tmp_path):
    _, bc, _ = trainers
    ds_id = store("mine/torn-v0", lambda m: None)
    (Path(minari.storage.get_dataset_path(ds_id)) / "data" / "metadata.json").write_text("", encoding="utf-8")
    msg = _error(capsys, bc.main, ["--datasets", ds_id, "--out", str(tmp_path / "out"), *QUICK])
    assert msg.startswith(f"--datasets: {ds_id!r} cannot be read: ")


def test_from_python_the_same_checks_are_one_value_error(trainers, store, tmp_path):
    common, bc, _ = trainers
    cfg = bc.TrainConfig(datasets=SMALL_ID, out=str(tmp_path / "out"), lr=float("nan"))
    with pytest.raises(ValueError, match=r"--lr must be a finite number in \(0, 1\]"):
        bc.train(cfg)
    with pytest.raises(common.ArgumentError, match="no dataset"):
        bc.train(bc.TrainConfig(datasets="mine/missing-v0", out=str(tmp_path / "out")))
    assert not (tmp_path / "out").exists()


def test_a_matching_dataset_still_trains(trainers, store, tmp_path):
    _, bc, _ = trainers
    out = tmp_path / "out"
    assert bc.main(["--datasets", SMALL_ID, "--out", str(out), *QUICK]) == 0
    policy = json.loads((out / "policy" / "policy.json").read_text(encoding="utf-8"))
    assert policy["observation"]["env_id"] == "ElectroLoc-v0"
    assert policy["provenance"]["datasets"] == [SMALL_ID]


# ---- the suite's scripts ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "script,argv,pattern",
    [
        ("run_suite", ["--seeds", "1,1"], "--seeds names a seed more than once"),
        ("run_suite", ["--seeds", "x"], r"--seeds must be comma-separated integers in \[0, 4294967295\]"),
        ("run_suite", ["--seeds", ""], "--seeds must be comma-separated integers"),
        ("run_suite", ["--trials", "３"], "ASCII digits"),
        ("make_datasets", ["--only", "nope"], r"--only names \['nope'\]; choose from"),
        ("make_datasets", ["--version", "-1"], r"--version must be an integer in \[0, 1000000\]"),
        ("report", ["--reps", "10000000"], r"--reps must be an integer in \[100, 1000000\]"),
    ],
)
def test_the_suites_scripts_refuse_bad_options_in_one_line(trainers, store, capsys, tmp_path, script, argv, pattern):
    import importlib

    module = importlib.import_module(script)
    full = [str(tmp_path), *argv] if script == "report" else argv
    msg = _error(capsys, module.main, full)
    assert re.search(pattern, msg), msg


def test_the_suite_refuses_an_out_under_a_file(trainers, capsys, tmp_path):
    import run_suite

    blocker = tmp_path / "file"
    blocker.write_text("", encoding="utf-8")
    msg = _error(capsys, run_suite.main, ["--out", str(blocker / "results")])
    assert "which is a file" in msg


#: (the edit of a stored benchmark's config.json, the one line the suite prints: None where the run is kept or
#: resumed; any line means the folder is removed and the benchmark run again from nothing)
BENCH_CONFIGS = [
    ("finished", None),  # the same trials and a summary.json: kept, nothing run
    ("unfinished", None),  # the same trials, no summary.json: resumed
    ("other-trials", "its benchmark ran another number of trials; running it again with 3"),
    ("garbage", "config.json: not valid UTF-8 JSON (DecodeError: JSON is malformed"),
    ("utf8", "config.json: not valid UTF-8 JSON (DecodeError"),
    ("nested", "config.json: not valid UTF-8 JSON (RecursionError"),
    ("list", "config.json: not a benchmark run's config: Expected `object`, got `array`"),
    ("missing-key", "config.json: not a benchmark run's config: missing key(s) ['seed']"),
    ("trials-text", "config.json: not a benchmark run's config: Expected `int`, got `str` - at `$.trials`"),
    ("unknown-env", "config.json: not a benchmark run's config: env_id must be one of"),
]


@pytest.mark.parametrize("edit, said", BENCH_CONFIGS, ids=[e for e, _ in BENCH_CONFIGS])
def test_the_suite_reads_a_bench_config_through_its_schema(trainers, capsys, tmp_path, monkeypatch, edit, said):
    """A stored benchmark's config.json is read as a run's config (its one schema): one that is not is named in
    one line and its benchmark is run again from nothing, like one of another trial count."""
    import msgspec
    import run_suite

    from electroloc_gym.bench.config import BenchConfig

    out = tmp_path / "bench"
    out.mkdir()
    config = msgspec.to_builtins(BenchConfig(agents=("ppo-belief",), trials=2 if edit == "other-trials" else 3))
    raw = {
        "garbage": b"[[[garbage",
        "utf8": b"\xff\xfe",
        "nested": b"[" * 50_000,
        "list": b"[1, 2]",
        "missing-key": json.dumps({k: v for k, v in config.items() if k != "seed"}).encode(),
        "trials-text": json.dumps({**config, "trials": "3"}).encode(),
        "unknown-env": json.dumps({**config, "env_id": "Nope-v0"}).encode(),
    }.get(edit, json.dumps(config).encode())
    (out / "config.json").write_bytes(raw)
    (out / "trials.jsonl").write_text("", encoding="utf-8")
    if edit == "finished":
        (out / "summary.json").write_text("{}", encoding="utf-8")
    runs: list[list[str]] = []
    monkeypatch.setattr(run_suite.subprocess, "run", lambda argv, **kwargs: runs.append(argv))
    capsys.readouterr()
    run_suite._bench("ppo-belief", out, 3)
    lines = capsys.readouterr().out.strip().splitlines()
    if said is None:  # kept (nothing run) or resumed
        assert lines == [] and out.is_dir()
        assert len(runs) == (edit == "unfinished") and all("--resume" in argv for argv in runs)
        return
    assert len(lines) == 1 and said in lines[0] and "Traceback" not in lines[0], lines
    if edit != "other-trials":  # the line names the file, then what the suite does
        assert lines[0].startswith(f"{out / 'config.json'}: ")
        assert lines[0].endswith("; running its benchmark again from nothing")
    assert not out.exists() and len(runs) == 1 and "--resume" not in runs[0]
    assert runs[0][runs[0].index("--trials") + 1] == "3"
