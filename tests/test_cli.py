"""Subprocess smoke tests of the `electroloc` console script's foundation commands."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from electroloc_gym.conditions import PAPER_TABLE3_THEORY_MM, PRESET_NAMES

ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def run_cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "electroloc_gym.cli", *args], capture_output=True, text=True,
                          env=ENV, timeout=timeout)


def test_detect_table_prints_paper_columns() -> None:
    out = run_cli("detect")
    assert out.returncode == 0, out.stderr
    for name in PRESET_NAMES:
        assert name in out.stdout
    assert "paper theory" in out.stdout and "paper measured" in out.stdout
    assert "not reproducible" in out.stdout  # the 38.1 mm discrepancy is flagged


def test_detect_json_small_spheres_within_1p5_mm() -> None:
    out = run_cli("detect", "--json")
    assert out.returncode == 0, out.stderr
    rows = {r["condition"]: r for r in json.loads(out.stdout)}
    assert set(rows) == set(PRESET_NAMES)
    for name, r in rows.items():
        assert r["paper_theory_mm"] == PAPER_TABLE3_THEORY_MM[name]
        if name.endswith("12.7"):
            assert abs(r["model_mm"] - r["paper_theory_mm"]) <= 1.5
        assert r["model_fitted_mm"] >= r["paper_measured_mm"] - 0.05


@pytest.mark.parametrize("condition", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_eev_writes_png(tmp_path, condition: str) -> None:
    out_file = tmp_path / "eev.png"
    out = run_cli("eev", "--condition", condition, "--out", str(out_file))
    assert out.returncode == 0, out.stderr
    assert out_file.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]  # atomic write left no temp file


def test_demo_writes_png(tmp_path) -> None:
    out_file = tmp_path / "demo.png"
    out = run_cli("demo", "--sensor-model", "analytic", "--out", str(out_file))
    assert out.returncode == 0, out.stderr
    assert out_file.stat().st_size > 10_000
    assert "observations" in out.stdout


def test_bad_condition_is_a_clear_usage_error() -> None:
    out = run_cli("eev", "--condition", "fresh-gold-12.7")
    assert out.returncode == 2
    assert "invalid choice" in out.stderr and "--condition" in out.stderr


def test_console_script_entry_point() -> None:
    from electroloc_gym.cli import main

    assert main(["detect", "--json"]) == 0


@pytest.mark.parametrize("command", [[], ["bench"], ["detect"], ["eev"], ["demo"]])
def test_help_is_plain_text_with_defaults(command) -> None:
    out = run_cli(*command, "--help")
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())  # line wrapping depends on the terminal width
    assert "``" not in text and ":func:" not in text and ":mod:" not in text
    assert "(default: None)" not in text and "(default: False)" not in text
    if command == ["bench"]:
        for default in ("--trials TRIALS", "(default: 50)", "(default: 0)", "(default: bench_out)",
                        "(default: calibrated,", "2500 as the paper; unknown-target: 5000", "(default: 35)",
                        "(default: all)",
                        "(default: process)", "examples:", "ppo-belief"):
            assert default in text, default
    if command == ["eev"]:
        assert "(default: eev.png)" in text and "(default: fresh-steel-12.7)" in text
    if command == ["demo"]:
        assert "(default: demo.png)" in text
