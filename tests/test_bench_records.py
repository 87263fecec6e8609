"""Records a damaged or crafted trials.jsonl cannot change: bounded parsing, the schema, the run's rules."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.records import REJECTED_FILE, load_records
from electroloc_gym.bench.runner import OUTPUT_FILES, record_rules, run_benchmark
from electroloc_gym.bench.schema import RECORD_KEYS, TIMING_KEYS, TrialRecord
from electroloc_gym.cli import main as cli_main

TARGET = dict(
    agents=("rnd-wlk", "zero-crossing[max_observations=60]"),
    conditions=("fresh-steel-12.7",),
    trials=3,
    seed=5,
    n_particles=300,
    max_observations=6,
    sensor_model="analytic",
)
UNKNOWN = dict(
    agents=("rnd-wlk",),
    conditions=("fresh-steel-12.7",),
    trials=2,
    seed=5,
    n_particles=300,
    max_observations=5,
    sensor_model="analytic",
    env_id="ElectroLocUnknownTarget-v0",
)


def _cli(cfg: dict, out: Path) -> list[str]:
    args = [
        "bench",
        "--agents",
        ",".join(cfg["agents"]),
        "--conditions",
        ",".join(cfg["conditions"]),
        "--trials",
        str(cfg["trials"]),
        "--seed",
        str(cfg["seed"]),
        "--n-particles",
        str(cfg["n_particles"]),
        "--max-observations",
        str(cfg["max_observations"]),
        "--sensor-model",
        cfg["sensor_model"],
        "--backend",
        "serial",
        "--no-progress",
        "--out",
        str(out),
    ]
    return args + (["--env", "unknown-target"] if cfg.get("env_id") == "ElectroLocUnknownTarget-v0" else [])


def _strip(summary: dict) -> list:
    return [{k: v for k, v in r.items() if k not in ("decision_ms_median",)} for r in summary["rows"]]


@pytest.fixture(scope="module", params=["target", "unknown"])
def reference(request, tmp_path_factory):
    cfg = TARGET if request.param == "target" else UNKNOWN
    out = tmp_path_factory.mktemp(request.param)
    summary = run_benchmark(BenchConfig(**cfg), out, backend="serial", progress=False, log=None)
    return cfg, out, (out / "trials.jsonl").read_text().splitlines(keepends=True), summary


def _crafted(reference, tmp_path: Path, line_no: int, new_line: str) -> Path:
    cfg, out, lines, _ = reference
    run = tmp_path / "run"
    shutil.copytree(out, run)
    lines = list(lines)
    lines[line_no] = new_line if new_line.endswith("\n") else new_line + "\n"
    (run / "trials.jsonl").write_text("".join(lines))
    return run


def _edit(line: str, **changes) -> str:
    rec = json.loads(line)
    for k, v in changes.items():
        if v is _DROP:
            rec.pop(k)
        elif k == "shape" and isinstance(v, dict) and isinstance(rec.get("shape"), dict):
            rec["shape"] = {**rec["shape"], **v}
        else:
            rec[k] = v
    return json.dumps(rec)


_DROP = object()


def _resume_and_check(reference, run: Path, capsys, message: str) -> None:
    """The crafted line is set aside by file and line, run again, and the summary is the reference's."""
    cfg, _, lines, summary = reference
    (run / "table.md").write_text("stale table")
    assert cli_main([*_cli(cfg, run), "--resume"]) == 0
    captured = capsys.readouterr()
    err = captured.out + captured.err
    assert f"{run / 'trials.jsonl'}:1: " in err and message in err, err
    assert "Traceback" not in err
    assert _strip(json.loads((run / "summary.json").read_text())) == _strip(summary)
    assert (run / "table.md").read_text() != "stale table"
    assert len((run / REJECTED_FILE).read_text().splitlines()) == 1


# ---- the reproducers ---------------------------------------------------------------------------------------
def test_a_wrong_type_inside_shape_is_set_aside(reference, tmp_path, capsys) -> None:
    if reference[0] is not UNKNOWN:
        pytest.skip("the unknown-target env's records")
    run = _crafted(reference, tmp_path, 0, _edit(reference[2][0], shape={"radius_estimate_mm": "big"}))
    _resume_and_check(reference, run, capsys, "'shape' must be null or an object with exactly the keys")


def test_an_unknown_target_record_without_shape_is_set_aside(reference, tmp_path, capsys) -> None:
    if reference[0] is not UNKNOWN:
        pytest.skip("the unknown-target env's records")
    run = _crafted(reference, tmp_path, 0, _edit(reference[2][0], shape=_DROP))
    _resume_and_check(reference, run, capsys, "'shape' must be the task's results, exactly the keys")


