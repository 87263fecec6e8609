"""A smoke test of every experiment script: it starts, parses ``--help`` and exits 0.

A change to the library that breaks a study's imports or its command line fails here, in the default
suite, without running the study itself (its own tests and ``-m slow`` do that). Each script runs in the
test's own process (``runpy``, as ``python script.py --help`` runs it: its folder first on ``sys.path``,
the repository root as the working directory), so the package's modules load once for all of them; the
study modules a script imports from its folder are unloaded after it, so that no script sees another's.
"""

from __future__ import annotations

import runpy
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


def _study_modules() -> set[str]:
    """The loaded modules that live in a study folder (a script's siblings). A path is resolved only where its text
    names this folder: resolving the path of every loaded module costs a quarter of a second.
    """
    return {
        name
        for name, module in list(sys.modules.items())
        if HERE.name in (path := getattr(module, "__file__", None) or "") and HERE in Path(path).resolve().parents
    }


@pytest.mark.parametrize("script", SCRIPTS, ids=[str(p.relative_to(HERE)) for p in SCRIPTS])
def test_the_script_starts(script: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(sys, "argv", [str(script), "--help"])
    monkeypatch.setattr(sys, "path", [str(script.parent), *sys.path])
    before = _study_modules()
    try:
        with pytest.raises(SystemExit) as exited:
            runpy.run_path(str(script), run_name="__main__")
    finally:
        for name in _study_modules() - before:
            del sys.modules[name]
    out, err = capsys.readouterr()
    assert exited.value.code in (0, None), err[-2000:]
    assert "usage:" in out
