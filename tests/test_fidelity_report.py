"""experiments/fidelity/fidelity_report.py on a bench folder written now (docs/fidelity.md's command).

The report reads a folder as ``--resume`` does (the current record keys, ``readings``) and summarises it with
the package's summary, so a folder of today and the stored reference run (older key names) read alike.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from pathlib import Path

import pytest
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


def _edit_json(path: Path, edit) -> None:
    data = json.loads(path.read_text(encoding="utf-8"))
    edit(data)
    path.write_text(json.dumps(data), encoding="utf-8")


#: (the edit of a copy of the stored reference run, the agents its rows summarise, or the file the one line names)
SUMMARY_CASES = [
    ("none", {"rnd-wlk", "min-var", "ppo-belief-global"}),
    ("summary-for-one-agent", {"min-var"}),  # config.json holds every agent ever asked for; the summary one
    ("summary-without-config", {"rnd-wlk", "min-var", "ppo-belief-global"}),  # then the folder's config.json
    ("summary-garbage", "summary.json"),
    ("summary-utf8", "summary.json"),
    ("summary-list", "summary.json"),
    ("summary-config-list", "summary.json"),
    ("summary-config-missing-key", "summary.json"),
    ("summary-config-trials-text", "summary.json"),
    ("summary-config-unknown-env", "summary.json"),
    ("summary-config-no-agents", "summary.json"),
    ("config-garbage", "config.json"),
    ("config-missing-key", "config.json"),
]


@pytest.mark.parametrize("edit, want", SUMMARY_CASES, ids=[e for e, _ in SUMMARY_CASES])
def test_the_summary_is_read_as_the_run_it_was_written_for(tmp_path, capsys, edit, want) -> None:
    """summary.json's ``config`` (the run it summarises) is read through the run's one schema: the rows are those
    agents' and conditions'; a summary or config that is not one is one line naming the file."""
    folder = tmp_path / "bench-global"
    shutil.copytree(ROOT / "experiments/reference/bench-global", folder)
    summary, config = folder / "summary.json", folder / "config.json"
    {
        "none": lambda: None,
        "summary-for-one-agent": lambda: _edit_json(summary, lambda d: d["config"].update(agents=["min-var"])),
        "summary-without-config": lambda: _edit_json(summary, lambda d: d.pop("config")),
        "summary-garbage": lambda: summary.write_text("{[garbage", encoding="utf-8"),
        "summary-utf8": lambda: summary.write_bytes(b"\xff\xfe"),
        "summary-list": lambda: summary.write_text("[1, 2]", encoding="utf-8"),
        "summary-config-list": lambda: _edit_json(summary, lambda d: d.update(config=[1, 2])),
        "summary-config-missing-key": lambda: _edit_json(summary, lambda d: d["config"].pop("seed")),
        "summary-config-trials-text": lambda: _edit_json(summary, lambda d: d["config"].update(trials="50")),
        "summary-config-unknown-env": lambda: _edit_json(summary, lambda d: d["config"].update(env_id="Nope-v0")),
        "summary-config-no-agents": lambda: _edit_json(summary, lambda d: d["config"].update(agents=[])),
        "config-garbage": lambda: config.write_text("{[garbage", encoding="utf-8"),
        "config-missing-key": lambda: _edit_json(config, lambda d: d.pop("seed")),
    }[edit]()
    report = _report_module()
    if isinstance(want, set):
        rows, _, _ = report._load(str(folder))
        assert {r["agent"] for r in rows} == want
        return
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        report.main(["--bench", str(tmp_path / "no-run"), "--global", str(folder)])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert exc.value.code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"fidelity_report: error: {folder / want}"), lines
