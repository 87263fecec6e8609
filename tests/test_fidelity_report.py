"""experiments/fidelity/fidelity_report.py on a bench folder written now (docs/fidelity.md's command).

The report reads a folder as ``--resume`` does (the current record keys, ``readings``) and summarises it with
the package's summary, so a folder of today and the stored reference run (older key names) read alike.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

from tiny_bench_run import AGENTS, TINY, run_tiny

ROOT = Path(__file__).resolve().parents[1]


def _report_module():
    spec = importlib.util.spec_from_file_location("fidelity_report", ROOT / "experiments/fidelity/fidelity_report.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_the_report_runs_on_a_bench_folder_written_now(tmp_path, capsys) -> None:
    out = tmp_path / "bench"
    run_tiny(out)
    records = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines()]
    assert all("readings" in r and "observations" not in r for r in records)  # today's key
    report = _report_module()
    capsys.readouterr()
    report.main(["--bench", str(out), "--global", str(out)])
    text, err = capsys.readouterr()
    assert not err
    n = TINY["trials"]
    assert f"### Table 4, default simulation (`{out}`, seed {TINY['seed']}, {n} trials)" in text
    assert "### Starts inside and outside the detection region, default simulation" in text
    assert "### Table 1 (zero-crossing), default simulation" in text
    assert "### Table 2" in text
    # the inside/outside section: the agent's median readings inside and outside, from the records' `readings`
    section = text.split("### Starts inside and outside the detection region")[1].split("###")[0]
    (row,) = [line for line in section.splitlines() if line.startswith(f"| {AGENTS[0]} | ")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    inside = [report._inside(r, "fitted") for r in records if r["agent"] == AGENTS[0]]
    readings = [r["readings"] for r in records if r["agent"] == AGENTS[0]]
    assert cells[1].startswith(f"{sum(inside)}/{len(inside)} ")
    outside = sorted(x for x, i in zip(readings, inside) if not i)
    assert cells[3] == (f"{(outside[(len(outside) - 1) // 2] + outside[len(outside) // 2]) / 2:g}" if outside else "–")
    # rnd-wlk's paper counts hold no count of two trials: the small-run mark, never [2–1]
    assert f"[none of {n}] –" in text and "[2–1]" not in text


def test_the_report_reads_the_stored_reference_run_as_its_summary() -> None:
    report = _report_module()
    folder = ROOT / "experiments/reference/bench-global"
    rows, records, config = report._load(str(folder))
    assert rows == json.loads((folder / "summary.json").read_text(encoding="utf-8"))["rows"]
    assert len(records) == 150 and all("readings" in r for r in records)  # stored as `observations`
    assert config["env_id"] == "ElectroLocGlobal-v0"
