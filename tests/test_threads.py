"""Threads: what the package starts runs its numeric libraries on the chosen count (one unless chosen).

The count comes from ``--threads``, else ``$ELECTROLOC_THREADS``, else 1 (:mod:`electroloc_gym.utils.runtime`); the CLI
pins itself to it and hands it to the benchmark's worker processes and the training run.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import torch
from threadpoolctl import threadpool_info

from electroloc_gym.utils.runtime import (
    THREAD_VARS,
    THREADS_VAR,
    chosen_threads,
    pin_threads,
    thread_env,
)


def _threads_now() -> dict[str, object]:
    """What this process's numeric libraries run on: every loaded BLAS/OpenMP pool, torch, numba, the variables."""
    import numba

    return {
        "pools": sorted({int(p["num_threads"]) for p in threadpool_info()}),
        "torch": torch.get_num_threads(),
        "numba": int(numba.config.NUMBA_NUM_THREADS),
        "env": sorted({os.environ.get(v) for v in (*THREAD_VARS, "NUMBA_NUM_THREADS", THREADS_VAR)}),
        "pid": os.getpid(),
    }


def _worker_threads(_spec: int) -> dict[str, object]:
    """A bench worker's report (module level: the spawned worker unpickles it by name)."""
    import numpy  # noqa: F401  (its BLAS pool)
    import torch as worker_torch  # noqa: F401  (its OpenMP pool, loaded after the initializer ran)

    return _threads_now()


@pytest.fixture
def restore_threads(monkeypatch):
    """Every variable :func:`pin_threads` writes is restored afterwards, and this process is pinned to 1 again."""
    for var in thread_env(1):
        if var in os.environ:
            monkeypatch.setenv(var, os.environ[var])
        else:
            monkeypatch.delenv(var, raising=False)
    monkeypatch.delenv(THREADS_VAR, raising=False)
    yield monkeypatch
    pin_threads(1)


def test_the_count_is_the_argument_then_the_variable_then_one(restore_threads) -> None:
    assert chosen_threads() == 1
    restore_threads.setenv(THREADS_VAR, "3")
    assert chosen_threads() == 3
    assert chosen_threads(2) == 2  # --threads wins over the variable
    restore_threads.setenv("OMP_NUM_THREADS", "8")  # a job's generic setting is not the package's choice
    assert chosen_threads() == 3
    assert thread_env(2) == {**dict.fromkeys(THREAD_VARS, "2"), "NUMBA_NUM_THREADS": "2", THREADS_VAR: "2"}


@pytest.mark.parametrize("bad", ["0", "-1", "two", "1.5", "100000", "²", "٢", "1_0", " 2"])  # ASCII digits only
def test_a_bad_variable_is_one_error_naming_it(restore_threads, bad) -> None:
    restore_threads.setenv(THREADS_VAR, bad)
    with pytest.raises(ValueError, match=rf"{THREADS_VAR} must be an integer in \[1, 1024\]"):
        chosen_threads()


@pytest.mark.parametrize("bad", [0, True, 2.0, "2"])
def test_a_bad_argument_is_one_error_naming_it(bad) -> None:
    with pytest.raises(ValueError, match=r"threads must be an integer in \[1, 1024\]"):
        chosen_threads(bad)
    assert chosen_threads(np.int64(2)) == 2  # a numpy integer is the int it holds, as for every integer setting


def test_pin_threads_sets_every_pool_of_the_process(restore_threads) -> None:
    assert pin_threads(2) == 2
    now = _threads_now()
    assert now["pools"] == [2] and now["torch"] == 2 and now["numba"] == 2 and now["env"] == ["2"]
    pin_threads()  # the variable it wrote is this process's choice from now on
    assert _threads_now()["torch"] == 2
    assert pin_threads(1) == 1 and _threads_now()["pools"] == [1] and torch.get_num_threads() == 1


def test_the_cli_runs_on_the_chosen_count(restore_threads, capsys) -> None:
    from electroloc_gym.bench import bench_command as bench_cli
    from electroloc_gym.cli import main

    seen: list[dict[str, object]] = []
    restore_threads.setattr(bench_cli, "run", lambda args: seen.append(_threads_now()) or 0)
    assert main(["bench", "--agents", "rnd-wlk"]) == 0
    assert seen[-1]["pools"] == [1] and seen[-1]["torch"] == 1 and seen[-1]["env"] == ["1"]
    assert main(["bench", "--agents", "rnd-wlk", "--threads", "2"]) == 0
    assert seen[-1]["pools"] == [2] and seen[-1]["torch"] == 2 and seen[-1]["env"] == ["2"]
    pin_threads(1)
    restore_threads.setenv(THREADS_VAR, "2")
    assert main(["bench", "--agents", "rnd-wlk"]) == 0
    assert seen[-1]["pools"] == [2] and seen[-1]["torch"] == 2
    restore_threads.setenv(THREADS_VAR, "many")
    assert main(["bench"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "electroloc: error: ELECTROLOC_THREADS must be an integer in [1, 1024], got 'many'"
    ]
    restore_threads.delenv(THREADS_VAR)
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "--threads", "0"])
    assert exit_info.value.code == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "--threads" in line and "[1, 1024]" in line


@pytest.mark.parametrize("threads", [None, 2])
def test_bench_workers_run_on_the_callers_count(restore_threads, threads) -> None:
    from electroloc_gym.bench.backends import ProcessBackend

    if threads is not None:
        restore_threads.setenv(THREADS_VAR, str(threads))
    want = threads or 1
    reports = [r for _, r in ProcessBackend(workers=2).run_trials([0, 1], _worker_threads)]
    assert len(reports) == 2 and all(r["pid"] != os.getpid() for r in reports)
    for r in reports:
        assert r["pools"] == [want] and r["torch"] == want and r["numba"] == want, r
        assert r["env"] == [str(want)], r


def test_one_worker_runs_in_this_process_and_gives_back_its_counts(restore_threads) -> None:
    """One worker runs the trials in this process on the workers' count (results do not depend on the worker
    count), then gives the caller its own counts back: a library call (``bench.run``) changes no global setting."""
    from threadpoolctl import threadpool_limits

    from electroloc_gym.bench.backends import ProcessBackend

    threadpool_limits(3)
    torch.set_num_threads(3)
    env_before = {v: os.environ.get(v) for v in thread_env(1)}
    [(_, during)] = list(ProcessBackend(workers=1).run_trials([0], _worker_threads))
    assert during["pid"] == os.getpid() and during["torch"] == 1 and during["env"] == ["1"], during
    assert 1 in during["pools"] and 3 not in during["pools"], during
    assert torch.get_num_threads() == 3 and 3 in {int(p["num_threads"]) for p in threadpool_info()}
    assert {v: os.environ.get(v) for v in thread_env(1)} == env_before


def test_the_training_run_starts_on_the_chosen_count(restore_threads) -> None:
    from electroloc_gym.train.run import zoo_argv

    def num_threads(argv: list[str]) -> str:
        return argv[argv.index("--num-threads") + 1]

    assert num_threads(zoo_argv("ppo", "ElectroLoc-v0", 1)) == "1"
    assert num_threads(zoo_argv("ppo", "ElectroLoc-v0", 1, threads=3)) == "3"
    restore_threads.setenv(THREADS_VAR, "2")
    assert num_threads(zoo_argv("ppo", "ElectroLoc-v0", 1)) == "2"
