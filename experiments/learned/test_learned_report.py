"""The learned-baseline report (learned_report.py, its statistics in learned_scores.py) on synthetic records."""

import importlib.util
import json
from pathlib import Path

import msgspec
import numpy as np
import pytest
import rliable.library  # noqa: F401  (the zoo extra installs it; rliable 1.2 needs pandas<3 for arch)

pytestmark = pytest.mark.zoo

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("learned_report", ROOT / "experiments" / "learned" / "learned_report.py")
report = importlib.util.module_from_spec(spec)
spec.loader.exec_module(report)
import learned_scores as scores  # noqa: E402  (beside the report, which put its folder on sys.path)

from electroloc_gym.bench.config import (  # noqa: E402
    ENV_MAX_OBSERVATIONS,
    ENV_N_PARTICLES,
    ENV_SENSOR_MODELS,
    BenchConfig,
)
from electroloc_gym.bench.records import open_trials  # noqa: E402
from electroloc_gym.registry import bench_env, task_entry  # noqa: E402

TARGET_ID, GLOBAL_ID = bench_env("target")[0].env_id, bench_env("global")[0].env_id

#: The tests' short condition names → the conditions their records and config.json hold (in the same order).
NAMES = {"a": "fresh-delrin-12.7", "b": "fresh-steel-12.7", "g": task_entry("global").map_condition}
CONDS = (NAMES["a"], NAMES["b"])
#: Bootstrap draws of the tests that check which records are set aside and the scores' matrices, not the intervals
#: (0.05 s an analysis, not 0.5 s at 200 draws).
SET_ASIDE_REPS = 20


RESULTS = ROOT / "experiments" / "learned" / "results"
with open_trials(RESULTS / "ElectroLoc-v0" / "ppo" / "seed-1" / "bench" / "trials.jsonl") as _kept:  # or its .gz
    TEMPLATE = json.loads(_kept.readline())


def _record(cond: str, agent: str, trial: int, n: int) -> dict:
    """A schema-valid record: a success after n readings, or (n > 35) a failure at the cap."""
    rec = {**TEMPLATE, "condition": NAMES[cond], "agent": agent, "trial": trial}
    rec.pop("far_success", None)  # absent: computed from success and error (null is refused)
    if n <= 35:
        rec.update(success=True, ended_by="success", observations=n, decisions=n - 1, spread_mm=2.0)
    else:
        rec.update(success=False, ended_by="cap", observations=35, decisions=34, spread_mm=20.0)
    return rec


def _config_json(env_id: str, conditions: list[str]) -> dict:
    """A run's config.json: three trials of ``conditions`` (short names) with the env's default settings."""
    config = BenchConfig(
        agents=("-",),
        conditions=tuple(sorted(NAMES[c] for c in conditions)),
        trials=3,
        env_id=env_id,
        sensor_model=ENV_SENSOR_MODELS[env_id][0],
        n_particles=ENV_N_PARTICLES[env_id],
        max_observations=ENV_MAX_OBSERVATIONS[env_id],
    )
    return {**msgspec.to_builtins(config), "agents": []}


