"""``electroloc bench --distractors D``: the env gets D, records carry D and the far-success flag, bad values are one
clear error, and older runs (no ``distractors`` key) still resume as D = 0."""

from __future__ import annotations

import json

import pytest

from electroloc_gym.bench.agents import bench_env_kwargs
from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.bench.schema import FAR_ERROR_MM, TrialRecord, is_far_success
from electroloc_gym.cli import main as cli_main

TINY = dict(conditions=("fresh-steel-12.7",), trials=2, seed=3, n_particles=300, max_observations=8)


def test_far_success_is_one_definition() -> None:
    assert is_far_success(True, FAR_ERROR_MM + 0.1)
    assert not is_far_success(True, FAR_ERROR_MM)
    assert not is_far_success(False, 40.0)
    assert not is_far_success(True, None)


def test_config_and_cli_refuse_bad_counts(tmp_path, capsys) -> None:
    for bad in (-1, 9, True):
        with pytest.raises(ValueError, match=r"distractors must be an integer in \[0, 8\]"):
            BenchConfig(distractors=bad)
    with pytest.raises(
        ValueError,
        match=r"distractors must be 0 on ElectroLocGlobal-v0 \(only \['ElectroLoc-v0'\] take distractors\), got 1",
    ):
        BenchConfig(env_id="ElectroLocGlobal-v0", distractors=1)
    assert cli_main(["bench", "--distractors", "9", "--out", str(tmp_path / "x"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--distractors must be an integer in [0, 8], got 9" in err and err.count("\n") == 1


def test_agent_env_kwargs_cannot_override_the_runs_distractors() -> None:
    class Trained:
        env_kwargs = {"distractors": [0, 1, 2], "observation": "belief"}

    kw = bench_env_kwargs(
        "ElectroLoc-v0", Trained(), None, condition="fresh-steel-12.7", signal="fitted", distractors=2
    )
    assert kw["distractors"] == 2 and kw["observation"] == "belief"
    assert "distractors" not in bench_env_kwargs(
        "ElectroLoc-v0", Trained(), None, condition="fresh-steel-12.7", signal="fitted"
    )


def test_records_carry_d_and_far_success_and_the_env_has_the_distractors(tmp_path) -> None:
    cfg = BenchConfig(agents=("rnd-wlk",), distractors=2, **TINY)
    run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    recs = [json.loads(x) for x in (tmp_path / "trials.jsonl").read_text().splitlines()]
    assert len(recs) == 2
    for r in recs:
        assert r["distractors"] == 2
        assert r["far_success"] == is_far_success(r["success"], r["error_mm"])
    plain = tmp_path / "plain"
    run_benchmark(BenchConfig(agents=("rnd-wlk",), **TINY), plain, backend="serial", progress=False, log=None)
    plain_recs = [json.loads(x) for x in (plain / "trials.jsonl").read_text().splitlines()]
    assert [r["distractors"] for r in plain_recs] == [0, 0]
    # same seeds, same start; the distractors change the readings and so the trial
    assert [r["start"] for r in plain_recs] == [r["start"] for r in recs]
    assert [(r["readings"], r["estimate"]) for r in plain_recs] != [(r["readings"], r["estimate"]) for r in recs]
    with pytest.raises(ValueError, match="settings differ"):
        run_benchmark(
            BenchConfig(agents=("rnd-wlk",), distractors=1, **TINY),
            tmp_path,
            backend="serial",
            resume=True,
            progress=False,
            log=None,
        )


def test_an_older_run_without_the_key_resumes_as_zero(tmp_path) -> None:
    cfg = BenchConfig(agents=("rnd-wlk",), **{**TINY, "trials": 1})
    run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    for name in ("trials.jsonl",):
        path = tmp_path / name
        lines = [json.loads(x) for x in path.read_text().splitlines()]
        for rec in lines:
            rec.pop("distractors"), rec.pop("far_success")
        path.write_text("".join(json.dumps(r) + "\n" for r in lines))
    conf = json.loads((tmp_path / "config.json").read_text())
    conf.pop("distractors")
    (tmp_path / "config.json").write_text(json.dumps(conf))
    summary = run_benchmark(
        BenchConfig(agents=("rnd-wlk",), **TINY), tmp_path, backend="serial", resume=True, progress=False, log=None
    )
    assert summary is not None
    assert len((tmp_path / "trials.jsonl").read_text().splitlines()) == 2


def test_schema_refuses_a_far_flag_that_contradicts_the_error() -> None:
    rec = {
        "condition": "fresh-steel-12.7",
        "agent": "rnd-wlk",
        "agent_label": "rnd-wlk",
        "table_layout": "table4",
        "trial": 0,
        "seed": 1,
        "agent_seed": 2,
        "success": True,
        "ended_by": "success",
        "observations": 5,
        "error_mm": 20.0,
        "error_x_mm": 20.0,
        "error_y_mm": 0.0,
        "estimate": [20.0, 0.0],
        "target": [0.0, 0.0],
        "start": [1.0, 1.0],
        "spread_mm": 5.0,
        "decisions": 4,
        "decision_ms_median": 1.0,
        "decision_ms_mean": 1.0,
        "sensor_model": "calibrated",
        "signal": "fitted",
        "max_observations": 35,
        "n_particles": 2500,
        "env_id": "ElectroLoc-v0",
        "wall_s": 1.0,
        "distractors": 1,
        "far_success": True,
    }
    assert TrialRecord.from_json(rec).far_success
    with pytest.raises(ValueError, match="'far_success' False contradicts"):
        TrialRecord.from_json({**rec, "far_success": False})
    with pytest.raises(ValueError, match=r"Expected `int` <= 8 - at `\$.distractors`"):
        TrialRecord.from_json({**rec, "distractors": 9})
    for key in ("distractors", "far_success"):  # absent (an older record) reads as what it meant; null is refused
        with pytest.raises(ValueError, match=rf"got `null` - at `\$.{key}`"):
            TrialRecord.from_json({**rec, key: None})
    old = TrialRecord.from_json({k: v for k, v in rec.items() if k not in ("distractors", "far_success")})
    assert old.distractors == 0 and old.far_success and old.readings == 5


def test_a_bench_of_eight_distractors_always_finishes(tmp_path) -> None:
    """Seed 0's first 40 trials include three draws that rejection alone cannot place."""
    cfg = BenchConfig(
        agents=("rnd-wlk",),
        distractors=8,
        conditions=("fresh-steel-12.7",),
        trials=40,
        seed=0,
        n_particles=100,
        max_observations=2,
    )
    run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    recs = [json.loads(x) for x in (tmp_path / "trials.jsonl").read_text().splitlines()]
    assert len(recs) == 40 and all(r["distractors"] == 8 for r in recs)
