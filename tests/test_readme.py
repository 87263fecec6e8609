"""The README's first lines give the two fresh-machine commands, CI runs the test one verbatim, the example
runs, and the headline table is the reference run's."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
MAX_LINES = 150


def _readme_commands() -> list[str]:
    lines = README.splitlines()[:12]
    return [ln.strip() for ln in lines if ln.strip().startswith("python3 -m venv")]


def test_readme_starts_with_two_commands() -> None:
    main_job, tests = _readme_commands()
    assert "electroloc bench" in main_job and "-c constraints.txt" in main_job  # CPU torch pin
    # -j auto: the sessions that allow it run beside each other (noxfile.py; nox 2026.10.20 was run)
    assert tests.endswith(".venv/bin/nox -j auto") and 'pip install "nox>=2026.10.20"' in tests


def test_ci_runs_the_readme_test_command() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert _readme_commands()[1] in ci.splitlines()


def test_nox_runs_every_default_session() -> None:
    noxfile = (ROOT / "noxfile.py").read_text(encoding="utf-8")
    sessions = re.findall(r"@nox\.session(?:\(.*\))?\ndef (\w+)", noxfile)
    assert set(sessions) == {"tests", "lowest", "rllib", "wheel"}
    listed = re.search(r"nox\.options\.sessions = \[([^\]]*)\]", noxfile).group(1)
    # the docs build (tests) and the type check (rllib) among them
    assert sorted(re.findall(r'"(\w+)"', listed)) == sorted(sessions)


def test_constraints_pin_cpu_torch() -> None:
    assert "torch==2.13.0" in (ROOT / "constraints.txt").read_text().split()


def test_readme_is_short_and_names_the_plugin_agents() -> None:
    assert len(README.splitlines()) <= MAX_LINES
    assert "--agents" in README and "module:factory" in README


def test_the_example_runs(tmp_path: Path) -> None:
    (example,) = [b for b in re.findall(r"```python\n(.*?)```", README, re.S) if "gym.make" in b]
    proc = subprocess.run(
        [sys.executable, "-c", example],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    n_obs, success, error = proc.stdout.splitlines()[0].split()
    assert 1 <= int(n_obs) <= 35 and success in ("True", "False") and float(error) >= 0
    vector_line = proc.stdout.splitlines()[1]
    assert vector_line.startswith("(16,") and vector_line.endswith(" (16,)")


def _all_row(table: str, agent: str) -> list[str]:
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[0].startswith("All conditions") and agent in cells:
            return cells
    raise AssertionError(agent)


def test_the_headline_table_is_the_reference_run() -> None:
    """Each Table-4 and Table-2 headline row's success and medians are the reference run's table.md cells."""
    bench = (ROOT / "experiments" / "reference" / "bench" / "table.md").read_text(encoding="utf-8")
    glob = (ROOT / "experiments" / "reference" / "bench-global" / "table.md").read_text(encoding="utf-8")
    block = README.split("<!-- results:start")[1].split("<!-- results:end")[0]
    rows = [[c.strip() for c in ln.strip("|").split("|")] for ln in block.splitlines() if ln.startswith("| Table")]
    assert rows
    for task, agent, success, _paper, error, _pe, steps, _ps in rows:
        name = agent.split(" ")[0]
        if task.startswith("Table 4"):
            cells = _all_row(bench, name)
            assert cells[3] == success and cells[4].split("/")[1] == error and cells[5].split("/")[1] == steps
        elif task.startswith("Table 2"):
            (cells,) = [
                [c.strip() for c in ln.strip("|").split("|")]
                for ln in glob.splitlines()
                if ln.startswith(f"| {name} |")
            ]
            assert success.startswith(cells[1]) and cells[2].split("/")[1] == error
            assert cells[3].split("/")[1] == steps
        else:
            cells = _all_row(bench, name)
            assert cells[2] == success and steps == cells[6]
