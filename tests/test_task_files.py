"""A task is one place: each built-in task occupies at most two package files, its task module and its table entry.

A file *occupies* a task when it names one of the task's own things, read from its entry (not listed by hand):
its task class, its options, state and metrics declarations, its single and vector env classes, and the module
that holds them (as ``numba_core.track_task``). A name two entries share (the localise family's options, its
env bases) is no task's own. ``utils/moved_paths.py`` is left out: it is the CHANGELOG's table of where old
import paths went, history that must name the old and the new place, not a declaration of the task.
"""

from __future__ import annotations

import re
import sys
from collections import Counter
from pathlib import Path

import pytest

from electroloc_gym.envs.table import BUILTIN_ENVS
from electroloc_gym.registry import ENVS, EnvEntry

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "electroloc_gym"
HISTORY = {"electroloc_gym/utils/moved_paths.py"}
BUILTIN = tuple(e.env_id for e in BUILTIN_ENVS)


def own_names(entry: EnvEntry) -> tuple[set[str], set[str]]:
    """(names, modules) of what ``entry`` declares: its classes, its declarations' names, their modules."""
    task = entry.task_class
    names = {task.__name__, task.Options.__name__, task.State.__name__}
    names |= {c.__name__ for c in (entry.env_class, entry.vector_class) if c is not None}
    modules = {task.__module__} | {c.__module__ for c in (entry.env_class, entry.vector_class) if c is not None}
    for m in modules:
        for name, value in vars(sys.modules[m]).items():
            if value is task.metrics and name.isupper():
                names.add(name)
    return names, modules


def occupied_files(entry: EnvEntry) -> list[str]:
    """The package files that name ``entry``'s own things (module docstring)."""
    shared_names = Counter(n for e in ENVS for n in own_names(e)[0])
    shared_modules = Counter(m for e in ENVS for m in own_names(e)[1])
    names, modules = own_names(entry)
    own = [re.escape(n) for n in names if shared_names[n] == 1]
    own_modules = [m for m in modules if shared_modules[m] == 1]
    pattern = re.compile(
        r"\b(?:"
        + "|".join(own)
        + r")\b"
        + "".join(r"|\b" + re.escape(".".join(m.split(".")[-2:])) + r"\b" for m in own_modules)
    )
    hits = {m.replace(".", "/") + ".py" for m in own_modules}
    for path in PACKAGE.rglob("*.py"):
        rel = str(path.relative_to(ROOT))
        if rel not in HISTORY and pattern.search(path.read_text(encoding="utf-8")):
            hits.add(rel)
    return sorted(hits)


@pytest.mark.parametrize("env_id", BUILTIN)
def test_a_built_in_task_occupies_its_module_and_its_table_entry(env_id: str) -> None:
    entry = next(e for e in ENVS if e.env_id == env_id)
    files = occupied_files(entry)
    module = entry.task_class.__module__.replace(".", "/") + ".py"
    assert files == sorted({module, "electroloc_gym/envs/table.py"}), files


def test_the_count_sees_a_file_that_names_a_task(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The count is not blind: a copy of the package with one more file naming the moving target's options
    counts it."""
    import shutil

    copy = tmp_path / "electroloc_gym"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__", "models"))
    (copy / "envs" / "extra.py").write_text('"""extra: names TrackOptions."""\n', encoding="utf-8")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", copy)
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    entry = next(e for e in ENVS if e.env_id == "ElectroLocTrack-v0")
    assert "electroloc_gym/envs/extra.py" in occupied_files(entry)
    assert len(occupied_files(entry)) == 3