def _append_run(path: Path, agent: str, rows: list[dict], conditions: list[str], env_id: str) -> None:
    """Append ``agent``'s trial records to the run's trials file and add the agent to its config.json."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write("".join(json.dumps(r) + "\n" for r in rows))
    cfg_path = path.parent / "config.json"
    cfg = json.loads(cfg_path.read_text()) if cfg_path.is_file() else _config_json(env_id, conditions)
    cfg["agents"] = sorted(set(cfg["agents"]) | {agent})
    cfg_path.write_text(json.dumps(cfg))


def _write(path: Path, agent: str, readings: dict[str, list[int]], env_id: str = TARGET_ID) -> None:
    rows = [_record(cond, agent, t, n) for cond, obs in readings.items() for t, n in enumerate(obs)]
    _append_run(path, agent, rows, list(readings), env_id)
    (path.parent / "summary.json").write_text("{}")  # the benchmark finished


def _results(tmp_path: Path) -> Path:
    env = tmp_path / "ElectroLoc-v0"
    base = env / "_baselines" / "bench" / "trials.jsonl"
    _write(base, "rnd-wlk", {"a": [20, 30, 99], "b": [25, 25, 25]})  # 99: a failure, scored as the cap 35
    _write(base, "min-var", {"a": [10, 10, 10], "b": [15, 15, 15]})
    for k, shift in enumerate((0, 1, 2)):
        _write(
            env / "ppo" / f"seed-{k}" / "bench" / "trials.jsonl", "ppo", {"a": [5 + shift] * 3, "b": [6 + shift] * 3}
        )
    return tmp_path


def test_scores_count_failures_as_the_cap(tmp_path):
    conds, learned, baselines, seeds = scores.collect(_results(tmp_path), "ElectroLoc-v0")
    assert conds == list(CONDS)
    np.testing.assert_allclose(baselines["rnd-wlk"]["readings"][0], [(20 + 30 + 35) / 3, 25])
    np.testing.assert_allclose(baselines["rnd-wlk"]["success"][0], [2 / 3, 1])
    assert learned["ppo"]["readings"].shape == (3, 2) and seeds["ppo"] == ["seed-0", "seed-1", "seed-2"]


def test_normalised_score_is_zero_at_rnd_wlk_and_one_at_the_best_planner(tmp_path):
    _, _, baselines, _ = scores.collect(_results(tmp_path), "ElectroLoc-v0")
    np.testing.assert_allclose(scores.normalised(baselines["rnd-wlk"]["readings"], baselines), 0)
    np.testing.assert_allclose(scores.normalised(baselines["min-var"]["readings"], baselines), 1)


def test_analysis_intervals_contain_the_point_and_poi_is_certain(tmp_path):
    a = scores.analyse(_results(tmp_path), "ElectroLoc-v0", reps=200)
    row = a["algorithms"]["ppo"]
    for key in ("readings_iqm", "readings_mean", "success_mean", "normalised_iqm"):
        point, lo, hi = row[key]
        assert lo <= point <= hi
    assert row["readings_mean"][0] == pytest.approx(np.mean([5, 6, 6, 7, 7, 8]))
    assert row["p_improvement"]["min-var"][0] == pytest.approx(1.0)  # every ppo run beats min-var everywhere
    assert "lookahead" not in row["p_improvement"]


def test_intervals_are_reproducible_and_independent_of_the_other_algorithms():
    rng = np.random.default_rng(3)
    a, b = rng.normal(5, 1, (5, 8)), rng.normal(7, 2, (3, 8))
    mean = lambda x: np.array([x.mean()])  # noqa: E731
    alone = scores.interval({"a": a}, mean, reps=300, seed=0)["a"]
    assert scores.interval({"a": a}, mean, reps=300, seed=0)["a"] == alone  # the same records, the same CI
    assert scores.interval({"b": b, "a": a}, mean, reps=300, seed=0)["a"] == alone
    assert scores.interval({"a": a}, mean, reps=300, seed=1)["a"] != alone  # the seed does reach the draws


def test_an_extra_folder_joins_the_table_on_the_same_trials_only(tmp_path):
    res = _results(tmp_path / "suite")
    extra = tmp_path / "offline"
    bc = extra / "ElectroLoc-v0" / "bc-min-var"
    for k in (1, 2):
        _write(bc / f"seed-{k}" / "bench" / "trials.jsonl", f"{bc}/seed-{k}/policy", {"a": [9, 11, 10], "b": [14] * 3})
    a = scores.analyse(res, "ElectroLoc-v0", reps=200, extra=[extra])
    assert set(a["algorithms"]) == {"ppo", "bc-min-var"} and a["seeds"]["bc-min-var"] == ["seed-1", "seed-2"]
    assert a["algorithms"]["bc-min-var"]["readings_mean"][0] == pytest.approx(12.0)
    assert a["algorithms"]["ppo"] == scores.analyse(res, "ElectroLoc-v0", reps=200)["algorithms"]["ppo"]
    assert report.main([str(res), "--reps", "200", "--extra", str(extra)]) == 0
    assert "| ElectroLoc-v0 | bc-min-var | 2 |" in (res / "report.md").read_text()
    _write(bc / "seed-3" / "bench" / "trials.jsonl", "bc", {"a": [9, 11], "b": [14, 14]})  # two trials, not three
    with pytest.raises(scores.ReportError, match="other trials"):
        scores.analyse(res, "ElectroLoc-v0", reps=200, extra=[extra])
    clash = tmp_path / "clash"
    _write(clash / "ElectroLoc-v0" / "ppo" / "seed-1" / "bench" / "trials.jsonl", "ppo", {"a": [5] * 3, "b": [6] * 3})
    with pytest.raises(scores.ReportError, match="already in"):
        scores.analyse(res, "ElectroLoc-v0", reps=200, extra=[clash])


def test_main_writes_report_and_figure(tmp_path):
    res = _results(tmp_path)
    assert report.main([str(res), "--reps", "200"]) == 0
    text = (res / "report.md").read_text()
    assert "| ElectroLoc-v0 | ppo | 3 |" in text
    assert "| ppo (3 seeds) | 6.00 (5.0–7.0) | 7.00 (6.0–8.0) |" in text  # per condition: mean (min–max) of seeds
    assert "| rnd-wlk | 28.33 | 25.00 |" in text
    assert json.loads((res / "report.json").read_text())[0]["env_id"] == TARGET_ID
    assert (res / "profile_ElectroLoc-v0.png").stat().st_size > 0


def test_main_says_its_progress_and_every_file_it_wrote_into_out(tmp_path, capsys):
    res = _results(tmp_path / "runs")
    before = sorted(p.name for p in res.iterdir())
    out = tmp_path / "elsewhere" / "report"
    assert report.main([str(res), "--reps", "200", "--out", str(out)]) == 0
    assert sorted(p.name for p in res.iterdir()) == before  # nothing written beside the runs
    err = capsys.readouterr().err.splitlines()
    progress = [line for line in err if line.startswith("learned_report: [")]
    assert any("ElectroLoc-v0 (1 of 1)" in line for line in progress), err
    wrote = [Path(line.removeprefix("wrote: ")) for line in err if line.startswith("wrote: ")]
    assert {p.name for p in wrote} >= {"report.md", "report.json", "profile_ElectroLoc-v0.png"}
    assert all(p.parent == out and p.is_file() for p in wrote) and len(wrote) == len(list(out.iterdir()))


def test_out_is_checked_before_any_work(tmp_path, capsys):
    res = _results(tmp_path)
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(SystemExit) as exc:
        report.main([str(res), "--out", str(a_file)])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and "--out" in err[-1] and "is a file" in err[-1] and "Traceback" not in "\n".join(err)
    assert not any(line.startswith("learned_report: [") for line in err)  # refused before any work


def test_pairs_of_learned_configurations_are_compared(tmp_path, capsys):
    res = _results(tmp_path)
    for k in range(2):  # a2c needs more readings than every ppo run on both conditions
        _write(
            res / "ElectroLoc-v0" / "a2c" / f"seed-{k}" / "bench" / "trials.jsonl",
            "a2c",
            {"a": [20 + k] * 3, "b": [21] * 3},
        )
    assert report.main([str(res), "--reps", "200", "--compare", "ppo:a2c", "--compare", "a2c:sac"]) == 0
    text = (res / "report.md").read_text()
    assert "| ElectroLoc-v0 | ppo | a2c | 1.00 [1.00, 1.00] |" in text and "sac" not in text  # sac never ran
    (cmp,) = json.loads((res / "report.json").read_text())[0]["comparisons"]
    assert cmp["better"] == "ppo" and cmp["than"] == "a2c" and cmp["p"][0] == pytest.approx(1.0)
    with pytest.raises(SystemExit) as exc:
        report.main([str(res), "--compare", "ppo"])
    assert exc.value.code == 2 and "--compare takes A:B" in capsys.readouterr().err


def test_a_suite_still_running_reports_what_is_finished(tmp_path, capsys):
    res = _results(tmp_path)
    _write(res / "ElectroLoc-v0" / "ppo" / "seed-9" / "bench" / "trials.jsonl", "ppo", {"a": [1] * 3, "b": [1] * 3})
    (res / "ElectroLoc-v0" / "ppo" / "seed-9" / "bench" / "summary.json").unlink()  # its benchmark still running
    _write(res / GLOBAL_ID / "_baselines" / "bench" / "trials.jsonl", "rnd-wlk", {"g": [9] * 3}, GLOBAL_ID)
    assert report.main([str(res), "--reps", "200"]) == 0
    text = (res / "report.md").read_text()
    assert "| ElectroLoc-v0 | ppo | 3 |" in text and GLOBAL_ID not in text
    assert "ElectroLocGlobal-v0 left out: no learned runs" in capsys.readouterr().err


def test_bad_arguments_are_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        report.main([str(tmp_path / "missing")])
    assert exc.value.code == 2 and "does not exist" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        report.main([str(tmp_path), "--reps", "5"])
    with pytest.raises(SystemExit) as exc:
        report.main([str(tmp_path), "--seed", "-1"])
    assert exc.value.code == 2 and "--seed must be in [0, 2**32)" in capsys.readouterr().err


# ------------------------------------------------------------------ damaged results: set aside or one line
def _lines(res: Path) -> Path:
    return res / "ElectroLoc-v0" / "ppo" / "seed-0" / "bench" / "trials.jsonl"


def _damage_line(res: Path, key: str, value) -> None:
    path = _lines(res)
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    rows[0][key] = value
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))


def _clean_table(res: Path) -> dict:
    return scores.analyse(res, "ElectroLoc-v0", reps=SET_ASIDE_REPS)


@pytest.mark.parametrize(
    "key, value",
    [
        ("observations", 1000),
        ("observations", -5),
        ("observations", float("nan")),
        ("success", None),
        ("condition", "nowhere"),
        ("observations", "x"),
    ],
)
def test_an_impossible_record_is_set_aside_and_named(tmp_path, key, value):
    res = _results(tmp_path)
    _damage_line(res, key, value)
    a = scores.analyse(res, "ElectroLoc-v0", reps=SET_ASIDE_REPS)
    assert len(a["set_aside"]) == 1 and "seed-0" in a["set_aside"][0]


def test_a_seed_x_folder_and_copied_records_are_set_aside(tmp_path):
    res = _results(tmp_path)
    env = res / "ElectroLoc-v0" / "ppo"
    import shutil

    shutil.copytree(env / "seed-0", env / "seed-x")
    a = scores.analyse(res, "ElectroLoc-v0", reps=SET_ASIDE_REPS)
    assert any("seed-x" in m for m in a["set_aside"]) and a["seeds"]["ppo"] == ["seed-0", "seed-1", "seed-2"]
    res2 = _results(tmp_path / "two")
    other = res2 / "ElectroLoc-v0" / "sac" / "seed-0" / "bench" / "trials.jsonl"
    _write(other, "sac", {"a": [5] * 3, "b": [6] * 3})
    with open(other, "a") as fh:  # the ppo seed's records copied into the sac run
        fh.write(_lines(res2).read_text())
    a = scores.analyse(res2, "ElectroLoc-v0", reps=SET_ASIDE_REPS)
    assert sum("agent 'ppo' is not one of the run's" in m for m in a["set_aside"]) == 6


@pytest.mark.parametrize("damage", ["torn", "garbage", "utf8", "nested", "list", "missing-key"])
def test_a_damaged_line_is_set_aside(tmp_path, damage):
    res = _results(tmp_path)
    path = _lines(res)
    raw = path.read_bytes()
    extra = {
        "torn": raw[:40],
        "garbage": b"%%%\n",
        "utf8": b"\xff\xfe\n",
        "nested": b"[" * 50_000 + b"\n",
        "list": b"[1, 2]\n",
        "missing-key": json.dumps({"condition": "a"}).encode() + b"\n",
    }[damage]
    path.write_bytes(raw + extra)
    a = scores.analyse(res, "ElectroLoc-v0", reps=SET_ASIDE_REPS)
    assert len(a["set_aside"]) == 1
    np.testing.assert_array_equal(
        a["_matrices"]["readings"]["ppo"], _clean_table(_results(tmp_path / "c"))["_matrices"]["readings"]["ppo"]
    )


def _edit_json(path: Path, edit) -> None:
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))


#: (damage, the file the one line names): a results file the report cannot read, each through its own reader —
#: the records, the evaluation log, a training run's summary.json (``read_summary``) and a benchmark's
#: config.json (``config_from_json``).
DAMAGED_FILES = [
    ("none", None),  # the folder undamaged: the report is written
    ("empty", "trials.jsonl"),
    ("missing", "trials.jsonl"),
    ("eval-nan", "eval.csv"),
    ("summary-garbage", "summary.json"),
    ("summary-list", "summary.json"),
    ("summary-utf8", "summary.json"),
    ("summary-missing-field", "summary.json"),
    ("summary-negative-wall-time", "summary.json"),
    ("summary-wall-time-text", "summary.json"),
    ("config-garbage", "config.json"),
    ("config-utf8", "config.json"),
    ("config-nested", "config.json"),
    ("config-list", "config.json"),
    ("config-missing-key", "config.json"),
    ("config-trials-text", "config.json"),
    ("config-no-trials", "config.json"),
    ("config-unknown-env", "config.json"),
    ("config-unknown-condition", "config.json"),
    ("config-no-agents", "config.json"),
]


@pytest.mark.parametrize("damage, named", DAMAGED_FILES, ids=[d for d, _ in DAMAGED_FILES])
def test_a_damaged_file_is_one_line(tmp_path, damage, named, capsys, train_summary_json):
    res = _results(tmp_path)
    base = res / "ElectroLoc-v0" / "_baselines" / "bench" / "trials.jsonl"
    config = base.parent / "config.json"
    zoo = res / "ElectroLoc-v0" / "ppo" / "seed-0" / "zoo" / "ppo" / "ElectroLoc-v0_1"
    zoo.mkdir(parents=True)
    head = "timesteps,wall_time_s,episodes,success_rate,mean_readings,median_readings,median_error_mm,mean_error_mm"
    (zoo / "eval.csv").write_text(f"{head}\n100,12.5,2,0.5,9.0,9.0,2,2\n")
    summary = zoo / "summary.json"
    train_summary_json(summary, "ElectroLoc-v0", {"episodes": 2, "first_seed": 100000, "env_kwargs": {}})
    (zoo / "ElectroLoc-v0").mkdir()
    (zoo / "ElectroLoc-v0" / "config.yml").write_text("env_kwargs: {condition: random}\n")
    damages = {
        "none": lambda: None,
        "empty": lambda: base.write_text(""),
        "missing": base.unlink,
        "eval-nan": lambda: (zoo / "eval.csv").write_text(f"{head}\n100,12.5,2,nan,9.0,9.0,2,2\n"),
        "summary-garbage": lambda: summary.write_text("[[[garbage"),
        "summary-list": lambda: summary.write_text("[1, 2]"),
        "summary-utf8": lambda: summary.write_bytes(b"\xff\xfe"),
        "summary-missing-field": lambda: _edit_json(summary, lambda d: d.pop("wall_time_s")),
        "summary-negative-wall-time": lambda: _edit_json(summary, lambda d: d.update(wall_time_s=-1.0)),
        "summary-wall-time-text": lambda: _edit_json(summary, lambda d: d.update(wall_time_s="12 s")),
        "config-garbage": lambda: config.write_text("[[[garbage"),
        "config-utf8": lambda: config.write_bytes(b"\xff\xfe"),
        "config-nested": lambda: config.write_text("[" * 50_000),
        "config-list": lambda: config.write_text("[1, 2]"),
        "config-missing-key": lambda: _edit_json(config, lambda d: d.pop("seed")),
        "config-trials-text": lambda: _edit_json(config, lambda d: d.update(trials="3")),
        "config-no-trials": lambda: _edit_json(config, lambda d: d.update(trials=0)),
        "config-unknown-env": lambda: _edit_json(config, lambda d: d.update(env_id="Nope-v0")),
        "config-unknown-condition": lambda: _edit_json(config, lambda d: d.update(conditions=["nowhere"])),
        "config-no-agents": lambda: _edit_json(config, lambda d: d.update(agents=[])),
    }
    damages[damage]()
    assert report.main([str(res), "--reps", "100"]) == (0 if named is None else 2)  # the fewest it takes
    err = [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith("learned_report: [")]
    if named is None:
        assert not [line for line in err if "error" in line], err
        return
    assert len(err) == 1 and err[0].startswith("learned_report: error:") and "Traceback" not in err[0], err
    assert named in err[0], err


def test_reps_are_bounded(tmp_path, capsys):
    with pytest.raises(SystemExit):
        report.main([str(_results(tmp_path)), "--reps", "10000000000"])
    assert "--reps must be in [100," in capsys.readouterr().err


_VALUES = [None, True, -5, 0, 1000, 1e300, "x", "", [], {}, [[]], 3.5]


def test_any_single_field_damage_gives_the_clean_report_or_names_what_it_set_aside(tmp_path):
    """Hypothesis: one field of one record replaced; the scores equal the clean ones, or one record is
    set aside and named (and the others scored as before).
    """
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as hs

    clean = _clean_table(_results(tmp_path / "clean"))

    @settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
    @given(hs.sampled_from(sorted(TEMPLATE)), hs.sampled_from(_VALUES), hs.integers(0, 1))
    def check(key, value, which):
        import shutil

        d = tmp_path / "case"
        if d.exists():
            shutil.rmtree(d)
        res = _results(d)
        path = _lines(res)
        rows = [json.loads(x) for x in path.read_text().splitlines()]
        rows[which][key] = value
        path.write_text("".join(json.dumps(r) + "\n" for r in rows))
        try:
            a = scores.analyse(res, "ElectroLoc-v0", reps=SET_ASIDE_REPS)
        except ValueError as exc:  # a condition left without trials: one line
            assert "\n" not in str(exc)
            return
        if a["set_aside"]:
            assert len(a["set_aside"]) == 1 and str(path) in a["set_aside"][0]
        else:
            np.testing.assert_array_equal(a["_matrices"]["readings"]["ppo"], clean["_matrices"]["readings"]["ppo"])

    check()


# ------------------------------------------------------------------ a tracking env: tracking error and capture
TRACK_ID = task_entry("track").env_id
TRACK_CAP = 70  # every moving-target trial runs to its 70 readings


def _track_record(cond: str, agent: str, trial: int, err: float, captured: bool) -> dict:
    """A schema-valid moving-target record: run to the cap, its tracking error ``err`` mm and capture."""
    rec = {**TEMPLATE, "condition": NAMES[cond], "agent": agent, "trial": trial, "env_id": TRACK_ID}
    rec.pop("far_success", None)
    rec.update(
        success=False,
        ended_by="cap",
        observations=TRACK_CAP,
        max_observations=TRACK_CAP,
        decisions=TRACK_CAP - 1,
        spread_mm=5.0,
        shape={"tracking_error_mm": err, "carriage_distance_mm": 5.0 if captured else 30.0, "captured": captured},
    )
    return rec


def _write_track(path: Path, agent: str, trials: dict[str, list[tuple[float, bool]]]) -> None:
    rows = [_track_record(cond, agent, t, e, c) for cond, ts in trials.items() for t, (e, c) in enumerate(ts)]
    _append_run(path, agent, rows, list(trials), TRACK_ID)
    (path.parent / "summary.json").write_text("{}")


def _same(err: float, captured: bool = True) -> list[tuple[float, bool]]:
    return [(err, captured)] * 3


def _track_results(tmp_path: Path) -> Path:
    """Two conditions × three trials; rnd-wlk, min-var and pursuit; ppo and ppo-framestack-raw, two seeds."""
    env = tmp_path / TRACK_ID
    base = env / "_baselines" / "bench" / "trials.jsonl"
    _write_track(base, "rnd-wlk", {"a": [(30.0, False), (40.0, False), (50.0, True)], "b": _same(20.0, False)})
    _write_track(base, "min-var", {"a": _same(10.0), "b": [(12.0, True), (12.0, False), (12.0, False)]})
    _write_track(base, "pursuit", {"a": _same(8.0), "b": _same(15.0)})
    for k in range(2):
        _write_track(
            env / "ppo" / f"seed-{k}" / "bench" / "trials.jsonl", "ppo", {"a": _same(4.0 + k), "b": _same(6.0 + k)}
        )
        _write_track(
            env / "ppo-framestack-raw" / f"seed-{k}" / "bench" / "trials.jsonl",
            "ppo-framestack-raw",
            {"a": _same(9.0), "b": [(13.0, True), (13.0, False), (13.0, False)]},
        )
    return tmp_path


def _track_lines(res: Path) -> Path:
    return res / TRACK_ID / "ppo" / "seed-0" / "bench" / "trials.jsonl"


def test_a_tracking_env_is_scored_by_tracking_error_and_capture(tmp_path):
    conds, learned, baselines, seeds = scores.collect(_track_results(tmp_path), TRACK_ID)
    assert conds == list(CONDS) and seeds["ppo"] == ["seed-0", "seed-1"]
    np.testing.assert_allclose(baselines["rnd-wlk"]["tracking_error"][0], [40, 20])
    np.testing.assert_allclose(baselines["rnd-wlk"]["capture"][0], [1 / 3, 0])
    np.testing.assert_allclose(learned["ppo"]["tracking_error"], [[4, 6], [5, 7]])
    np.testing.assert_allclose(learned["ppo-framestack-raw"]["capture"], [[1, 1 / 3], [1, 1 / 3]])
    # 0 at rnd-wlk, 1 at the best non-learned controller per condition (pursuit on a: 8 mm, min-var on b: 12 mm)
    np.testing.assert_allclose(
        scores.normalised(baselines["rnd-wlk"]["tracking_error"], baselines, "tracking_error"), 0
    )
    np.testing.assert_allclose(
        scores.normalised(baselines["min-var"]["tracking_error"], baselines, "tracking_error"), [[30 / 32, 1]]
    )
    np.testing.assert_allclose(
        scores.normalised(learned["ppo"]["tracking_error"], baselines, "tracking_error"),
        [[36 / 32, 14 / 8], [35 / 32, 13 / 8]],
    )


def test_a_tracking_env_analysis(tmp_path):
    a = scores.analyse(_track_results(tmp_path), TRACK_ID, reps=200)
    assert a["metric"] == "tracking_error_mm" and a["set_aside"] == []
    row = a["algorithms"]["ppo"]
    assert "readings_iqm" not in row and "readings_mean" not in a["baselines"]["rnd-wlk"]
    for key in ("tracking_error_iqm", "tracking_error_mean", "capture_mean", "normalised_iqm"):
        point, lo, hi = row[key]
        assert lo <= point <= hi
    assert row["tracking_error_mean"][0] == pytest.approx(5.5) and row["tracking_error_iqm"][0] == pytest.approx(5.5)
    assert row["capture_mean"][0] == pytest.approx(1.0)
    assert a["algorithms"]["ppo-framestack-raw"]["capture_mean"][0] == pytest.approx(2 / 3)
    assert row["p_improvement"]["min-var"][0] == pytest.approx(1.0)  # a lower error than min-var everywhere
    assert a["algorithms"]["ppo-framestack-raw"]["p_improvement"]["min-var"][0] == pytest.approx(0.5)  # 9 < 10, 13 > 12
    assert "lookahead" not in row["p_improvement"]
    assert a["baselines"]["min-var"]["tracking_error_mean"] == pytest.approx(11.0)
    assert a["baselines"]["pursuit"]["normalised_mean"] == pytest.approx((1 + 5 / 8) / 2)
    (cmp,) = a["comparisons"]  # the default pair on a tracking env: the belief against stacked raw readings
    assert (cmp["better"], cmp["than"]) == ("ppo", "ppo-framestack-raw") and cmp["p"][0] == pytest.approx(1.0)


def test_main_reports_a_tracking_env_in_its_own_table(tmp_path):
    res = _track_results(_results(tmp_path))  # ElectroLoc-v0 and the tracking env in one folder
    zoo = res / TRACK_ID / "ppo" / "seed-0" / "zoo" / "ppo" / f"{TRACK_ID}_1"
    zoo.mkdir(parents=True)
    (zoo / "eval.csv").write_text(
        "timesteps,success_rate,mean_readings,median_readings,mean_error_mm,mean_return\n"
        "0,0.1,70,70,30.0,-170.5\n100,0.9,70,70,4.0,-30.25\n"
    )
    assert report.main([str(res), "--reps", "200"]) == 0
    text = (res / "report.md").read_text()
    main, _, rest = text.partition("Tracking envs")
    assert "| ElectroLoc-v0 | ppo | 3 |" in main and TRACK_ID not in main.split("\n\n")[0]
    assert f"| {TRACK_ID} | ppo | 2 | 5.50 [" in rest
    assert f"| {TRACK_ID} | rnd-wlk (not learned) | 1 | – | 30.00 | 0.17 | 0.00 | – |" in rest
    assert "P(lower error than min-var) [CI]" in rest and "lookahead" not in rest.split("\n\n")[1]
    assert f"| {TRACK_ID} | ppo | ppo-framestack-raw | 1.00 [1.00, 1.00] |" in rest
    assert "| ppo (2 seeds) | 4.50 (4.0–5.0) | 6.50 (6.0–7.0) |" in rest  # tracking error per condition, mm
    assert "| ppo-framestack-raw (2 seeds) | 1.00 (1.00–1.00) | 0.33 (0.33–0.33) |" in rest  # capture
    assert "| rnd-wlk | 40.00 | 20.00 |" in rest and "| rnd-wlk | 0.33 | 0.00 |" in rest
    analyses = {a["env_id"]: a for a in json.loads((res / "report.json").read_text())}
    assert analyses[TRACK_ID]["metric"] == "tracking_error_mm" and "metric" not in analyses[TARGET_ID]
    assert (res / f"profile_{TRACK_ID}.png").stat().st_size > 0
    assert (res / f"curves_{TRACK_ID}.png").stat().st_size > 0  # the validation return, not the readings
    (zoo / "eval.csv").write_text("timesteps,success_rate,mean_readings,median_readings\n0,0.1,70,70\n")
    assert report.main([str(res), "--reps", "200"]) == 2  # a tracking env's curves need the return: one line


@pytest.mark.parametrize(
    "key, value",
    [
        ("shape", None),
        ("shape", {"tracking_error_mm": -1.0, "carriage_distance_mm": 5.0, "captured": True}),
        ("shape", {"tracking_error_mm": float("nan"), "carriage_distance_mm": 5.0, "captured": True}),
        ("shape", {"tracking_error_mm": "x", "carriage_distance_mm": 5.0, "captured": True}),
        ("shape", {"tracking_error_mm": 4.0, "carriage_distance_mm": 5.0, "captured": "yes"}),
        ("shape", {"tracking_error_mm": 4.0, "captured": True}),
        ("ended_by", "success"),
        ("condition", "nowhere"),
    ],
)
def test_an_impossible_tracking_record_is_set_aside_and_named(tmp_path, key, value):
    res = _track_results(tmp_path)
    path = _track_lines(res)
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    rows[0][key] = value
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    a = scores.analyse(res, TRACK_ID, reps=SET_ASIDE_REPS)
    assert len(a["set_aside"]) == 1 and "seed-0" in a["set_aside"][0]
    np.testing.assert_allclose(a["_matrices"]["tracking_error"]["ppo"], [[4, 6], [5, 7]])  # the other trials: 4 mm


def test_another_tasks_results_in_a_tracking_run_are_set_aside(tmp_path):
    """The schema takes the unknown target's identification as a record's ``shape`` too; a tracking env's
    report keeps only records carrying its own results.
    """
    res = _track_results(tmp_path)
    path = _track_lines(res)
    rows = [json.loads(x) for x in path.read_text().splitlines()]
    rows[1]["shape"] = {
        "radius_estimate_mm": 6.0,
        "radius_mean_mm": 6.0,
        "radius_spread_mm": 1.0,
        "target_radius_mm": 6.35,
        "radius_error_frac": 0.05,
        "p_conductor": 0.9,
        "material_estimate": "conductor",
        "material_correct": True,
        "chi_estimate": 0.9,
        "target_chi": 1.0,
    }
    rows[1]["spread_mm"] = 20.0  # not tight: a consistent failure to the schema
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    a = scores.analyse(res, TRACK_ID, reps=SET_ASIDE_REPS)
    assert len(a["set_aside"]) == 1 and "'shape' must be the task's results" in a["set_aside"][0]
    np.testing.assert_allclose(a["_matrices"]["tracking_error"]["ppo"], [[4, 6], [5, 7]])


@pytest.mark.parametrize("damage", ["torn", "garbage", "missing-key"])
def test_a_damaged_tracking_line_is_set_aside(tmp_path, damage):
    res = _track_results(tmp_path)
    path = _track_lines(res)
    raw = path.read_bytes()
    path.write_bytes(raw + {"torn": raw[:40], "garbage": b"%%%\n", "missing-key": b'{"condition": "a"}\n'}[damage])
    a = scores.analyse(res, TRACK_ID, reps=SET_ASIDE_REPS)
    assert len(a["set_aside"]) == 1
    np.testing.assert_allclose(a["_matrices"]["tracking_error"]["ppo"], [[4, 6], [5, 7]])


def test_the_report_says_when_each_run_reached_min_vars_validation_level(tmp_path, capsys, train_summary_json):
    """Env steps and wall time to min-var's level on the validation episodes (eval.csv against min-var's cached
    evaluation on the same episodes); "not within the budget" where a run never reached it; computed only with
    --min-var-level when not cached."""
    res = _results(tmp_path)
    head = "timesteps,wall_time_s,episodes,success_rate,mean_readings,median_readings,median_error_mm,mean_error_mm"
    for k, readings in enumerate(([30, 11, 9, 8], [30, 20, 11, 10], [30, 25, 20, 15])):
        run = res / "ElectroLoc-v0" / "ppo" / f"seed-{k}" / "zoo" / "ppo" / "ElectroLoc-v0_1"
        (run / "ElectroLoc-v0").mkdir(parents=True)
        rows = [f"{i * 500},{12.5 * i},2,1,{r},{r},2,2" for i, r in enumerate(readings)]
        (run / "eval.csv").write_text("\n".join([head, *rows]) + "\n")
        validation = {"episodes": 2, "first_seed": 100000, "env_kwargs": {"randomize_target": False}}
        train_summary_json(run / "summary.json", "ElectroLoc-v0", validation)
        (run / "ElectroLoc-v0" / "config.yml").write_text("env_kwargs: {condition: random, randomize_target: true}\n")
    assert report.main([str(res), "--reps", "200"]) == 0
    text = (res / "report.md").read_text()
    assert "seed 0: min-var's level not computed (--min-var-level)" in text
    cache = res / "ElectroLoc-v0" / "_baselines" / "validation" / "min-var.json"
    entry = {"env_id": "ElectroLoc-v0", "env_kwargs": {"condition": "random", "randomize_target": False}}
    cache.parent.mkdir(parents=True)
    cache.write_text(json.dumps([{**entry, "first_seed": 100000, "episodes": 2, "row": {"mean_readings": 11.0}}]))
    assert report.main([str(res), "--reps", "200", "--min-var-level"]) == 0
    text = (res / "report.md").read_text()
    assert "| ElectroLoc-v0 | ppo | mean_readings 11 | 2 of 3 |" in text
    assert "seed 0: 500; seed 1: 1 000; seed 2: not within the budget (1 500)" in text
    assert "seed 0: 12; seed 1: 25; seed 2: not within the budget" in text
    level = json.loads((res / "report.json").read_text())[0]["min_var_level"]
    assert [s["timesteps"] for s in level[0]["seeds"]] == [500, 1000, None]
