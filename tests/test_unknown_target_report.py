"""experiments/unknown_target/unknown_target_report.py reads a bench folder as ``--resume`` reads it: its
config.json and its records through their schemas; a folder it cannot read is one line naming the file, and a
damaged record is set aside and named."""

from __future__ import annotations

import runpy
import shutil
import sys
from pathlib import Path

import pytest

from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.registry import task_entry

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "experiments" / "unknown_target" / "unknown_target_report.py"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A tiny unknown-target run: two agents, two conditions, two trials each."""
    out = tmp_path_factory.mktemp("unknown") / "bench"
    config = BenchConfig(
        agents=("rnd-wlk", "min-var"),
        conditions=("fresh-steel-12.7", "salt-delrin-38.1"),
        trials=2,
        env_id=task_entry("unknown").env_id,
        sensor_model="analytic",
        n_particles=300,
    )
    run_benchmark(config, out, backend="serial", progress=False, log=None)
    return out


#: (the damage to a copy of the run, the file the one error line names; None: the figure is written)
DAMAGES = [
    ("none", None),
    ("record-garbage", None),  # set aside and named; the figure of the other records
    ("config-garbage", "config.json"),
    ("config-list", "config.json"),
    ("config-missing-key", "config.json"),
    ("config-missing", "config.json"),
    ("trials-missing", "trials.jsonl"),
    ("folder-missing", ""),
]


@pytest.mark.parametrize("damage, named", DAMAGES, ids=[d for d, _ in DAMAGES])
def test_the_report_reads_a_run_through_its_schemas(run, tmp_path, monkeypatch, capsys, damage, named) -> None:
    folder = tmp_path / "bench"
    shutil.copytree(run, folder)
    config = folder / "config.json"
    {
        "none": lambda: None,
        "record-garbage": lambda: (folder / "trials.jsonl").write_bytes(
            (folder / "trials.jsonl").read_bytes() + b"%%%\n"
        ),
        "config-garbage": lambda: config.write_text("{[garbage"),
        "config-list": lambda: config.write_text("[1, 2]"),
        "config-missing-key": lambda: config.write_text(config.read_text().replace('"seed"', '"sead"')),
        "config-missing": config.unlink,
        "trials-missing": (folder / "trials.jsonl").unlink,
        "folder-missing": lambda: shutil.rmtree(folder),
    }[damage]()
    png = tmp_path / "figure.png"
    monkeypatch.setattr(sys, "argv", [str(SCRIPT), str(folder), "--out", str(png)])
    capsys.readouterr()
    if named is None:
        runpy.run_path(str(SCRIPT), run_name="__main__")
        out, err = capsys.readouterr()
        assert png.stat().st_size > 0 and f"wrote {png}" in out
        aside = [line for line in err.splitlines() if line.startswith("unknown_target_report: set aside ")]
        assert len(aside) == (damage == "record-garbage") and all(f"{folder / 'trials.jsonl'}:" in a for a in aside)
        return
    with pytest.raises(SystemExit) as exc:
        runpy.run_path(str(SCRIPT), run_name="__main__")
    lines = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(lines) == 1 and not png.exists(), lines
    assert lines[0].startswith(f"unknown_target_report: error: {folder / named if named else folder}"), lines
