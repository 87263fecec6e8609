"""Output paths: one rule for every command's files and folders, checked before any work.

A name component longer than the file system allows, a symbolic link that leads nowhere anywhere in the
path, and a folder where a real write fails (``/proc``: writable by its permission bits to root) are
refused by :func:`~electroloc_gym.utils.fileio.check_output_path` (files) and
:func:`~electroloc_gym.utils.fileio.check_output_folder` (``--out`` folders) — and so by every command,
in one line and exit status 2, before it draws, times or runs anything.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from tiny_bench_run import TINY_CLI

from electroloc_gym.bench.records import prepare_out_dir
from electroloc_gym.cli import main as cli_main
from electroloc_gym.utils.fileio import check_output_folder, check_output_path

ROOT = Path(__file__).resolve().parents[1]
LINUX = sys.platform.startswith("linux")


def _bad_paths(tmp_path: Path) -> dict[str, tuple[Path, Path, str]]:
    """kind → (a file path, a folder path, a word of the message)."""
    (tmp_path / "gone").symlink_to(tmp_path / "missing")
    kinds = {
        "name over 255 bytes": (tmp_path / ("é" * 130 + ".png"), tmp_path / ("a" * 256), "bytes"),
        "name whose temporary file is too long": (tmp_path / ("a" * 246 + ".png"), None, "bytes"),
        "dangling symlink parent": (tmp_path / "gone" / "x.png", tmp_path / "gone" / "out", "symbolic link"),
        "dangling symlink as the file": (tmp_path / "gone", None, "symbolic link"),
    }
    if LINUX:
        kinds["under /proc"] = (Path("/proc/electroloc-test.png"), Path("/proc/electroloc-test"), "not writable")
    return kinds


def _one_line(capsys, code: int | None, word: str) -> str:
    assert code == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert "Traceback" not in err and word in lines[-1], err
    return lines[-1]


def test_the_bad_kinds_are_refused_by_the_file_and_folder_checks(tmp_path) -> None:
    for kind, (file, folder, word) in _bad_paths(tmp_path).items():
        with pytest.raises(ValueError, match=word) as exc:
            check_output_path("--out", file)
        assert "--out" in str(exc.value) and "\n" not in str(exc.value), kind
        if folder is not None:
            with pytest.raises(ValueError, match=word):
                check_output_folder("--out", folder)
            with pytest.raises(ValueError, match=word):
                prepare_out_dir(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gone"]  # nothing created


def test_good_paths_pass_and_nothing_is_created(tmp_path) -> None:
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    check_output_path("--out", tmp_path / "new" / "deeper" / ("a" * 241))  # the longest name that fits
    check_output_path("--out", tmp_path / "link" / "x.json")  # a link that leads somewhere
    assert check_output_folder("--out", tmp_path / "link" / "new" / ("b" * 255)) == tmp_path / "link" / "new" / (
        "b" * 255
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "real"] and not any((tmp_path / "real").iterdir())


def test_eev_refuses_before_drawing(tmp_path, capsys, monkeypatch) -> None:
    import electroloc_gym.views.eev_maps as eev_maps

    monkeypatch.setattr(eev_maps, "plot_eev", lambda *a, **k: pytest.fail("drew the map before the path check"))
    for kind, (file, _, word) in _bad_paths(tmp_path).items():
        line = _one_line(capsys, cli_main(["eev", "--out", str(file)]), word)
        assert line.startswith("electroloc eev: error: --out"), (kind, line)


def test_bench_refuses_before_any_trial(tmp_path, capsys, monkeypatch) -> None:
    import electroloc_gym.bench.runner as runner

    monkeypatch.setattr(runner, "make_backend", lambda *a, **k: pytest.fail("ran before the --out check"))
    for kind, (_, folder, word) in _bad_paths(tmp_path).items():
        if folder is not None:
            line = _one_line(capsys, cli_main(["bench", *TINY_CLI, "--out", str(folder)]), word)
            assert line.startswith("electroloc bench: error: --out"), (kind, line)


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_device_throughput_refuses_before_timing(tmp_path, capsys, monkeypatch) -> None:
    pytest.importorskip("torch")
    bench = _load(ROOT / "benchmarks" / "device_throughput.py", "output_paths_device_throughput")
    monkeypatch.setattr(bench, "numba_rate", lambda *a: pytest.fail("timed before the path check"))
    monkeypatch.setattr(bench, "torch_rate", lambda *a: pytest.fail("timed before the path check"))
    for kind, (file, _, word) in _bad_paths(tmp_path).items():
        for option in ("--out", "--md"):
            with pytest.raises(SystemExit) as exc:
                bench.main([option, str(file), "--n-envs", "4", "--ppo-n"])
            assert option in _one_line(capsys, exc.value.code, word), kind


def test_an_experiment_script_refuses_before_its_trials(tmp_path, capsys, monkeypatch) -> None:
    script = _load(ROOT / "experiments" / "array" / "commutativity.py", "output_paths_commutativity")
    monkeypatch.setattr(script, "run_trials", lambda *a, **k: pytest.fail("ran trials before the path check"))
    for kind, (file, _, word) in _bad_paths(tmp_path).items():
        with pytest.raises(SystemExit) as exc:
            script.main(["--out", str(file), "--trials", "2"])
        assert "--out" in _one_line(capsys, exc.value.code, word), kind


def test_a_path_under_home_is_one_path_for_the_check_the_writes_and_the_reads(tmp_path, monkeypatch, capsys) -> None:
    """``~`` in a folder or file a command takes (a shell leaves ``--out=~/b`` as typed) is the home folder for the
    check, the writes and what the command reads back: bench's command line and Python API, train's rl-zoo3 command,
    the dataset's reference run, a figure's file — never a folder named ``~`` in the working directory.
    """
    from electroloc_gym.bench import run
    from electroloc_gym.dataset.seed_protocol import reference_scores
    from electroloc_gym.train.run import zoo_argv

    home, cwd = tmp_path / "home", tmp_path / "cwd"
    home.mkdir(), cwd.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(cwd)
    assert cli_main(["bench", *TINY_CLI, "--backend", "serial", "--out", "~/b"]) == 0
    assert "| rnd-wlk |" in capsys.readouterr().out  # the table read back and printed
    assert (home / "b" / "table.md").is_file()
    result = run(
        "rnd-wlk", conditions="fresh-steel-12.7", trials=1, n_particles=100, sensor_model="analytic", out="~/c"
    )
    assert result.out == home / "c" and (home / "c" / "table.md").is_file()
    argv = zoo_argv("ppo", "ElectroLoc-v0", 0, log_folder="~/logs")
    assert argv[argv.index("--log-folder") + 1] == str(home / "logs")
    with pytest.raises(ValueError, match="must hold rnd-wlk and one of"):  # read: a run without a planner
        reference_scores("~/b", "ElectroLoc-v0")
    assert cli_main(["eev", "--out", "~/eev.png"]) == 0  # an output file: checked and written there too
    assert (home / "eev.png").is_file()
    assert not (cwd / "~").exists()