@pytest.mark.parametrize(
    "crafted,message",
    [
        ("[" * 100_000, "a line longer than 16384 characters"),
        ('{"shape": {"a": ' + "[" * 5000 + "]" * 5000 + "}}", "nested too deep"),
        ("[" * 1000 + "]" * 1000, "Expected `object`, got `array`"),
        ('{"trial": ' + "9" * 5001 + "}", "Integer value out of range - at `$.trial`"),
        ('{"trial": 1e999999}', "Number out of range - at `$.trial`"),
        ('{"trial": NaN}', "not JSON (JSON is malformed: invalid character"),
        ("x" * 20_000, "not JSON (JSON is malformed"),
    ],
)
def test_parsing_is_bounded(reference, tmp_path, capsys, crafted, message) -> None:
    if reference[0] is not TARGET:
        pytest.skip("once")
    run = _crafted(reference, tmp_path, 0, crafted)
    _resume_and_check(reference, run, capsys, message)


@pytest.mark.parametrize(
    "changes,message",
    [
        ({"readings": 1000}, "'readings' 1000 exceeds the record's cap 'max_observations' 6"),
        ({"readings": 5, "decisions": 5}, "≠ 'readings' − 1 = 4"),
        ({"observations": 3}, "both 'readings' and its old name 'observations'"),
        ({"start": [0, 0]}, "'start' [0.0, 0.0] is not the start"),
        ({"start": [0.0, 1e-3]}, "is not the start"),
        ({"far_success": None}, "Expected `bool`, got `null` - at `$.far_success`"),
        ({"distractors": None}, "Expected `int`, got `null` - at `$.distractors`"),
        ({"distractors": 9}, "Expected `int` <= 8 - at `$.distractors`"),
        ({"error_mm": -5}, "Expected `float` >= 0.0 - at `$.error_mm`"),
        ({"agent": "evil"}, "agent 'evil' is not one of the run's"),
        ({"trial": 7}, "trial 7 is outside the run's range 0–2"),
        ({"table_layout": "table1", "_failed": True}, "table_layout 'table1', but agent 'rnd-wlk' reports to 'table4'"),
        (
            {"spread_mm": 50.0, "success": True, "ended_by": "success", "readings": 5, "decisions": 4},
            "vs the criterion 10.0 mm",
        ),
        ({"extra": 1}, "Object contains unknown field `extra`"),
    ],
)
def test_impossible_records_are_set_aside(reference, tmp_path, capsys, changes, message) -> None:
    cfg, _, lines, _ = reference
    if cfg is not TARGET:
        pytest.skip("the target env's records")
    failed = changes.pop("_failed", False)
    n = next(
        i
        for i, line in enumerate(lines)
        if json.loads(line)["agent"] == "rnd-wlk" and (not failed or not json.loads(line)["success"])
    )
    crafted = _edit(lines[n], **changes)
    lines = [lines[n], *lines[:n], *lines[n + 1 :]]  # the crafted record first: line 1
    run = _crafted((cfg, reference[1], lines, reference[3]), tmp_path, 0, crafted)
    _resume_and_check(reference, run, capsys, message)


def test_summary_and_table_are_written_together_or_not_at_all(reference, tmp_path, monkeypatch) -> None:
    cfg, out, _, _ = reference
    run = tmp_path / "run"
    shutil.copytree(out, run)
    import electroloc_gym.bench.tables as tables

    def broken(summary):
        raise RuntimeError("table failed")

    monkeypatch.setattr(tables, "render_table_md", broken)
    with pytest.raises(RuntimeError, match="table failed"):
        run_benchmark(BenchConfig(**cfg), run, backend="serial", progress=False, log=None, resume=True)
    assert not any((run / name).exists() for name in OUTPUT_FILES)


# ---- properties --------------------------------------------------------------------------------------------
_ANY = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=8),
    st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)
#: Fields whose other values can be valid on their own: accepted only inside their documented range.
_LOOSE = {
    "agent_label": lambda v: isinstance(v, str) and 0 < len(v) <= 2000,
    # any spread consistent with the record's success (≤ the criterion ⇔ success) is a valid spread
    "spread_mm": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0,
    **{
        k: (lambda v: v is None or (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v <= 86_400e3))
        for k in TIMING_KEYS
    },
}


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_every_field_is_checked_on_resume(reference, tmp_path, data) -> None:
    cfg, out, lines, _ = reference
    config = BenchConfig(**cfg)
    rules = _rules(cfg)
    table4 = [i for i, line in enumerate(lines) if json.loads(line)["table_layout"] == "table4"]  # every field pinned
    n = data.draw(st.sampled_from(table4), label="line")
    key = data.draw(st.sampled_from(RECORD_KEYS), label="field")
    original = json.loads(lines[n])
    value = data.draw(_ANY, label="value")
    if value == original.get(key) and type(value) is type(original.get(key)):
        return
    crafted = dict(original, **{key: value})
    path = tmp_path / f"trials-{key}.jsonl"
    path.write_text("".join([json.dumps(crafted) + "\n", *lines[:n], *lines[n + 1 :]]))
    loaded = load_records(path, config, rules)
    kept = list(loaded.records.values())
    assert len(kept) + len(loaded.rejected) + len(loaded.foreign) == len(lines)
    accepted = crafted in kept
    if key in _LOOSE:
        assert not accepted or _LOOSE[key](value)
    else:
        assert not accepted, (key, value)


