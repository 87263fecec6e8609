"""The track table: its statistics against their definitions on the kept baseline run, and bad input in one line."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

HERE = Path(__file__).resolve().parent
BASE = HERE.parents[0] / "learned" / "results" / "ElectroLocTrack-v0" / "_baselines" / "bench"
_spec = importlib.util.spec_from_file_location("track_table", HERE / "track_table.py")
table = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("track_table", table)
_spec.loader.exec_module(table)


def test_the_statistics_are_their_definitions(tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.setattr(table, "REPS", 200)  # bootstrap draws: the intervals' containment, not their width, is checked
    out = tmp_path / "t.md"
    assert table.main([str(BASE), "--out", str(out)]) == 0
    rows = json.loads(out.with_suffix(".json").read_text())
    agents = table.load([BASE])
    for name, r in rows.items():
        err = np.concatenate([v[:, 0] for v in agents[name].values()])
        cap = np.concatenate([v[:, 1] for v in agents[name].values()])
        assert r["trials"] == len(err) == 400
        assert r["iqm"] == pytest.approx(stats.trim_mean(err, 0.25))
        assert r["iqm_ci"][0] <= r["iqm"] <= r["iqm_ci"][1]
        assert r["count"] == int(cap.sum()) and r["share_ci"][0] <= r["share"] <= r["share_ci"][1]
    assert "p_improvement" not in rows["min-var"]  # the reference
    ref, rnd = agents["min-var"], agents["rnd-wlk"]
    by_hand = np.mean([(rnd[c][:, 0][:, None] < ref[c][:, 0][None, :]).mean() for c in sorted(ref)])
    assert rows["rnd-wlk"]["p_improvement"] == pytest.approx(by_hand)  # no ties between real-valued errors
    assert "| rnd-wlk | 400 |" in out.read_text() and "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--learned", "x=/no/such/*"], "--learned 'x=/no/such/*': expected LABEL=GLOB"),
        (["--reference", "nobody"], "--reference 'nobody' is not among the agents"),
    ],
)
def test_bad_input_is_one_line(argv, words, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        table.main([str(BASE), "--out", str(tmp_path / "t.md"), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and words in err[-1] and not (tmp_path / "t.md").exists()
