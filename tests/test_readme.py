"""The README's first lines give the two fresh-machine commands, and CI runs the test one verbatim."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands() -> list[str]:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()[:12]
    return [ln.strip() for ln in lines if ln.strip().startswith("python3 -m venv")]


def test_readme_starts_with_two_commands() -> None:
    cmds = _readme_commands()
    assert len(cmds) == 2
    assert "electroloc bench" in cmds[0]
    assert "pytest" in cmds[1]
    assert all("-c constraints.txt" in c for c in cmds)  # CPU torch pin


def test_ci_runs_the_readme_test_command() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert _readme_commands()[1] in ci.splitlines()


def test_constraints_pin_cpu_torch() -> None:
    assert "torch==2.13.0" in (ROOT / "constraints.txt").read_text().split()
