"""Subprocess smoke tests of the `electroloc` console script's foundation commands."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from cli_inproc import run_cli as run_inproc

from electroloc_gym.contract.params import MIN_OBSERVATION_CAP
from electroloc_gym.world.conditions import PAPER_TABLE3_THEORY_MM, PRESET_NAMES

ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def run_cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """``python -m electroloc_gym.cli ARGS`` as a real process: the console's smoke tests (eev, demo) and the
    process-only checks; what a command says and does is checked in this process (``cli_inproc``)."""
    return subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", *args], capture_output=True, text=True, env=ENV, timeout=timeout
    )


def test_detect_table_prints_paper_columns() -> None:
    out = run_inproc("detect")
    assert out.returncode == 0, out.stderr
    for name in PRESET_NAMES:
        assert name in out.stdout
    assert "paper theory" in out.stdout and "paper measured" in out.stdout
    assert "not reproducible" in out.stdout  # the 38.1 mm discrepancy is flagged


def test_detect_json_small_spheres_within_1p5_mm() -> None:
    out = run_inproc("detect", "--json")
    assert out.returncode == 0, out.stderr
    rows = {r["condition"]: r for r in json.loads(out.stdout)}
    assert set(rows) == set(PRESET_NAMES)
    for name, r in rows.items():
        assert r["paper_theory_mm"] == PAPER_TABLE3_THEORY_MM[name]
        if name.endswith("12.7"):
            assert abs(r["model_mm"] - r["paper_theory_mm"]) <= 1.5
        assert r["model_fitted_mm"] >= r["paper_measured_mm"] - 0.05


@pytest.mark.parametrize("condition", ["fresh-steel-12.7", "salt-delrin-38.1"])
def test_eev_writes_png(tmp_path, condition: str) -> None:
    out_file = tmp_path / "eev.png"
    out = run_cli("eev", "--condition", condition, "--out", str(out_file))
    assert out.returncode == 0, out.stderr
    assert out_file.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]  # atomic write left no temp file


def test_demo_writes_png(tmp_path) -> None:
    out_file = tmp_path / "demo.png"
    out = run_cli("demo", "--sensor-model", "analytic", "--out", str(out_file))
    assert out.returncode == 0, out.stderr
    assert out_file.stat().st_size > 10_000
    assert "observations" in out.stdout


def test_bad_condition_is_a_clear_usage_error() -> None:
    out = run_inproc("eev", "--condition", "fresh-gold-12.7")
    assert out.returncode == 2
    assert "invalid choice" in out.stderr and "--condition" in out.stderr


def test_console_script_entry_point() -> None:
    from electroloc_gym.cli import main

    assert main(["detect", "--json"]) == 0


@pytest.mark.parametrize("command", [[], ["bench"], ["detect"], ["eev"], ["demo"]])
def test_help_is_plain_text_with_defaults(command) -> None:
    out = run_inproc(*command, "--help")
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())  # line wrapping depends on the terminal width
    assert "``" not in text and ":func:" not in text and ":mod:" not in text
    assert "(default: None)" not in text and "(default: False)" not in text
    if command == ["bench"]:
        for default in (
            "--trials TRIALS",
            "(default: 50)",
            "(default: 0)",
            "(default: bench_out)",
            "(default: calibrated,",
            "2500 as the paper; unknown-target: 5000",
            "35 as the paper",
            "(default: all)",
            "(default: process)",
            "examples:",
            "ppo-belief",
        ):
            assert default in text, default
    if command == ["eev"]:
        assert "(default: eev.png)" in text and "(default: fresh-steel-12.7)" in text
    if command == ["demo"]:
        assert "(default: demo.png)" in text


# ---- bad input: one line naming the option, exit 2, nothing written ----------------------------------------
def _one_line_error(capsys, argv, tmp_path, option: str) -> str:
    from electroloc_gym.cli import main

    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(SystemExit) as exc_info:
        raise SystemExit(main(argv))
    assert exc_info.value.code == 2, argv
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "error" in lines[0] and option in lines[0], (argv, err)
    assert "Traceback" not in err and not out
    assert sorted(p.name for p in tmp_path.iterdir()) == before, argv  # nothing written
    return lines[0]


@pytest.mark.parametrize(
    "argv,option",
    [
        (["eev", "--out", "{tmp}"], "--out"),
        (["eev", "--out", ""], "--out"),
        (["eev", "--out", "{tmp}/e.xyz"], "--out"),
        (["eev", "--out", "{tmp}/FILE/e.png"], "--out"),
        (["detect", "--plot", "{tmp}/p.xyz"], "--plot"),
        (["demo", "--seed", "-1"], "--seed"),
        (["demo", "--seed", "1_0"], "--seed"),  # ASCII digits, as every integer option takes them
        # the same file (or, where matplotlib writes no GIF figure, its suffix): named by the flag either way
        (["demo", "--out", "{tmp}/X.gif", "--gif", "{tmp}/X.gif"], "error: --out "),
        (
            [
                "bench",
                "--agents",
                "lookahead[n_options=256,continuations=256,branches=1024,n_particles=100000]",
                "--out",
                "{tmp}/b",
            ],
            "lookahead[n_options=256",
        ),
        (["bench", "--trials", "1000000000000", "--out", "{tmp}/b"], "--trials"),
        (["bench", "--agents", "", "--out", "{tmp}/b"], "--agents names no agent (got ''); leave it out"),
        (["bench", "--agents", ",", "--out", "{tmp}/b"], "--agents"),
        (["bench", "--agents", "lookahead[depth=2,depth=3]", "--out", "{tmp}/b"], "'depth' given twice"),
        (["bench", "--env", "unknown-target", "--agents", "ppo-belief", "--out", "{tmp}/b"], "ppo-belief"),
        (["bench", "--agents", "ppo-belief-unknown", "--out", "{tmp}/b"], "trained on ElectroLocUnknownTarget-v0"),
        (["bench", "--env", "dynamic-gain", "--agents", "ppo-belief-global", "--out", "{tmp}/b"], "ppo-belief-global"),
        (["bench", "--env", "dynamic-gain", "--agents", "ppo-belief", "--out", "{tmp}/b"], "gain_levels"),
    ],
)
def test_issue_reproducers_are_one_line(capsys, tmp_path, argv, option) -> None:
    (tmp_path / "FILE").write_text("a file")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if any("ppo-" in a for a in argv):
        pytest.importorskip("torch")
    _one_line_error(capsys, argv, tmp_path, option)


def test_detect_json_is_strict_and_nan_rows_have_no_branch_label() -> None:
    for factor in ("1", "1/10000"):  # the ends of the range: every row computed
        proc = run_inproc("detect", "--noise-factor", factor, "--json")
        assert proc.returncode == 0

        def refuse(constant):
            raise AssertionError(f"non-strict JSON constant {constant}")

        data = json.loads(proc.stdout, parse_constant=refuse)
        for row in data["rows"]:
            for signal in ("paper", "fitted"):
                values = (row["zero_crossing_mm"], row[f"{signal}_mm"], row[f"{signal}_quiet_mm"])
                assert (row[f"{signal}_branch"] == "n/a") == (None in values), row


_BENCH_INTS = {
    "--trials": (1, 100_000),
    "--workers": (1, 1024),
    "--max-observations": (MIN_OBSERVATION_CAP, 100_000),
    "--n-particles": (2, 1_000_000),
    "--seed": (0, 2**63 - 1),
}
_CHOICES = {
    ("bench", "--env"),
    ("bench", "--backend"),
    ("bench", "--sensor-model"),
    ("bench", "--signal"),
    ("eev", "--condition"),
    ("eev", "--signal"),
    ("eev", "--env"),
    ("demo", "--condition"),
    ("demo", "--sensor-model"),
}


def _bad_value(draw, command: str, option: str) -> str:
    from hypothesis import strategies as st

    if command == "bench" and option in _BENCH_INTS:
        low, high = _BENCH_INTS[option]
        return str(
            draw(
                st.one_of(
                    st.integers(max_value=low - 1, min_value=-(10**30)),
                    st.integers(min_value=high + 1, max_value=10**30),
                    st.sampled_from(["x", "1.5", "", "1e3", "nan"]),
                )
            )
        )
    if (command, option) in _CHOICES:
        return draw(
            st.text(alphabet="abcxyz-_.", min_size=0, max_size=8).filter(
                lambda t: (
                    t
                    not in ("target", "global", "process", "serial", "ray", "analytic", "calibrated", "fitted", "paper")
                )
            )
        )
    if command == "bench" and option == "--out":  # a folder: a file, under a file, or nothing
        return draw(st.sampled_from(["", "  ", "{tmp}/FILE", "{tmp}/FILE/x"]))
    if option in ("--out", "--plot", "--gif"):  # a figure file
        return draw(st.sampled_from(["", "{tmp}", "{tmp}/FILE/x.png", "{tmp}/x.xyz", "{tmp}/x"]))
    if option == "--noise-factor":
        return draw(st.sampled_from(["0", "-1", "x", "1/0", "inf", "nan", "", "1e-320", "1e-9", "1e308", "2"]))
    if option == "--seed":
        return str(draw(st.one_of(st.integers(max_value=-1, min_value=-(10**30)), st.integers(min_value=2**63))))
    if option == "--agents":
        return draw(
            st.sampled_from(
                [
                    "",
                    ",",
                    "nope",
                    "a[b]",
                    "min-var[x=1]]",
                    "lookahead[depth=2,depth=3]",
                    "no_such_module_h2:f",
                    "min-var[n_voters=-5]",
                    "lookahead[depth=99]",
                ]
            )
        )
    if option == "--conditions":
        return draw(st.sampled_from(["", "nope", "fresh-steel-12.7,fresh-steel-12.7", ","]))
    raise AssertionError(f"no bad values for {command} {option}")


_OPTIONS = [
    ("bench", o)
    for o in (
        "--agents",
        "--conditions",
        "--env",
        "--trials",
        "--seed",
        "--workers",
        "--backend",
        "--sensor-model",
        "--signal",
        "--max-observations",
        "--n-particles",
        "--out",
    )
]
_OPTIONS += [("eev", o) for o in ("--condition", "--signal", "--out", "--env")]
_OPTIONS += [("demo", o) for o in ("--condition", "--sensor-model", "--seed", "--out", "--gif")]
_OPTIONS += [("detect", o) for o in ("--noise-factor", "--plot")]


def test_every_option_bad_values_are_one_line(capsys, tmp_path) -> None:
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    (tmp_path / "FILE").write_text("a file")

    @settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck))
    @given(data=st.data())
    def check(data) -> None:
        command, option = data.draw(st.sampled_from(_OPTIONS), label="option")
        value = _bad_value(data.draw, command, option).replace("{tmp}", str(tmp_path))
        argv = [command, option, value]
        if command == "bench":
            argv += ["--out", str(tmp_path / "never")] if option != "--out" else []
            argv += ["--agents", "rnd-wlk"] if option != "--agents" else []
        if command == "demo" and option == "--gif":
            argv += ["--out", str(tmp_path / "never.png")]
        name = "--plot" if option == "--plot" else option
        if option in ("--gif",) and value.endswith("/x"):
            name = "gif"
        line = _one_line_error(capsys, argv, tmp_path, "")
        assert name.lstrip("-") in line or option in line or "agent" in line or "condition" in line, (argv, line)

    check()


@pytest.mark.parametrize(
    "argv, patch, says",
    [
        (
            ["bench", "--agents", "rnd-wlk", "--out", "{tmp}/b"],
            "electroloc_gym.bench.bench_command.run_benchmark",
            "electroloc bench: interrupted; the finished trials are in {tmp}/b/trials.jsonl (--resume continues)",
        ),
        (
            ["dataset", "--agent", "rnd-wlk", "--episodes", "1"],
            "electroloc_gym.dataset.collect.build_dataset",
            "electroloc dataset: interrupted; nothing is lost: an unfinished dataset keeps its episodes (--resume "
            "continues it) and a --force run leaves the dataset it was replacing as it was",
        ),
    ],
    ids=["bench", "dataset"],
)
def test_ctrl_c_is_one_line_saying_what_is_kept_and_exit_130(argv, patch, says, tmp_path, capsys, monkeypatch) -> None:
    """Ctrl-C during a run: exit 130 and one line saying what is kept and how the run continues, no traceback."""
    from electroloc_gym.cli import main

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    monkeypatch.setattr(patch, interrupted)
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 130
    assert capsys.readouterr().err.strip().splitlines() == [says.replace("{tmp}", str(tmp_path))]
