"""The benchmark's output folder and processes: bad --out, the lock, workers that die with their parent, and runs
killed at random points then resumed."""

from __future__ import annotations

import errno
import io
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from tiny_bench_run import ENV, TINY_CLI, run_tiny, strip_timing

from electroloc_gym.bench.records import LOCK_FILE, FolderBusyError, prepare_out_dir, read_trials, run_lock
from electroloc_gym.cli import main as cli_main


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
            run_tiny(Path(out) if out else out)  # type: ignore[arg-type]
        assert cli_main(["bench", *TINY_CLI, "--out", out]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("electroloc bench: error: --out") and match in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


@pytest.mark.parametrize("step, words", [("mkdir", "cannot be created"), ("probe_write", "is not writable")])
def test_a_folder_the_system_refuses_is_one_line_with_its_reason(tmp_path, monkeypatch, step, words) -> None:
    """The file system's own refusal (a permission the checks before cannot see, e.g. a root-squashed share) while
    the output folder is made or probed: one line naming the setting, the folder and the system's reason."""
    from electroloc_gym.bench import records

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(Path, "mkdir", refuse) if step == "mkdir" else monkeypatch.setattr(records, step, refuse)
    out = tmp_path / "out"
    for name in ("out", "--out"):
        with pytest.raises(ValueError) as info:
            prepare_out_dir(out, name)
        assert str(info.value) == f"{name} {str(out)!r} {words}: Permission denied"


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


# ---- a full disk ------------------------------------------------------------------------------------------
class _FullDisk(io.FileIO):
    """A file on a disk with ``room`` bytes left: the write that reaches it is cut short, the next one fails
    with ENOSPC — what the kernel does (no file name in the error, as Python's buffered writes raise it)."""

    def __init__(self, file, mode: str, room: int) -> None:
        super().__init__(file, mode)
        self.room = room

    def write(self, b) -> int:
        if self.room <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        part = bytes(b)[: self.room]
        self.room -= len(part)
        return super().write(part)


def _fill_disk(monkeypatch, name: str, room: int) -> None:
    """Writes to the file ``name`` (or to its temporary file, ``.name.*.tmp``) get ``room`` bytes, then ENOSPC:
    trials.jsonl's appends through the records writer's open(), the atomic writes through os.fdopen."""
    import builtins

    import electroloc_gym.bench.records as records

    def fd_name(fd: int) -> str:
        return Path(os.readlink(f"/proc/self/fd/{fd}")).name

    real_open, real_fdopen = builtins.open, os.fdopen

    def fake_open(file, mode="r", *args, **kwargs):
        if Path(file).name == name and "a" in mode:
            return io.TextIOWrapper(io.BufferedWriter(_FullDisk(file, "a", room)), encoding=kwargs.get("encoding"))
        return real_open(file, mode, *args, **kwargs)

    def fake_fdopen(fd, mode="r", *args, **kwargs):
        if fd_name(fd).startswith(f".{name}.") and "w" in mode:
            return io.BufferedWriter(_FullDisk(fd, "w", room))
        return real_fdopen(fd, mode, *args, **kwargs)

    monkeypatch.setattr(records, "open", fake_open, raising=False)
    monkeypatch.setattr(os, "fdopen", fake_fdopen)


@pytest.mark.parametrize(
    "command, settings, advice",
    [
        ("bench", {"out": "runs/b", "resume": False}, "then run the same command with --resume"),
        ("dataset", {"resume": False, "force": False}, "then run the same command with --resume"),
        ("dataset", {"resume": True, "force": False}, "then run the same command with --resume"),
        # a replacement continues by --force: --resume beside it is refused, and --resume alone does not take it
        ("dataset", {"resume": False, "force": True}, "then run the same command again"),
    ],
)
def test_a_disk_error_says_the_command_that_continues(command, settings, advice) -> None:
    import argparse

    from electroloc_gym.utils.fileio import os_error_line

    line = os_error_line(command, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), argparse.Namespace(**settings))
    assert line.endswith(advice) and "\n" not in line, line


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/fd")
@pytest.mark.parametrize("name, room", [("trials.jsonl", 1500), ("summary.json", 100)])
def test_a_full_disk_is_one_line_and_resume_gives_the_uninterrupted_records(tmp_path, capsys, monkeypatch, name, room):
    """A disk that fills while the records (a line torn half-way) or the summary are written: one line naming
    the file and the system's reason, saying the finished trials are kept and --resume continues; exit 2, no
    traceback. Once space is free, --resume ends with the records of an uninterrupted run."""
    out = tmp_path / "out"
    argv = ["bench", *TINY_CLI, "--backend", "serial", "--out", str(out)]
    with monkeypatch.context() as m:
        _fill_disk(m, name, room)
        code = cli_main(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("electroloc bench: error: cannot write ") and name in lines[0], lines
    for words in ("No space left on device", f"{out / 'trials.jsonl'}", "kept", "--resume"):
        assert words in lines[0], (words, lines[0])
    assert cli_main([*argv, "--resume"]) == 0
    reference = tmp_path / "reference"
    run_tiny(reference)
    assert strip_timing(read_trials(out / "trials.jsonl")) == strip_timing(read_trials(reference / "trials.jsonl"))
    assert (out / "table.md").exists() and (out / "summary.json").exists()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/fd")
def test_a_full_disk_under_a_figure_is_one_line(tmp_path, capsys, monkeypatch) -> None:
    """A command without records (electroloc eev): one line naming the file and the reason, exit 2, and the
    file it would have replaced left as it was (atomic writes)."""
    png = tmp_path / "eev.png"
    png.write_bytes(b"old")
    with monkeypatch.context() as m:
        _fill_disk(m, "eev.png", 100)
        code = cli_main(["eev", "--out", str(png)])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"electroloc eev: error: cannot write {png}: No space left on device"), lines
    assert "--resume" not in lines[0] and png.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eev.png"]  # no temporary file left


# ---- the lock ----------------------------------------------------------------------------------------------
def test_a_second_run_on_a_locked_folder_refuses(tmp_path, capsys) -> None:
    with run_lock(tmp_path):
        with pytest.raises(FolderBusyError, match="in use by another electroloc bench run"):
            run_lock(tmp_path).acquire()
        with pytest.raises(ValueError, match="in use by another electroloc bench run"):
            run_tiny(tmp_path)
        assert cli_main(["bench", *TINY_CLI, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "in use by another electroloc bench run" in err[0]
        assert not (tmp_path / "trials.jsonl").exists()
    run_tiny(tmp_path)  # released: the run goes ahead
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
    """Workers in the middle of long trials (a decision takes about a second at 100 000 particles) exit within
    seconds of their parent's SIGKILL: they do not finish their trial first."""
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
        "100000",
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
        time.sleep(2.0)
        assert all(_alive(p) for p in workers), "the workers did not start their trials"
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 5  # the kernel's parent-death signal at once, the poller within 0.5 s
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
    assert strip_timing(read_trials(trials)) == strip_timing(read_trials(whole / "trials.jsonl"))

    def rows(out: Path) -> list[dict]:
        return [
            {k: v for k, v in r.items() if k != "decision_ms_median"}
            for r in json.loads((out / "summary.json").read_text())["rows"]
        ]

    assert rows(run) == rows(whole)
    print("fault campaign, records after each kill:", partial, "of", total)
