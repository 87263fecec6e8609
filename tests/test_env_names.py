"""Nothing above the env table compares an env id, a task name or a bench row's name to a literal: every
per-env fact is read from the table (electroloc_gym.registry)."""

from __future__ import annotations

import ast
from pathlib import Path

from electroloc_gym.registry import ENVS

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("electroloc_gym", "benchmarks", "experiments", "examples")


def _names() -> set[str]:
    names: set[str] = set()
    for e in ENVS:
        names |= {e.env_id, e.task, *(b.name for b in e.bench)}
        if e.map_condition is not None:
            names.add(e.map_condition)
    return names


def _literals(node: ast.expr) -> list[object]:
    if isinstance(node, ast.Constant):
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [x.value for x in node.elts if isinstance(x, ast.Constant)]
    return []


def env_name_comparisons(path: Path, names: set[str]) -> list[str]:
    """``file:line`` of every comparison of an env name literal in ``path``."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Compare) and any(
            v in names for c in (node.left, *node.comparators) for v in _literals(c) if isinstance(v, str)
        ):
            where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            out.append(f"{where}:{node.lineno}: {ast.unparse(node)}")
    return out


def test_no_code_compares_an_env_name() -> None:
    names = _names()
    found = [
        hit
        for folder in SCANNED
        for p in sorted((ROOT / folder).rglob("*.py"))
        if p.name != "registry.py" and not p.name.startswith("test_")  # tests name the envs they test
        for hit in env_name_comparisons(p, names)
    ]
    assert found == []


def test_the_scan_finds_a_comparison(tmp_path: Path) -> None:
    f = tmp_path / "probe.py"
    f.write_text('if env_id == "ElectroLocGlobal-v0" or name in ("target", "x"):\n    pass\n', encoding="utf-8")
    assert len(env_name_comparisons(f, _names())) == 2
