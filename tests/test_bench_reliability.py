"""The benchmark's output folder: bad --out, the lock, keyed records, checked resume, damaged lines, dead parents."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.records import (
    LOCK_FILE,
    REJECTED_FILE,
    FolderBusyError,
    load_records,
    prepare_out_dir,
    read_trials,
    run_lock,
)
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.bench.schema import TIMING_KEYS
from electroloc_gym.cli import main as cli_main

TINY = dict(
    conditions=("fresh-steel-12.7", "salt-delrin-38.1"),
    trials=2,
    seed=3,
    n_particles=300,
    max_observations=6,
    sensor_model="analytic",
)
AGENTS = ("rnd-wlk", "zero-crossing[max_observations=60]")
TINY_CLI = [
    "--agents",
    "rnd-wlk,zero-crossing[max_observations=60]",
    "--conditions",
    "fresh-steel-12.7,salt-delrin-38.1",
    "--trials",
    "2",
    "--seed",
    "3",
    "--n-particles",
    "300",
    "--max-observations",
    "6",
    "--sensor-model",
    "analytic",
    "--no-progress",
]
ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _strip(records) -> dict:
    return {
        (r["condition"], r["agent"], r["trial"]): {k: v for k, v in r.items() if k not in TIMING_KEYS} for r in records
    }


def _run(out: Path, **kw):
    return run_benchmark(BenchConfig(agents=AGENTS, **TINY), out, backend="serial", progress=False, log=None, **kw)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    summary = _run(out)
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


# ---- --out -------------------------------------------------------------------------------------------------
def _bad_outs(tmp_path: Path) -> list[tuple[str, str]]:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    return [
        ("", "must name a folder"),
        (str(a_file), "is a file, not a folder"),
        (str(a_file / "sub" / "out"), "which is a file"),
        ("/proc/self", "not writable"),
        ("/sys/electroloc-bench-test", "cannot be created"),
    ]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and /sys as unwritable folders")
def test_bad_out_is_one_clear_error_before_any_work(tmp_path, capsys) -> None:
    for out, match in _bad_outs(tmp_path):
        with pytest.raises(ValueError, match=match):
            prepare_out_dir(out)
        with pytest.raises(ValueError, match=match):
            _run(Path(out) if out else out)  # type: ignore[arg-type]
        assert cli_main(["bench", *TINY_CLI, "--out", out]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("electroloc bench: error: --out") and match in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_out_folder(tmp_path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(ValueError, match="not writable"):
            prepare_out_dir(ro)
        with pytest.raises(ValueError, match="cannot be created"):
            prepare_out_dir(ro / "sub")
    finally:
        ro.chmod(0o755)


# ---- the lock ----------------------------------------------------------------------------------------------
def test_a_second_run_on_a_locked_folder_refuses(tmp_path, capsys) -> None:
    with run_lock(tmp_path):
        with pytest.raises(FolderBusyError, match="in use by another electroloc bench run"):
            run_lock(tmp_path).acquire()
        with pytest.raises(ValueError, match="in use by another electroloc bench run"):
            _run(tmp_path)
        assert cli_main(["bench", *TINY_CLI, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "in use by another electroloc bench run" in err[0]
        assert not (tmp_path / "trials.jsonl").exists()
    _run(tmp_path)  # released: the run goes ahead
    assert len(read_trials(tmp_path / "trials.jsonl")) == 8


def test_the_lock_dies_with_its_holder(tmp_path) -> None:
    code = (
        "import time\nfrom electroloc_gym.bench.records import run_lock\n"
        f"lock = run_lock({str(tmp_path)!r}).acquire(); print('locked', flush=True); time.sleep(120)"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        assert holder.stdout.readline().strip() == "locked"
        proc = subprocess.run(
            [sys.executable, "-m", "electroloc_gym.cli", "bench", *TINY_CLI, "--out", str(tmp_path)],
            capture_output=True,
            text=True,
            env=ENV,
            timeout=120,
        )
        assert proc.returncode == 2
        assert "in use by another electroloc bench run" in proc.stderr
        assert "Traceback" not in proc.stderr and not (tmp_path / "trials.jsonl").exists()
    finally:
        holder.kill()
        holder.wait()
    run_lock(tmp_path).acquire().release()  # SIGKILL released the lock
    assert (tmp_path / LOCK_FILE).exists()


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
        _run(mixed, resume=True)
    only_foreign = _copy_run(reference, tmp_path / "foreign", lines=foreign, config=False)
    with pytest.raises(ValueError, match=r"trials.jsonl:1 \(and 7 more\) is not a trial of this run"):
        _run(only_foreign, resume=True)
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
        _run(run, resume=True)


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
        "null-trial": ([*b[:3], json.dumps(null_trial).encode() + b"\n", *b[4:]], 4, "'trial' must be an integer"),
        "missing-keys": ([*b[:3], json.dumps(no_keys).encode() + b"\n", *b[4:]], 4, "missing key(s)"),
        "not-object": ([*b[:3], b"[1, 2, 3]\n", *b[3:]], 4, "not a JSON object"),
        "bad-type": (
            [*b[:3], json.dumps({**rec, "success": "yes"}).encode() + b"\n", *b[4:]],
            4,
            "'success' must be true or false",
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
    assert _strip(read_trials(run / "trials.jsonl")) == _strip(json.loads(ln) for ln in lines)
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
    assert _strip(read_trials(run / "trials.jsonl")) == _strip(json.loads(ln) for ln in lines)


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


# ---- workers die with their parent ---------------------------------------------------------------------------
def _children(pid: int) -> list[int]:
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(entry.name))
    return kids


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_exit_when_the_parent_is_killed(tmp_path) -> None:
    workers: list[int] = []
    cmd = [
        sys.executable,
        "-m",
        "electroloc_gym.cli",
        "bench",
        "--agents",
        "min-var",
        "--trials",
        "40",
        "--conditions",
        "fresh-steel-12.7",
        "--n-particles",
        "2000",
        "--workers",
        "2",
        "--no-progress",
        "--out",
        str(tmp_path),
    ]
    parent = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            workers = [
                p
                for p in _children(parent.pid)
                if "spawn_main" in Path(f"/proc/{p}/cmdline").read_bytes().decode(errors="replace")
            ]
            if len(workers) == 2 and (tmp_path / "trials.jsonl").exists():
                break
            assert parent.poll() is None, "the run ended before its workers started"
            time.sleep(0.2)
        assert len(workers) == 2, "no worker processes found"
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(_alive(p) for p in workers):
            time.sleep(0.2)
        assert not [p for p in workers if _alive(p)], "workers outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        for p in workers:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


# ---- the fault campaign (slow) -------------------------------------------------------------------------------
def _lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


@pytest.mark.slow
def test_fault_campaign_kill_at_random_points_then_resume(tmp_path) -> None:
    """SIGKILL a bench run at random points, --resume until it finishes: the records equal an uninterrupted run's.

    The kill points are random moments of the start-up (before any trial finished) and random trial
    counts (kill when the file holds k more records), so the campaign does not depend on the speed of
    the machine.
    """
    args = [
        "--agents",
        "rnd-wlk,min-var[n_voters=64],zero-crossing",
        "--conditions",
        "fresh-steel-12.7,salt-delrin-38.1,fresh-delrin-38.1",
        "--trials",
        "4",
        "--n-particles",
        "500",
        "--workers",
        "2",
        "--no-progress",
    ]
    base = [sys.executable, "-m", "electroloc_gym.cli", "bench", *args]
    whole = tmp_path / "whole"
    subprocess.run([*base, "--out", str(whole)], check=True, capture_output=True, env=ENV, timeout=900)
    total = len(read_trials(whole / "trials.jsonl"))
    rng = random.Random(20080529)
    run = tmp_path / "killed"
    trials = run / "trials.jsonl"
    plan = [("time", rng.uniform(0.2, 2.0)), ("time", rng.uniform(0.2, 2.0))] + [
        ("records", rng.randint(1, max(1, total // 4))) for _ in range(5)
    ]
    partial = []
    for kind, point in plan:
        cmd = [*base, "--out", str(run)] + (["--resume"] if trials.exists() else [])
        before = _lines(trials)
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV)
        t0 = time.monotonic()
        while proc.poll() is None:
            if (time.monotonic() - t0 >= point) if kind == "time" else (_lines(trials) - before >= point):
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.02)
        proc.wait()
        assert proc.returncode in (0, -signal.SIGKILL), proc.stderr.read().decode()
        partial.append(len(read_trials(trials)))
    proc = subprocess.run([*base, "--out", str(run), "--resume"], capture_output=True, text=True, env=ENV, timeout=900)
    assert proc.returncode == 0, proc.stderr
    assert sum(0 < n < total for n in partial) >= 3, partial  # killed mid-run, several times
    assert _strip(read_trials(trials)) == _strip(read_trials(whole / "trials.jsonl"))

    def rows(out: Path) -> list[dict]:
        return [
            {k: v for k, v in r.items() if k != "decision_ms_median"}
            for r in json.loads((out / "summary.json").read_text())["rows"]
        ]

    assert rows(run) == rows(whole)
    print("fault campaign, records after each kill:", partial, "of", total)
