"""What the docs say about the code agrees with the code: constants, commands, the scripts' settings and help."""

from __future__ import annotations

import argparse
import importlib.util
import re
import shlex
import sys
from pathlib import Path

import pytest

from electroloc_gym.protocol import FAR_ERROR_MM

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_FENCE = re.compile(r"^```[a-z]*\n(.*?)^```", re.S | re.M)


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8")


# ---- the far-success threshold ------------------------------------------------------------------------------
_FAR = re.compile(
    r"(?:far[ -]success(?:es)?|\*\*?far\*\*?)[^.]{0,120}?(?:more than|>)\s*(\d+(?:\.\d+)?)\s*mm", re.I | re.S
)


def test_every_page_states_the_far_threshold_of_the_code() -> None:
    found = {p.relative_to(ROOT).as_posix(): [float(x) for x in _FAR.findall(_read(p))] for p in PAGES}
    stated = {page: values for page, values in found.items() if values}
    assert {"README.md", "docs/benchmark.md", "docs/glossary.md", "docs/results.md"} <= set(stated), stated
    wrong = {page: values for page, values in stated.items() if any(v != FAR_ERROR_MM for v in values)}
    assert not wrong, f"far successes are > {FAR_ERROR_MM:g} mm (FAR_ERROR_MM); these pages say otherwise: {wrong}"


def test_the_far_success_count_of_the_benchmark_page_runs(tmp_path, capsys) -> None:
    from electroloc_gym.bench.config import BenchConfig
    from electroloc_gym.bench.runner import run_benchmark
    from electroloc_gym.bench.stored_run import read_run_records

    page = _read(ROOT / "docs" / "benchmark.md")
    section = page.split("## Far successes", 1)[1].split("\n## ", 1)[0]
    (code,) = _FENCE.findall(section)
    out = tmp_path / "bench"
    agents = ("rnd-wlk", "min-var")  # the paper's cap: most trials succeed, some far
    config = BenchConfig(
        agents=agents, conditions=("salt-delrin-38.1",), trials=4, seed=5, n_particles=300, sensor_model="analytic"
    )
    run_benchmark(config, out, backend="serial", progress=False, log=None)
    exec(compile(code.replace('"results/bench"', repr(str(out))), "docs/benchmark.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    records = read_run_records(out).records
    want = []
    for agent in agents:
        ok = [r for r in records if r["agent"] == agent and r["success"]]
        if ok:
            far = sum(r["error_mm"] > FAR_ERROR_MM for r in ok)
            want.append(f"{agent}: {far} of {len(ok)} successes end > {FAR_ERROR_MM:g} mm from the target")
    assert sorted(lines) == sorted(want) and len(want) == len(agents)
    assert any(int(line.split(": ")[1].split()[0]) > 0 for line in want)  # a far success is counted


# ---- commands ---------------------------------------------------------------------------------------------
def test_the_readme_names_every_command() -> None:
    from electroloc_gym.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    sentence = _read(ROOT / "README.md").split("Command line:", 1)[1].split("each with `--help`", 1)[0]
    named = set(re.findall(r"`(?:electroloc )?([a-z]+)`", sentence))
    assert named == set(sub.choices), (named, set(sub.choices))


def test_a_resume_in_the_benchmark_page_continues_a_run_written_above_it() -> None:
    (first, *_) = _FENCE.findall(_read(ROOT / "docs" / "benchmark.md"))
    written: set[str] = set()
    resumed = []
    for line in first.splitlines():
        words = shlex.split(line, comments=True)
        if "--out" not in words:
            continue
        out = words[words.index("--out") + 1]
        if "--resume" in words:
            resumed.append(out)
            assert out in written, f"{line!r} resumes {out}, which no command above writes"
        else:
            written.add(out)
    assert resumed


# ---- docs/fidelity.md and its scripts ---------------------------------------------------------------------
def test_the_decision_time_paragraph_states_the_command_it_ran() -> None:
    page = _read(ROOT / "docs" / "fidelity.md")
    (paragraph,) = [p for p in page.split("\n\n") if p.startswith("**Decision time**")]
    states = re.search(r"median over (\d+) belief states", paragraph)
    command = re.search(r"`python benchmarks/minvar\.py --states (\d+)`", paragraph)
    assert states and command and states.group(1) == command.group(1), paragraph
    assert f"python benchmarks/minvar.py --states {states.group(1)}" in page.split("## The tables")[0].split("```")[-2]


def test_the_coverage_factor_is_the_codes_everywhere() -> None:
    from electroloc_gym.world.conditions import coverage_signal_multiplier

    k = f"{coverage_signal_multiplier():.2f}"
    texts = {
        "docs/fidelity.md": _read(ROOT / "docs" / "fidelity.md"),
        "signal_scan.py": _read(ROOT / "experiments" / "fidelity" / "signal_scan.py"),
    }
    stated = {name: set(re.findall(r"\b8\.6\d\b", text)) for name, text in texts.items()}
    assert stated["docs/fidelity.md"] == {k}, stated
    assert stated["signal_scan.py"] <= {k}, stated


# ---- the examples' --help ---------------------------------------------------------------------------------
def _load_example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", ROOT / "examples" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_ppo_minimal_help_describes_every_option_and_its_default(capsys) -> None:
    parser = _load_example("ppo_minimal").build_parser()
    text = " ".join(parser.format_help().split())
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        assert action.help, f"{action.option_strings} has no help"
        if action.default is not None and not isinstance(action.default, bool):
            assert f"(default: {action.default})" in text, action.option_strings
    assert "(default: None)" not in text
    with pytest.raises(SystemExit):
        parser.parse_args(["--help"])
    capsys.readouterr()
