"""Env ids and agent names are spelled once, in their tables: the package reads every other use from the env
table (electroloc_gym.registry) and the agent registry (electroloc_gym.baselines.agent)."""

from __future__ import annotations

import ast
from pathlib import Path

from electroloc_gym.baselines.agent import AGENT_NAMES
from electroloc_gym.registry import ENV_IDS

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "electroloc_gym"
#: The tables themselves: where the ids and names are declared.
TABLES = {"electroloc_gym/registry.py", "electroloc_gym/envs/table.py", "electroloc_gym/baselines/agent.py"}
#: (file, literal) that stays, and why.
ALLOWED = {
    ("electroloc_gym/bench/tables.py", "rnd-wlk"): "the paper's published Tables 4 and 2, keyed by its controllers",
    ("electroloc_gym/bench/tables.py", "min-var"): "the paper's published Tables 4 and 2, keyed by its controllers",
    ("electroloc_gym/bench/tables.py", "ElectroLoc-v0"): "table.md's title for a summary that names no env (to "
    "read registry.PAPER_ENV_ID)",
}


def _docstrings(tree: ast.Module) -> set[int]:
    """ids of the module's, classes' and functions' docstring nodes."""
    out = set()
    for n in ast.walk(tree):
        if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body:
            first = n.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _name_declarations(tree: ast.Module) -> set[int]:
    """ids of the string values of ``name = "..."`` in class bodies (an agent class declares its own name)."""
    out = set()
    for cls in ast.walk(tree):
        if isinstance(cls, ast.ClassDef):
            for stmt in cls.body:
                if (
                    isinstance(stmt, ast.Assign)
                    and [getattr(t, "id", None) for t in stmt.targets] == ["name"]
                    and isinstance(stmt.value, ast.Constant)
                ):
                    out.add(id(stmt.value))
    return out


def table_literals(path: Path, values: set[str]) -> list[tuple[str, int, str]]:
    """(file, line, literal) of every string literal in ``path`` equal to one of ``values``, docstrings and a
    class's ``name = "..."`` left out.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skipped = _docstrings(tree) | _name_declarations(tree)
    where = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)
    return [
        (where, n.lineno, n.value)
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in values and id(n) not in skipped
    ]


def _values() -> set[str]:
    return set(ENV_IDS) | set(AGENT_NAMES)


def _package_hits() -> list[tuple[str, int, str]]:
    return [
        hit
        for p in sorted(PACKAGE.rglob("*.py"))
        if str(p.relative_to(ROOT)) not in TABLES
        for hit in table_literals(p, _values())
    ]


def test_no_env_id_or_agent_name_literal_outside_the_tables() -> None:
    found = [f"{f}:{line}: {v!r}" for f, line, v in _package_hits() if (f, v) not in ALLOWED]
    assert found == [], "read these from electroloc_gym.registry / electroloc_gym.baselines.agent:\n" + "\n".join(found)


def test_every_allowed_literal_is_still_there() -> None:
    hits = {(f, v) for f, _, v in _package_hits()}
    assert sorted(set(ALLOWED) - hits) == []


def test_the_scan_finds_a_literal(tmp_path: Path) -> None:
    f = tmp_path / "probe.py"
    f.write_text(
        '"""Runs min-var on ElectroLoc-v0."""\n'
        "class Probe:\n"
        '    name = "eedi"\n'
        "def run():\n"
        '    env = gym.make("ElectroLocGlobal-v0")\n'
        '    return make_agent("min-var", seed=0), f"{env}[min-var]"\n',
        encoding="utf-8",
    )
    assert sorted((line, v) for _, line, v in table_literals(f, _values())) == [
        (5, "ElectroLocGlobal-v0"),
        (6, "min-var"),
    ]
