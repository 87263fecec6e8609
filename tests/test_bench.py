"""Benchmark runner: seeds, worker-count independence, resume, Appendix-B statistics, files, CLI errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from tiny_bench_run import TINY  # the tiny run the reliability tests use too

from electroloc_gym.bench.backends import BACKENDS, Backend, SerialBackend, make_backend, register_backend
from electroloc_gym.bench.config import BenchConfig, make_trial_specs, resolve_conditions, trial_seeds
from electroloc_gym.bench.records import read_trials
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.bench.schema import TIMING_KEYS
from electroloc_gym.bench.stats import summarize
from electroloc_gym.bench.tables import PAPER_TABLE4, PAPER_TABLE4_ALL, render_table_md
from electroloc_gym.cli import main as cli_main
from electroloc_gym.world.conditions import PRESET_NAMES

SUMMARY_KEYS = {
    "condition",
    "agent",
    "trials",
    "successes",
    "failures",
    "error_mean_mm",
    "error_median_mm",
    "readings_mean",
    "readings_median",
    "decision_ms_median",
}


def _strip(records):
    return sorted(tuple(sorted((k, json.dumps(v)) for k, v in r.items() if k not in TIMING_KEYS)) for r in records)


# ---- seeds ------------------------------------------------------------------------------------------
def test_trial_seeds_are_spawned_per_condition_and_trial() -> None:
    a = trial_seeds(0, "fresh-steel-12.7", 3)
    assert a == trial_seeds(0, "fresh-steel-12.7", 3)
    assert a != trial_seeds(0, "fresh-steel-12.7", 4)
    assert a != trial_seeds(0, "fresh-delrin-12.7", 3)
    assert a != trial_seeds(1, "fresh-steel-12.7", 3)
    # exactly SeedSequence(seed).spawn(...)[condition].spawn(...)[trial]
    child = np.random.SeedSequence(0).spawn(8)[0].spawn(5)[3]
    assert a == tuple(int(v) for v in child.generate_state(2, dtype=np.uint32))


def test_every_agent_in_a_condition_gets_the_same_seeds() -> None:
    specs = make_trial_specs(BenchConfig(agents=("rnd-wlk", "min-var"), **TINY))
    by = {}
    for s in specs:
        by.setdefault((s.condition, s.trial), set()).add((s.env_seed, s.agent_seed))
    assert all(len(v) == 1 for v in by.values())
    assert len(specs) == 2 * 2 * 2


# ---- validation ---------------------------------------------------------------------------------------
def test_resolve_conditions() -> None:
    assert resolve_conditions("all") == list(PRESET_NAMES)
    assert resolve_conditions("salt-steel-38.1, fresh-steel-12.7") == ["salt-steel-38.1", "fresh-steel-12.7"]
    with pytest.raises(ValueError, match="unknown condition"):
        resolve_conditions("fresh-steel-12.7,bogus")
    with pytest.raises(ValueError, match="distinct"):
        resolve_conditions("fresh-steel-12.7,fresh-steel-12.7")
    with pytest.raises(ValueError, match="conditions must be"):
        resolve_conditions("")


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"trials": 0}, "trials"),
        ({"sensor_model": "exact"}, "sensor_model"),
        ({"signal": "x"}, "signal"),
        ({"agents": ()}, "at least one"),
        ({"agents": ("rnd-wlk", "rnd-wlk")}, "distinct"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bench_config_rejects_bad_values(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        BenchConfig(**kwargs)


def test_bad_agents_fail_before_running(tmp_path) -> None:
    with pytest.raises(ValueError, match="unknown agent 'nope'"):
        run_benchmark(
            BenchConfig(agents=("rnd-wlk", "nope"), **TINY), tmp_path, backend="serial", progress=False, log=None
        )
    with pytest.raises(ValueError, match="missing.zip"):
        run_benchmark(
            BenchConfig(agents=(str(tmp_path / "missing.zip"),), **TINY),
            tmp_path,
            backend="serial",
            progress=False,
            log=None,
        )
    assert not (tmp_path / "trials.jsonl").exists()


def test_cli_reports_bad_input(tmp_path, capsys) -> None:
    assert cli_main(["bench", "--agents", "nope", "--out", str(tmp_path), "--no-progress"]) == 2
    assert "unknown agent 'nope'" in capsys.readouterr().err
    assert cli_main(["bench", "--conditions", "fresh-steel-12.7,bogus", "--out", str(tmp_path)]) == 2
    assert "unknown condition" in capsys.readouterr().err
    assert cli_main(["bench", "--agents", str(tmp_path / "x.zip"), "--out", str(tmp_path)]) == 2
    assert "x.zip" in capsys.readouterr().err


def test_backend_registry() -> None:
    assert {"process", "serial"} <= set(BACKENDS)
    with pytest.raises(ValueError, match="backend must be one of"):
        make_backend("nowhere")
    with pytest.raises(ValueError, match="workers"):
        make_backend("serial", workers=0)

    class Reversed(Backend):
        name = "reversed-test"

        def run_trials(self, specs, worker_fn):
            yield from SerialBackend().run_trials(list(reversed(specs)), worker_fn)

    register_backend(Reversed)
    try:
        out = list(make_backend("reversed-test").run_trials([1, 2, 3], lambda s: s * 10))
        assert out == [(3, 30), (2, 20), (1, 10)]
    finally:
        BACKENDS.pop("reversed-test")


# ---- runs -------------------------------------------------------------------------------------------
AGENTS = ("rnd-wlk", "min-var[n_voters=16]", "zero-crossing[max_observations=60]")


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    cfg = BenchConfig(agents=AGENTS, **TINY)
    summary = run_benchmark(cfg, out, backend="serial", progress=False, log=None)
    return cfg, out, summary


def test_run_writes_all_files(serial_run) -> None:
    cfg, out, summary = serial_run
    records = read_trials(out / "trials.jsonl")
    assert len(records) == len(cfg.agents) * len(cfg.conditions) * cfg.trials
    for r in records:
        assert {
            "condition",
            "agent",
            "trial",
            "seed",
            "success",
            "readings",
            "error_mm",
            "estimate",
            "start",
            "decision_ms_median",
        } <= r.keys()
        assert 1 <= r["readings"]
    data = json.loads((out / "summary.json").read_text())  # strict JSON: no NaN
    rows = data["rows"]
    assert all(SUMMARY_KEYS <= r.keys() for r in rows)
    assert {r["condition"] for r in rows} == {*cfg.conditions, "all"}
    assert {r["agent"] for r in rows} == set(cfg.agents)
    table = (out / "table.md").read_text()
    assert "Table 4 layout" in table and "Table 1 layout" in table and "Appendix B" in table
    assert (out / "steps.png").stat().st_size > 1000 and (out / "conditions.png").stat().st_size > 1000
    assert json.loads((out / "config.json").read_text())["seed"] == cfg.seed


def test_results_do_not_depend_on_workers(serial_run, tmp_path) -> None:
    cfg, out, _ = serial_run
    run_benchmark(cfg, tmp_path, backend="process", workers=2, progress=False, log=None)
    assert _strip(read_trials(tmp_path / "trials.jsonl")) == _strip(read_trials(out / "trials.jsonl"))


def test_same_start_for_every_agent(serial_run) -> None:
    _, out, _ = serial_run
    recs = read_trials(out / "trials.jsonl")
    by = {}
    for r in recs:
        if r["table_layout"] == "table4":
            by.setdefault((r["condition"], r["trial"]), set()).add(tuple(r["start"]))
    assert by and all(len(v) == 1 for v in by.values())


def test_resume_skips_finished_and_survives_a_torn_line(serial_run, tmp_path) -> None:
    cfg, out, _ = serial_run
    ref = read_trials(out / "trials.jsonl")
    # A run "killed" after 5 trials, in the middle of writing the 6th line.
    lines = (out / "trials.jsonl").read_text().splitlines(keepends=True)
    (tmp_path / "trials.jsonl").write_text("".join(lines[:5]) + lines[5][: len(lines[5]) // 2])
    (tmp_path / "config.json").write_text((out / "config.json").read_text())
    with pytest.raises(ValueError, match="resume"):
        run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    summary = run_benchmark(cfg, tmp_path, backend="serial", resume=True, progress=False, log=None)
    assert summary["trials_run_this_time"] == len(ref) - 5
    assert _strip(read_trials(tmp_path / "trials.jsonl")) == _strip(ref)
    # Nothing left to do: a second resume runs nothing.
    again = run_benchmark(cfg, tmp_path, backend="serial", resume=True, progress=False, log=None)
    assert again["trials_run_this_time"] == 0


def test_resume_refuses_different_settings(serial_run, tmp_path) -> None:
    cfg, out, _ = serial_run
    (tmp_path / "trials.jsonl").write_text((out / "trials.jsonl").read_text())
    (tmp_path / "config.json").write_text((out / "config.json").read_text())
    other = BenchConfig(agents=cfg.agents, **{**TINY, "seed": 99})
    with pytest.raises(ValueError, match="settings differ"):
        run_benchmark(other, tmp_path, backend="serial", resume=True, progress=False, log=None)


# ---- Appendix B statistics -------------------------------------------------------------------------
def _rec(cond, agent, trial, success, steps, err, table_layout="table4"):
    return {
        "condition": cond,
        "agent": agent,
        "trial": trial,
        "success": success,
        "readings": steps,
        "error_mm": err,
        "error_x_mm": err,
        "error_y_mm": 0.0,
        "estimate": [err, 0.0],
        "table_layout": table_layout,
        "decision_ms_median": 1.0,
    }


def test_appendix_b_rules() -> None:
    recs = [
        _rec("c1", "a", 0, True, 5, 1.0),
        _rec("c1", "b", 0, True, 7, 3.0),
        _rec("c1", "a", 1, True, 9, 2.0),
        _rec("c1", "b", 1, False, 35, 20.0),
        _rec("c1", "a", 2, False, 35, 30.0),
        _rec("c1", "b", 2, True, 4, 5.0),
        _rec("c2", "a", 0, True, 10, 4.0),
        _rec("c2", "b", 0, True, 2, 1.0),
    ]
    s = summarize(recs, agents=["a", "b"], conditions=["c1", "c2"])
    row = {(r["condition"], r["agent"]): r for r in s["rows"]}
    a1 = row[("c1", "a")]
    assert (a1["successes"], a1["failures"]) == (2, 1)
    assert a1["paired_trials"] == 1  # only trial 0: both succeeded
    assert a1["error_mean_paired_mm"] == 1.0 and a1["readings_mean_paired"] == 5
    assert a1["error_mean_mm"] == 1.5 and a1["readings_mean"] == 7  # own successes
    assert a1["readings_median"] == 9 and a1["error_median_mm"] == 2.0  # all trials, failures included
    all_a = row[("all", "a")]
    assert all_a["successes"] == 3 and all_a["failures"] == 1
    assert all_a["readings_median"] == (9 + 10) / 2  # average of per-condition medians
    assert all_a["readings_median_pooled"] == 9.5
    assert math.isclose(all_a["error_mean_paired_mm"], (1.0 + 4.0) / 2)


def test_paper_all_conditions_row_is_average_of_rows() -> None:
    for agent in ("rnd-wlk", "min-var"):
        med = [v[5] for (c, a), v in PAPER_TABLE4.items() if a == agent]
        assert round(sum(med) / len(med), 1) == PAPER_TABLE4_ALL[agent][5]
        assert sum(v[0] for (c, a), v in PAPER_TABLE4.items() if a == agent) == PAPER_TABLE4_ALL[agent][0]


def test_table_renders_paper_numbers() -> None:
    recs = [
        _rec("fresh-steel-12.7", "min-var", 0, True, 5, 1.0),
        _rec("fresh-steel-12.7", "zero-crossing", 0, True, 300, 0.1, table_layout="table1"),
    ]
    text = render_table_md(summarize(recs))
    assert "50(0)" in text and "1.7/1.1" in text  # Table 4, fresh 12.7/S, min-var
    assert "0.39" in text  # Table 1, fresh 12.7/S, y


# ---- the statistical reproduction (slow) ------------------------------------------------------------
@pytest.mark.slow
def test_statistical_zero_crossing_is_submillimetre(tmp_path) -> None:
    cfg = BenchConfig(agents=("zero-crossing",), conditions=("fresh-steel-12.7", "salt-delrin-38.1"), trials=25, seed=0)
    summary = run_benchmark(cfg, tmp_path, progress=False, log=None)
    for r in summary["rows"]:
        assert r["failures"] == 0
        assert r["error_x_mean_abs_mm"] < 1.0 and r["error_y_mean_abs_mm"] < 1.0


@pytest.mark.slow
def test_statistical_min_var_beats_rnd_wlk_with_analytic_model(tmp_path) -> None:
    # With a noise-free (analytic) sensor model, min-var's particle vote does what the paper reports on
    # the large spheres: fewer failures and fewer steps than rnd-wlk (fixed seeds). These two conditions
    # were picked from a 20-trial analytic run over all eight, where min-var won on
    # 3-4 of 8 and lost clearly on salt-steel-12.7: this is an existence check, not a claim for all.
    cfg = BenchConfig(
        agents=("rnd-wlk", "min-var"),
        conditions=("fresh-delrin-38.1", "salt-steel-38.1"),
        trials=30,
        seed=0,
        sensor_model="analytic",
    )
    summary = run_benchmark(cfg, tmp_path, progress=False, log=None)
    row = {(r["condition"], r["agent"]): r for r in summary["rows"]}
    for c in cfg.conditions:
        assert row[(c, "min-var")]["failures"] < row[(c, "rnd-wlk")]["failures"]
        assert row[(c, "min-var")]["readings_median"] < row[(c, "rnd-wlk")]["readings_median"]


# The paper's claim (Table 4, Fig. 12): min-var fails less and needs fewer readings than rnd-wlk. With
# Algorithm 1's resample per vote and the pooled calibration over every offset (the default simulation)
# it holds over the eight conditions together (docs/fidelity.md: seed 0, 50 trials: 24 against 70
# failures, 12.5 against 15.9 median readings), though not in every condition (the two salt-water
# 12.7 mm conditions, with the smallest detection regions, go to rnd-wlk). Checked here on a seed other
# than the benchmark's.
@pytest.mark.slow
def test_statistical_min_var_beats_rnd_wlk(tmp_path) -> None:
    cfg = BenchConfig(agents=("rnd-wlk", "min-var"), conditions=PRESET_NAMES, trials=20, seed=3)
    summary = run_benchmark(cfg, tmp_path, progress=False, log=None)
    row = {(r["condition"], r["agent"]): r for r in summary["rows"]}
    mv, rw = row[("all", "min-var")], row[("all", "rnd-wlk")]
    assert mv["failures"] < rw["failures"]
    assert mv["readings_median"] < rw["readings_median"]
    assert mv["successes"] >= 0.9 * 20 * len(PRESET_NAMES)


# ---- tables: the paper's totals only beside all eight conditions ----------------------------------------------
def _eight_condition_records(conditions):
    return [
        _rec(c, a, k, k != 2, 5 + k, 1.0 + k) for c in conditions for a in ("rnd-wlk", "min-var") for k in range(3)
    ] + [_rec(c, "zero-crossing", 0, True, 300, 0.2, table_layout="table1") for c in conditions]


def test_all_conditions_row_only_over_the_papers_eight() -> None:
    full = render_table_md(summarize(_eight_condition_records(PRESET_NAMES)))
    assert "| All conditions |  | rnd-wlk | 16(8) |" in full and "287(113)" in full and "381(19)" in full
    assert "All conditions (average)" in full and "Subset" not in full
    two = PRESET_NAMES[:2]
    subset = render_table_md(summarize(_eight_condition_records(two)))
    assert "All conditions |" not in subset and "All conditions (average)" not in subset
    assert "| Subset (2 conditions) |  | rnd-wlk | 4(2) | " in subset
    assert "287(113)" not in subset and "381(19)" not in subset
    sub_row = [ln for ln in subset.splitlines() if ln.startswith("| Subset (2 conditions) |  | min-var")][0]
    assert sub_row.endswith("|  |  |  |")  # no paper cells
    t1 = [ln for ln in subset.splitlines() if ln.startswith("| Subset (2 conditions) (average) | zero-crossing")][0]
    assert t1.endswith("|  |  |")


def test_cli_subset_run_prints_no_paper_totals(serial_run) -> None:
    _, out, _ = serial_run
    table = (out / "table.md").read_text()
    assert "Subset (2 conditions)" in table and "All conditions |" not in table and "287(113)" not in table


# ---- progress --------------------------------------------------------------------------------------------------
def test_eta_is_measured_after_every_worker_warmed_up() -> None:
    from electroloc_gym.bench.progress import eta_s

    # 4 workers, 100 trials: start-up takes 60 s, then a trial every 0.5 s (2 trials/s).
    times = [60.0, 60.1, 60.2, 60.3] + [60.3 + 0.5 * i for i in range(1, 11)]
    assert eta_s(times[:4], 100, warm=4) is None  # only warm-up results so far
    eta = eta_s(times, 100, warm=4)
    assert eta == pytest.approx((100 - 14) * 0.5)  # 43 s, not (100 - 14) × 65 s / 14
    assert eta_s([1.0], 1, warm=4) is None


def test_progress_bar_names_the_agent(tmp_path) -> None:
    import os
    import subprocess
    import sys

    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
    model = tmp_path / "runs" / "my-policy"  # a learned policy by path: the bar shows its folder's name
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "electroloc_gym.cli",
            "bench",
            "--agents",
            "rnd-wlk",
            "--conditions",
            "fresh-steel-12.7",
            "--trials",
            "3",
            "--n-particles",
            "100",
            "--sensor-model",
            "analytic",
            "--max-observations",
            "4",
            "--workers",
            "1",
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "ETA after warm-up" in proc.stderr and "last: rnd-wlk on fresh-steel-12.7" in proc.stderr
    assert "agents: rnd-wlk" in proc.stdout
    from electroloc_gym.bench.agents import agent_display_name

    assert agent_display_name(str(model)) == "my-policy"
