"""The speed sweep's small run: every cell, the summary, the losing speed and a resumed run."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import speed_sweep


def test_a_small_sweep_summarises_and_resumes(tmp_path, capsys) -> None:
    out = tmp_path / "sweep.json"
    argv = ["--speeds", "1", "12", "--agents", "pursuit", "--trials", "2", "--sensor-model", "analytic"]
    argv += ["--n-particles", "200", "--out", str(out), "--figure", str(tmp_path / "fig.png")]
    result = speed_sweep.main(argv)
    rows = result["rows"]
    assert [(r["agent"], r["speed_mm"], r["trials"]) for r in rows] == [("pursuit", 1.0, 2), ("pursuit", 12.0, 2)]
    for r, c in zip(rows, result["cells"], strict=True):
        assert r["median_mm"] == np.median(c["tracking_error_mm"]) and r["capture_rate"] == np.mean(c["captured"])
    assert (tmp_path / "fig.png").stat().st_size > 0
    wrote = [line for line in capsys.readouterr().err.splitlines() if line.startswith("wrote: ")]
    assert wrote == [f"wrote: {out}", f"wrote: {tmp_path / 'fig.png'}"]  # what it wrote, said at the end
    kept = json.loads(out.read_text())
    again = speed_sweep.main([*argv, "--resume", "--speeds", "1", "12", "20"])
    assert again["cells"][:2] == kept["cells"] and len(again["cells"]) == 3  # only the new speed ran
    assert again["settings"]["speeds"] == [1.0, 12.0, 20.0]


def test_the_losing_speed_is_the_first_median_above_the_capture_distance() -> None:
    rows = [{"agent": "a", "speed_mm": v, "median_mm": m} for v, m in ((1.0, 3.0), (2.0, 11.0), (4.0, 9.0))]
    assert speed_sweep.losing_speed(rows, "a") == 2.0
    assert speed_sweep.losing_speed(rows[:1], "a") is None


# ---- bad options: one line, exit 2, before any work -----------------------------------------------------------
QUICK = ["--speeds", "1", "--agents", "pursuit", "--trials", "1", "--sensor-model", "analytic", "--n-particles", "50"]


def _refused(capsys, monkeypatch, tmp_path, argv: list[str], *words: str) -> str:
    """``argv`` must exit 2 with argparse's usage and one error line naming the option, run no cell, write nothing."""
    monkeypatch.setattr(
        speed_sweep, "run_cell", lambda *a, **k: pytest.fail("a cell ran before the options were checked")
    )
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(SystemExit) as exc:
        speed_sweep.main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and "Traceback" not in "\n".join(err), err
    assert [line for line in err if ": error: " in line] == [err[-1]], err  # the usage, then one line
    for w in words:
        assert w in err[-1], (w, err[-1])
    assert sorted(tmp_path.rglob("*")) == before  # nothing written
    return err[-1]


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--speeds", "nan"], ["--speeds", "finite", "nan"]),
        (["--speeds", "inf"], ["--speeds", "finite", "inf"]),
        (["--speeds", "-1"], ["--speeds", "≥ 0", "≤ 20"]),
        (["--speeds", "25"], ["--speeds", "≤ 20"]),
        (["--speeds", "1", "1.0"], ["--speeds", "more than once"]),
        (["--trials", "0"], ["--trials", "[1, 100000]"]),
        (["--trials", "٣"], ["--trials", "ASCII digits"]),
        (["--seed", "-1"], ["--seed", "[0, "]),
        (["--n-particles", "1"], ["--n-particles", "[2, "]),
        (["--motion-step-mm", "nan"], ["--motion-step-mm", "finite"]),
        (["--agents", "nope"], ["--agents", "unknown agent 'nope'"]),
        (["--agents", ""], ["--agents", "names no agent"]),
        (["--agents", "pursuit,pursuit"], ["--agents", "distinct"]),
        (["--agents", "ppo-belief"], ["--agents", "ppo-belief", "trained on ElectroLoc-v0"]),
    ],
)
def test_bad_options_are_one_line_before_any_work(capsys, monkeypatch, tmp_path, argv, words):
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(tmp_path / "o.json"), *argv], *words)


def test_bad_output_paths_are_refused_before_any_work(capsys, monkeypatch, tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--resume"], "--resume", "--out")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(a_file / "o.json")], "--out", "is a file")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(tmp_path)], "--out", "directory")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(tmp_path / "o.txt")], "--out", ".json")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--figure", str(tmp_path / "f.xyz")], "--figure", "'.xyz'")
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--figure", str(a_file / "f.png")], "--figure", "is a file")
    read_only = tmp_path / "ro"
    read_only.mkdir()
    read_only.chmod(0o555)
    try:  # root writes into any folder, but not into /proc
        where = Path("/proc") if hasattr(os, "geteuid") and os.geteuid() == 0 else read_only
        _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(where / "o.json")], "--out", "not writable")
    finally:
        read_only.chmod(0o755)


@pytest.mark.parametrize(
    "content, words",
    [
        ('{"cells": 3', ["not JSON"]),
        ("[1, 2]", ["not a speed sweep"]),
        ('{"settings": {}, "cells": [{"agent": "pursuit"}]}', ["not a speed sweep"]),
        (b"\xff\xfe", ["not JSON"]),
    ],
)
def test_a_damaged_out_is_refused_by_resume(capsys, monkeypatch, tmp_path, content, words):
    out = tmp_path / "o.json"
    (out.write_bytes if isinstance(content, bytes) else out.write_text)(content)
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--out", str(out), "--resume"], "--out", *words)


def test_resume_refuses_a_sweep_of_other_settings(capsys, monkeypatch, tmp_path):
    out = tmp_path / "o.json"
    speed_sweep.main([*QUICK, "--out", str(out)])
    capsys.readouterr()
    kept = out.read_bytes()
    _refused(capsys, monkeypatch, tmp_path, [*QUICK, "--seed", "5", "--out", str(out), "--resume"], "--out", "seed")
    assert out.read_bytes() == kept


def test_an_agent_that_never_loses_its_prey_is_said_in_words(capsys, monkeypatch):
    def cell(agent, speed_mm, seeds, env_kwargs):  # tracks within the capture distance at every speed
        n = len(seeds)
        out = {"agent": agent, "speed_mm": speed_mm, "tracking_error_mm": [2.0] * n, "captured": [True] * n}
        return {**out, "condition": ["fresh-steel-12.7"] * n, "wall_s": 0.0}

    monkeypatch.setattr(speed_sweep, "run_cell", cell)
    result = speed_sweep.main(["--speeds", "0.5", "4", *QUICK[2:]])
    out = capsys.readouterr().out
    assert result["losing_speed_mm"] == {"pursuit": None} and "None" not in out
    assert "pursuit: never lost its prey up to 4 mm per reading" in out