def _rules(cfg: dict):
    return record_rules(BenchConfig(**cfg))


def test_what_the_worker_writes_passes_its_own_schema(reference) -> None:
    _, _, lines, _ = reference
    rules = _rules(reference[0])
    for line in lines:
        rec = TrialRecord.from_json(json.loads(line))
        assert rec.problem(rules) is None and rec.to_json() == json.loads(line)
        assert rec.error_mm is None or math.isclose(rec.error_mm, math.dist(rec.estimate, rec.target))


# ---- the one reader, old key names -------------------------------------------------------------------------
def test_a_record_with_the_old_name_of_readings_reads_as_readings(reference, tmp_path) -> None:
    cfg, out, lines, _ = reference
    old = []
    for line in lines:
        rec = json.loads(line)
        rec["observations"] = rec.pop("readings")
        rec.pop("far_success"), rec.pop("distractors")  # written before these keys existed
        old.append(json.dumps(rec) + "\n")
    path = tmp_path / "trials.jsonl"
    path.write_text("".join(old))
    loaded = load_records(path, BenchConfig(**cfg), _rules(cfg))
    assert loaded.n_rejected == 0 and loaded.n_foreign == 0
    assert list(loaded.records.values()) == [json.loads(line) for line in lines]


def test_read_run_records_is_what_resume_keeps(reference, tmp_path) -> None:
    from electroloc_gym.bench.stored_run import read_run_records

    cfg, out, lines, _ = reference
    run = tmp_path / "run"
    shutil.copytree(out, run)
    bad = _edit(lines[0], readings=1000)
    (run / "trials.jsonl").write_text("".join([bad + "\n", "garbage\n", *lines[1:]]))
    got = read_run_records(run)
    assert got.config == BenchConfig(**cfg)
    assert got.records == [json.loads(line) for line in lines[1:]]
    assert got.n_set_aside == 2 and len(got.messages()) == 2
    assert (run / "trials.jsonl").read_text().startswith(bad)  # nothing written


@pytest.mark.parametrize(
    "damage",
    ["no-folder", "no-config", "no-trials", "config-garbage", "config-list", "config-bad-value", "trials-a-folder"],
)
def test_read_run_records_refuses_a_damaged_folder_in_one_line(reference, tmp_path, damage) -> None:
    from electroloc_gym.bench.stored_run import read_run_records

    cfg, out, _, _ = reference
    if cfg is not TARGET:
        pytest.skip("once")
    run = tmp_path / "run"
    shutil.copytree(out, run)
    config = json.loads((run / "config.json").read_text())
    if damage == "no-folder":
        run = tmp_path / "absent"
    elif damage == "no-config":
        (run / "config.json").unlink()
    elif damage == "no-trials":
        (run / "trials.jsonl").unlink()
    elif damage == "config-garbage":
        (run / "config.json").write_bytes(b"\xff[[[")
    elif damage == "config-list":
        (run / "config.json").write_text("[1, 2]")
    elif damage == "config-bad-value":
        (run / "config.json").write_text(json.dumps({**config, "trials": -3}))
    else:
        (run / "trials.jsonl").unlink()
        (run / "trials.jsonl").mkdir()
    with pytest.raises(ValueError) as info:
        read_run_records(run)
    assert "\n" not in str(info.value) and str(run.name) in str(info.value)


def test_rules_built_without_metrics_check_the_localisation_task_s_fields() -> None:
    """``RecordRules`` made by hand (not from a run's config) check the localisation task's metrics, the task every
    record of a run without a task of its own has."""
    from electroloc_gym.bench.schema import RecordRules
    from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS

    rules = RecordRules(
        conditions=frozenset({"fresh-steel-12.7"}), agents=frozenset({"rnd-wlk"}), trials=1, success_spread_mm=1.0
    )
    assert rules.metrics is LOCALIZATION_METRICS


def test_a_run_without_trials_has_no_records(tmp_path: Path) -> None:
    """No trials.jsonl (and no kept trials.jsonl.gz) is a run with no records yet, not an unreadable file."""
    loaded = load_records(tmp_path / "trials.jsonl")
    assert loaded.records == {} and not loaded.rejected and not loaded.foreign


def test_the_record_writer_lets_go_of_its_file(tmp_path: Path) -> None:
    """Leaving ``RecordWriter``'s block closes trials.jsonl (a run leaves no open file behind), its lines kept."""
    from electroloc_gym.bench.records import RecordWriter

    with RecordWriter(tmp_path / "trials.jsonl") as writer:
        writer.write({"trial": 0})
    assert writer._fh.closed and json.loads((tmp_path / "trials.jsonl").read_text()) == {"trial": 0}
