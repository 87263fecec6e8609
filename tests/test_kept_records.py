"""Kept runs' trial records stored compressed: read as the plain file is, reproducible bytes, never appended to."""

from __future__ import annotations

import gzip
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from tiny_bench_run import ENV, TINY_CLI

from electroloc_gym.bench.records import (
    TRIALS_FILE,
    TRIALS_GZ_FILE,
    compress_trials,
    load_records,
    open_trials,
    read_trials,
    stored_trials,
)
from electroloc_gym.bench.stored_run import read_run_records

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "experiments" / "reference" / "bench"
KEPT = sorted((ROOT / "experiments").rglob(TRIALS_GZ_FILE))


def _plain_copy(dest: Path, n_lines: int = 120) -> Path:
    """The reference run's config and its first ``n_lines`` records, as a plain (live) run folder."""
    dest.mkdir(parents=True)
    shutil.copy(REFERENCE / "config.json", dest / "config.json")
    with open_trials(REFERENCE / TRIALS_FILE) as fh:
        (dest / TRIALS_FILE).write_bytes(b"".join(fh.readline() for _ in range(n_lines)))
    return dest


def test_the_kept_runs_are_stored_compressed_with_reproducible_bytes(tmp_path) -> None:
    assert len(KEPT) >= 3 and REFERENCE / TRIALS_GZ_FILE in KEPT
    for packed in KEPT:
        folder = packed.parent
        assert not (folder / TRIALS_FILE).exists(), f"{folder} holds both the plain and the compressed records"
        assert (folder / "config.json").is_file() and (folder / "summary.json").is_file(), f"{folder}: not finished"
        raw = packed.read_bytes()
        assert raw[:2] == b"\x1f\x8b" and raw[4:8] == b"\0\0\0\0" and not raw[3] & 0x08, f"{packed}: mtime or name"
    again = tmp_path / "again"
    again.mkdir()
    (again / TRIALS_FILE).write_bytes(gzip.decompress((REFERENCE / TRIALS_GZ_FILE).read_bytes()))
    assert compress_trials(again).read_bytes() == (REFERENCE / TRIALS_GZ_FILE).read_bytes()
    assert not (again / TRIALS_FILE).exists()


def test_a_compressed_run_reads_as_its_plain_records(tmp_path) -> None:
    plain = _plain_copy(tmp_path / "plain")
    packed = shutil.copytree(plain, tmp_path / "packed")
    assert compress_trials(packed) == packed / TRIALS_GZ_FILE
    assert stored_trials(packed / TRIALS_FILE) == packed / TRIALS_GZ_FILE
    assert stored_trials(plain / TRIALS_FILE) == plain / TRIALS_FILE
    a, b = read_run_records(plain), read_run_records(packed)
    assert len(a.loaded.records) == 120 and a.loaded.records == b.loaded.records
    assert b.loaded.path == packed / TRIALS_GZ_FILE and b.n_set_aside == 0
    assert read_trials(packed / TRIALS_FILE) == read_trials(plain / TRIALS_FILE)


def test_a_damaged_line_in_a_compressed_run_is_named_by_its_file_and_line(tmp_path) -> None:
    plain = _plain_copy(tmp_path / "run", n_lines=5)
    lines = (plain / TRIALS_FILE).read_bytes().splitlines(keepends=True)
    (plain / TRIALS_FILE).write_bytes(b"".join([*lines[:2], b"garbage\n", *lines[2:]]))
    compress_trials(plain)
    loaded = read_run_records(plain).loaded
    assert len(loaded.records) == 5 and [m.split(": ")[0] for m in loaded.messages()] == [f"{plain / TRIALS_GZ_FILE}:3"]


def test_a_broken_compressed_file_is_one_error(tmp_path) -> None:
    plain = _plain_copy(tmp_path / "run", n_lines=20)
    packed = compress_trials(plain)
    packed.write_bytes(packed.read_bytes()[: len(packed.read_bytes()) // 2])
    with pytest.raises(ValueError, match=r"cannot read .*trials\.jsonl\.gz"):
        load_records(plain / TRIALS_FILE)
    packed.write_bytes(b"not gzip at all\n")
    with pytest.raises(ValueError, match=r"cannot read .*trials\.jsonl\.gz"):
        read_run_records(plain)


def test_compressing_refuses_a_missing_or_a_second_copy(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"trials\.jsonl: missing"):
        compress_trials(tmp_path)
    plain = _plain_copy(tmp_path / "run", n_lines=3)
    shutil.copy(plain / TRIALS_FILE, tmp_path / "keep.jsonl")
    compress_trials(plain)
    shutil.copy(tmp_path / "keep.jsonl", plain / TRIALS_FILE)
    with pytest.raises(ValueError, match=r"trials\.jsonl\.gz already exists"):
        compress_trials(plain)
    assert (plain / TRIALS_FILE).read_bytes() == (tmp_path / "keep.jsonl").read_bytes()  # nothing removed


@pytest.mark.parametrize("resume", [False, True])
def test_a_run_never_appends_to_a_compressed_run(tmp_path, resume) -> None:
    """The bench refuses a folder holding trials.jsonl.gz in one line, before it writes anything there."""
    run = tmp_path / "kept"
    run.mkdir()
    (run / TRIALS_GZ_FILE).write_bytes(gzip.compress(b"", mtime=0))
    before = sorted(p.name for p in run.iterdir())
    proc = subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", "bench", *TINY_CLI, "--out", str(run)]
        + (["--resume"] if resume else []),
        capture_output=True,
        text=True,
        env=ENV,
        timeout=300,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert "trials.jsonl.gz holds a kept run's trials (compressed); gunzip it" in proc.stderr
    assert sorted(p.name for p in run.iterdir()) == before
