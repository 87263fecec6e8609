"""The benchmark's records on --resume: keyed records, records and configs of other runs refused, damaged lines
and a damaged config reported, set aside and re-run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from tiny_bench_run import AGENTS, ENV, TINY, TINY_CLI, run_tiny, strip_timing

from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.records import REJECTED_FILE, load_records, read_trials
from electroloc_gym.bench.runner import run_benchmark


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    summary = run_tiny(out)
    lines = (out / "trials.jsonl").read_text(encoding="utf-8").splitlines(keepends=True)
    assert len(lines) == len(AGENTS) * 2 * 2
    return out, lines, summary


def _copy_run(reference, dest: Path, lines=None, config=True) -> Path:
    out, ref_lines, _ = reference
    dest.mkdir(parents=True, exist_ok=True)
    data = "".join(ref_lines if lines is None else lines)
    (dest / "trials.jsonl").write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
    if config:
        (dest / "config.json").write_text((out / "config.json").read_text())
    return dest


# ---- keyed records -------------------------------------------------------------------------------------------
def test_duplicate_lines_are_never_counted_twice(reference, tmp_path, capsys) -> None:
    out, lines, ref_summary = reference
    doubled = _copy_run(reference, tmp_path / "doubled", lines=lines + lines)  # two writers, every trial twice
    assert len(read_trials(doubled / "trials.jsonl")) == len(lines)
    summary = run_benchmark(
        BenchConfig(agents=AGENTS, **TINY), doubled, backend="serial", resume=True, progress=False, log=print
    )
    assert summary["trials_run_this_time"] == 0
    assert [(r["successes"], r["failures"], r["trials"]) for r in summary["rows"]] == [
        (r["successes"], r["failures"], r["trials"]) for r in ref_summary["rows"]
    ]
    assert (doubled / "table.md").read_text() == (out / "table.md").read_text()
    logged = capsys.readouterr().out
    assert logged.count("duplicate of line") == len(lines)
    assert f"trials.jsonl:{len(lines) + 1}: duplicate of line 1" in logged
    assert len((doubled / "trials.jsonl").read_text().splitlines()) == len(lines)
    assert len((doubled / REJECTED_FILE).read_text().splitlines()) == len(lines)


def test_a_conflicting_second_result_is_set_aside(reference, tmp_path) -> None:
    _, lines, _ = reference
    other = json.loads(lines[0])
    other["start"] = [other["start"][0] + 1.0, other["start"][1]]  # a valid record with another result
    loaded = load_records(_copy_run(reference, tmp_path, lines=[*lines, json.dumps(other) + "\n"]) / "trials.jsonl")
    assert len(loaded.records) == len(lines)
    assert loaded.rejected[0][0] == len(lines) + 1 and "a second, different result of line 1" in loaded.rejected[0][1]
    assert loaded.records[(other["condition"], other["agent"], other["trial"])]["start"] != other["start"]


# ---- resume checks every record ------------------------------------------------------------------------------
@pytest.mark.parametrize("with_config", [True, False])
def test_resume_refuses_records_of_another_seed(reference, tmp_path, with_config) -> None:
    _, lines, _ = reference
    other = tmp_path / "seed99"
    run_benchmark(BenchConfig(agents=AGENTS, **{**TINY, "seed": 99}), other, backend="serial", progress=False, log=None)
    foreign = (other / "trials.jsonl").read_text().splitlines(keepends=True)
    mixed = _copy_run(reference, tmp_path / "mixed", lines=[*lines[:3], foreign[3], *lines[4:]], config=with_config)
    with pytest.raises(ValueError, match=r"trials.jsonl:4 is not a trial of this run .*another --seed"):
        run_tiny(mixed, resume=True)
    only_foreign = _copy_run(reference, tmp_path / "foreign", lines=foreign, config=False)
    with pytest.raises(ValueError, match=r"trials.jsonl:1 \(and 7 more\) is not a trial of this run"):
        run_tiny(only_foreign, resume=True)
    assert (mixed / "trials.jsonl").read_text() == "".join([*lines[:3], foreign[3], *lines[4:]])  # untouched


@pytest.mark.parametrize(
    "key,value", [("sensor_model", "calibrated"), ("n_particles", 2500), ("max_observations", 35), ("signal", "paper")]
)
def test_resume_without_config_refuses_records_of_other_settings(reference, tmp_path, key, value) -> None:
    _, lines, _ = reference
    rec = json.loads(lines[2])
    rec[key] = value
    run = _copy_run(reference, tmp_path, lines=[*lines[:2], json.dumps(rec) + "\n", *lines[3:]], config=False)
    with pytest.raises(ValueError, match=rf"trials.jsonl:3 is not a trial of this run .*{key}"):
        run_tiny(run, resume=True)


def test_a_global_map_record_is_not_a_trial_of_a_target_run(reference) -> None:
    from electroloc_gym.bench.records import foreign_reason
    from electroloc_gym.registry import env_entry

    rec = {**json.loads(reference[1][0]), "condition": env_entry("ElectroLocGlobal-v0").map_condition}
    assert "does not belong to env ElectroLoc-v0" in foreign_reason(rec, BenchConfig(agents=AGENTS, **TINY))


def test_resume_refuses_a_config_of_other_settings(reference, tmp_path) -> None:
    run = _copy_run(reference, tmp_path)
    with pytest.raises(ValueError, match="settings differ"):
        run_benchmark(
            BenchConfig(agents=AGENTS, **{**TINY, "seed": 99}),
            run,
            backend="serial",
            resume=True,
            progress=False,
            log=None,
        )


def _damage(lines: list[str]) -> dict[str, tuple[list[bytes], int, str]]:
    """name → (damaged file lines, the damaged line's number, what the report says)."""
    b = [ln.encode("utf-8") for ln in lines]
    rec = json.loads(lines[3])
    null_trial = {**rec, "trial": None}
    no_keys = {k: v for k, v in rec.items() if k not in ("success", "readings")}
    return {
        "truncated": ([*b[:3], b[3][: len(b[3]) // 2] + b"\n", *b[4:]], 4, "not JSON"),
        "torn-last": ([*b[:3], *b[4:], b[3][:40]], len(b), "last line torn"),
        "garbage": ([*b[:3], b"\x00\x01 garbage }{\n", *b[3:]], 4, "not JSON"),
        "non-utf8": ([*b[:3], b"\xff\xfe" + b[3], *b[4:]], 4, "not UTF-8"),
        "null-trial": ([*b[:3], json.dumps(null_trial).encode() + b"\n", *b[4:]], 4, "got `null` - at `$.trial`"),
        "missing-keys": ([*b[:3], json.dumps(no_keys).encode() + b"\n", *b[4:]], 4, "missing required field `success`"),
        "not-object": ([*b[:3], b"[1, 2, 3]\n", *b[3:]], 4, "Expected `object`, got `array`"),
        "bad-type": (
            [*b[:3], json.dumps({**rec, "success": "yes"}).encode() + b"\n", *b[4:]],
            4,
            "Expected `bool`, got `str` - at `$.success`",
        ),
    }


@pytest.mark.parametrize(
    "case", ["truncated", "torn-last", "garbage", "non-utf8", "null-trial", "missing-keys", "not-object", "bad-type"]
)
def test_damaged_lines_are_reported_set_aside_and_rerun(reference, tmp_path, capsys, case) -> None:
    _, lines, _ = reference
    damaged, line_no, says = _damage(lines)[case]
    run = tmp_path / "run"
    run.mkdir()
    (run / "trials.jsonl").write_bytes(b"".join(damaged))
    (run / "config.json").write_text((reference[0] / "config.json").read_text())
    summary = run_benchmark(
        BenchConfig(agents=AGENTS, **TINY), run, backend="serial", resume=True, progress=False, log=print
    )
    logged = capsys.readouterr().out
    assert f"{run / 'trials.jsonl'}:{line_no}: " in logged and says in logged, logged
    assert summary["trials_run_this_time"] == (0 if case in ("garbage", "not-object") else 1)
    assert strip_timing(read_trials(run / "trials.jsonl")) == strip_timing(json.loads(ln) for ln in lines)
    rejected = (run / REJECTED_FILE).read_bytes()
    assert damaged[line_no - 1].rstrip(b"\n") in rejected


@pytest.mark.parametrize(
    "content", [b"[1, 2]", b"not json", b"\xff\xfe{}", b'"a string"', b'{"seed": "zero"}', b'{"agents": 1}']
)
def test_a_damaged_config_is_set_aside_and_records_checked_on_their_own(reference, tmp_path, capsys, content) -> None:
    _, lines, _ = reference
    run = _copy_run(reference, tmp_path, lines=lines[:5])
    (run / "config.json").write_bytes(content)
    summary = run_benchmark(
        BenchConfig(agents=AGENTS, **TINY), run, backend="serial", resume=True, progress=False, log=print
    )
    assert f"{run / 'config.json'}: " in capsys.readouterr().out
    assert (run / "config.rejected.json").read_bytes() == content
    assert summary["trials_run_this_time"] == len(lines) - 5
    assert json.loads((run / "config.json").read_text())["seed"] == TINY["seed"]
    assert strip_timing(read_trials(run / "trials.jsonl")) == strip_timing(json.loads(ln) for ln in lines)


def test_cli_resume_reports_and_reruns_without_traceback(reference, tmp_path) -> None:
    _, lines, _ = reference
    damaged, _, _ = _damage(lines)["non-utf8"]
    run = tmp_path / "run"
    run.mkdir()
    (run / "trials.jsonl").write_bytes(b"".join(damaged))
    proc = subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", "bench", *TINY_CLI, "--out", str(run), "--resume"],
        capture_output=True,
        text=True,
        env=ENV,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "trials.jsonl:4: not UTF-8" in proc.stdout and "set 1 line(s) aside" in proc.stdout
    assert "Traceback" not in proc.stderr
    assert len(read_trials(run / "trials.jsonl")) == len(lines)
