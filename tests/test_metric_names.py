"""Nothing above a task names one of its metrics: the record fields, statistics, evaluation columns, score and
curve columns a task declares (``Task.metrics``, electroloc_gym/contract/task_spec.py) appear as string literals
only in the task's own module; the benchmark, training, datasets, examples and experiments read the
declaration (as tests/test_env_names.py does for env names)."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
from electroloc_gym.registry import ENVS

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("electroloc_gym", "benchmarks", "experiments", "examples")

#: Modules that may name a task's metric keys, and why: each is that one task's own, below or beside it.
ALLOWED = {
    # the torch engine's twin of the moving target's and unknown target's tasks (the same info keys, computed on
    # the device; the engines' conformance tests hold them equal)
    "electroloc_gym/engines/torch_core/sim.py": "the torch engine's version of the tasks' info",
    # experiments about one task: their subject is that task's own results
    "experiments/track/speed_sweep.py": "the moving target's speed sweep (its tracking error by speed)",
    "experiments/unknown_target/unknown_target_report.py": "the unknown target's identification report",
    "experiments/unknown_target/radius_posterior.py": "the unknown target's radius estimate study",
}


def metric_names() -> set[str]:
    """Every metric key a registered task declares beyond the paper's shared localisation metrics."""
    shared = set(LOCALIZATION_METRICS.metric_keys())
    names: set[str] = set()
    for e in ENVS:
        names |= set(e.task_class.metrics.metric_keys())
    return names - shared


def task_modules() -> set[Path]:
    return {Path(inspect.getsourcefile(e.task_class)).resolve() for e in ENVS}  # type: ignore[arg-type]


def metric_literals(path: Path, names: set[str]) -> list[str]:
    """``file:line`` of every string literal in ``path`` that is a task's metric key."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
            where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
            out.append(f"{where}:{node.lineno}: {node.value!r}")
    return out


def test_the_declarations_name_their_metrics() -> None:
    names = metric_names()
    assert {"tracking_error_mm", "captured", "capture_rate", "material_correct", "identified_trials"} <= names
    for e in ENVS:
        m = e.task_class.metrics
        assert set(m.statistic_keys) >= {c.key for c in m.columns} - {"successes", "decision_ms_median"}
        assert m.table is None or m.table.count in m.statistic_keys
        assert m.statistics([]) == {}


def test_no_module_above_a_task_names_its_metrics() -> None:
    names, own = metric_names(), task_modules()
    found = [
        hit
        for folder in SCANNED
        for p in sorted((ROOT / folder).rglob("*.py"))
        if p.resolve() not in own
        and not p.name.startswith("test_")  # tests check the tasks' own values
        and str(p.relative_to(ROOT)) not in ALLOWED
        for hit in metric_literals(p, names)
    ]
    assert found == []


def test_the_allowed_modules_exist() -> None:
    assert all((ROOT / p).is_file() for p in ALLOWED)


def test_the_scan_finds_a_metric_name(tmp_path: Path) -> None:
    f = tmp_path / "probe.py"
    f.write_text('x = row["capture_rate"] if "tracking_error_mm" in info else None\n', encoding="utf-8")
    assert len(metric_literals(f, metric_names())) == 2
