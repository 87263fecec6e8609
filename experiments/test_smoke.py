"""A smoke test of every experiment script: it starts, parses ``--help`` and exits 0.

A change to the library that breaks a study's imports or its command line fails here, in the default
suite, without running the study itself (its own tests and ``-m slow`` do that).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SCRIPTS = sorted(
    p for p in HERE.glob("*/*.py") if "__main__" in p.read_text(encoding="utf-8") and not p.name.startswith("test_")
)


def test_every_study_folder_has_a_script() -> None:
    folders = {p.parent.name for p in SCRIPTS}
    assert {"learned", "offline", "fidelity", "array", "distractors", "gain", "planners", "unknown_target"} <= folders


@pytest.mark.parametrize("script", SCRIPTS, ids=[str(p.relative_to(HERE)) for p in SCRIPTS])
def test_the_script_starts(script: Path) -> None:
    proc = subprocess.run(
        [sys.executable, str(script), "--help"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "usage:" in proc.stdout
