"""The speed sweep's small run: every cell, the summary, the losing speed and a resumed run."""

from __future__ import annotations

import json

import numpy as np
import speed_sweep


def test_a_small_sweep_summarises_and_resumes(tmp_path) -> None:
    out = tmp_path / "sweep.json"
    argv = ["--speeds", "1", "12", "--agents", "pursuit", "--trials", "2", "--sensor-model", "analytic"]
    argv += ["--n-particles", "200", "--out", str(out), "--figure", str(tmp_path / "fig.png")]
    result = speed_sweep.main(argv)
    rows = result["rows"]
    assert [(r["agent"], r["speed_mm"], r["trials"]) for r in rows] == [("pursuit", 1.0, 2), ("pursuit", 12.0, 2)]
    for r, c in zip(rows, result["cells"], strict=True):
        assert r["median_mm"] == np.median(c["tracking_error_mm"]) and r["capture_rate"] == np.mean(c["captured"])
    assert (tmp_path / "fig.png").stat().st_size > 0
    kept = json.loads(out.read_text())
    again = speed_sweep.main([*argv, "--resume", "--speeds", "1", "12", "20"])
    assert again["cells"][:2] == kept["cells"] and len(again["cells"]) == 3  # only the new speed ran
    assert again["settings"]["speeds"] == [1.0, 12.0, 20.0]


def test_the_losing_speed_is_the_first_median_above_the_capture_distance() -> None:
    rows = [{"agent": "a", "speed_mm": v, "median_mm": m} for v, m in ((1.0, 3.0), (2.0, 11.0), (4.0, 9.0))]
    assert speed_sweep.losing_speed(rows, "a") == 2.0
    assert speed_sweep.losing_speed(rows[:1], "a") is None
