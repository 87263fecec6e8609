"""The Ray benchmark backend: the process backend's trials; without Ray or a cluster, one line and exit 2."""

from __future__ import annotations

import json
import socket
import sys
from pathlib import Path

import pytest

from electroloc_gym.bench.backends import BACKENDS, make_backend
from electroloc_gym.bench.ray_backend import RayBackend, check_ray_address
from electroloc_gym.cli import main

pytestmark = pytest.mark.rllib  # Ray; the nox session rllib runs these


def _closed_port() -> int:
    """A local TCP port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _records(out: Path) -> dict[tuple[str, str, int], dict]:
    recs = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines() if line.strip()]

    def timing(k: str) -> bool:  # measured durations differ between runs; everything else must not
        return "_ms" in k or "time" in k or k.endswith("_s") or k in ("worker", "pid")

    return {(r["condition"], r["agent"], r["trial"]): {k: v for k, v in r.items() if not timing(k)} for r in recs}


def test_ray_backend_is_registered_and_validates_options() -> None:
    assert BACKENDS["ray"] is RayBackend
    assert make_backend("ray", 2, address="auto").address == "auto"
    with pytest.raises(ValueError, match="address"):
        RayBackend(address="")
    with pytest.raises(ValueError, match="workers"):
        RayBackend(workers=0)
    with pytest.raises(ValueError, match=r"^names must be None or a mapping of settings \['address', 'backend'\]"):
        RayBackend(names={"out": "--out"})


def test_ray_backend_gives_the_process_backends_trials(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    from electroloc_gym.bench.config import BenchConfig
    from electroloc_gym.bench.runner import run_benchmark

    config = BenchConfig(
        agents=("rnd-wlk",),
        conditions=("fresh-steel-12.7", "salt-delrin-38.1"),
        trials=3,
        n_particles=300,
        max_observations=12,
    )
    run_benchmark(config, tmp_path / "process", workers=2, backend="process", progress=False, log=None)
    run_benchmark(config, tmp_path / "ray", workers=2, backend="ray", progress=False, log=None)
    a, b = _records(tmp_path / "process"), _records(tmp_path / "ray")
    assert len(a) == 6 and a.keys() == b.keys()
    for key in a:
        assert a[key] == b[key], key


#: How the command line names the settings the checks name (the Python API's names are the default).
FLAGS = {"backend": "--backend", "address": "--address"}


def test_ray_check_without_ray_names_the_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray → ImportError
    with pytest.raises(ValueError, match=r"^--backend ray needs Ray.*pip install"):
        check_ray_address(None, FLAGS)
    with pytest.raises(ValueError, match=r"^backend ray needs Ray.*pip install"):
        check_ray_address(None)


def test_ray_check_unreachable_address_names_the_option() -> None:
    pytest.importorskip("ray")
    port = _closed_port()
    for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}"):
        with pytest.raises(ValueError, match=r"^--address .*no Ray cluster answers at 127\.0\.0\.1"):
            check_ray_address(address, FLAGS)
    with pytest.raises(ValueError, match="^--address"):
        check_ray_address("no-port-here:abc", FLAGS)
    with pytest.raises(ValueError, match="^address 'no-port-here:abc'"):
        check_ray_address("no-port-here:abc")
    check_ray_address(None)  # a local Ray: nothing to check beyond the import


@pytest.mark.parametrize("without_ray", [False, True])
def test_ray_bench_bad_paths_exit_2_with_one_line_and_nothing_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, without_ray: bool
) -> None:
    if without_ray:
        monkeypatch.setitem(sys.modules, "ray", None)
        option = "--backend ray"
    else:
        pytest.importorskip("ray")
        option = "--address"
    out = tmp_path / "out"
    code = main(
        [
            "bench",
            "--agents",
            "rnd-wlk",
            "--conditions",
            "fresh-steel-12.7",
            "--trials",
            "1",
            "--backend",
            "ray",
            "--address",
            f"127.0.0.1:{_closed_port()}",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and option in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_ray_check_auto_without_a_cluster_names_the_option(monkeypatch: pytest.MonkeyPatch) -> None:
    services = pytest.importorskip("ray._private.services")

    def no_cluster(*_args: object, **_kwargs: object) -> str:
        raise ConnectionError("Could not find any running Ray instance. Please specify the one to connect to.")

    monkeypatch.setattr(services, "canonicalize_bootstrap_address_or_die", no_cluster)
    with pytest.raises(ValueError, match=r"^--address 'auto': no running Ray cluster found .*ray start --head"):
        check_ray_address("auto", FLAGS)


def test_ray_check_a_port_that_is_not_ray_names_the_option(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("ray")
    import electroloc_gym.bench.ray_backend as rb

    monkeypatch.setattr(rb, "PROBE_TIMEOUT_S", 3.0)
    with socket.socket() as server:  # accepts TCP connections (kernel backlog), speaks no Ray
        server.bind(("127.0.0.1", 0))
        server.listen(8)
        address = f"127.0.0.1:{server.getsockname()[1]}"
        with pytest.raises(
            ValueError,
            match=r"^--address '127\.0\.0\.1:\d+': (no Ray cluster answered within 3 s|"
            r"could not join a Ray cluster there)",
        ):
            check_ray_address(address, FLAGS)


class _RayThatRefuses:
    """Stands in for Ray where no cluster answers ``ray.init`` (after the address check passed)."""

    @staticmethod
    def is_initialized() -> bool:
        return False

    @staticmethod
    def init(**_kwargs: object) -> None:
        raise ConnectionError("Could not connect to the cluster at 127.0.0.1:1.\nsecond line")


@pytest.mark.parametrize("fault", ["ray missing", "init refused"])
@pytest.mark.parametrize("door", ["cli", "python"])
def test_ray_refusals_during_the_run_name_the_settings_as_their_front_end_does(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], door: str, fault: str
) -> None:
    import electroloc_gym.bench.ray_backend as rb
    from electroloc_gym.bench import run

    monkeypatch.setattr(rb, "check_ray_address", lambda *_args: None)  # the check passed; the run meets the fault
    if fault == "ray missing":
        monkeypatch.setitem(sys.modules, "ray", None)
        words = {"cli": "--backend ray needs Ray", "python": "backend ray needs Ray"}[door]
    else:
        monkeypatch.setattr(rb, "_import_ray", lambda _backend: _RayThatRefuses)
        words = {"cli": "--address '127.0.0.1:1': Could not connect", "python": "address '127.0.0.1:1': Could not"}
        words = words[door]
    settings = {"conditions": "fresh-steel-12.7", "trials": 1, "backend": "ray", "address": "127.0.0.1:1"}
    if door == "cli":
        flags = [w for k, v in settings.items() for w in (f"--{k}", str(v))]
        code = main(["bench", "--agents", "rnd-wlk", *flags, "--out", str(tmp_path / "out"), "--no-progress"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith(f"electroloc bench: error: {words}"), err
    else:
        with pytest.raises(ValueError) as caught:
            run("rnd-wlk", out=tmp_path / "out", **settings)
        assert str(caught.value).startswith(words) and "\n" not in str(caught.value), caught.value


RAISING_AGENT = """
import numpy as np


class Agent:
    calls = 0

    def reset(self, env):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        Agent.calls += 1
        if Agent.calls > 1:
            raise RuntimeError("boom\\nsecond line")
        return np.array([0.5, 0.0], dtype=np.float32), state


def make():
    return Agent()
"""


def test_ray_a_trial_that_raises_is_its_own_line_and_a_callers_ray_keeps_running(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """On a Ray the caller started, a trial whose agent raises ends the run with the benchmark's one line (the
    agent's error itself, not Ray's wrapper), and the caller's Ray is left running."""
    ray = pytest.importorskip("ray")
    (tmp_path / "rb_user_agents.py").write_text(RAISING_AGENT)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))  # the Ray workers import the agent's module too
    ray.shutdown()
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        argv = ["bench", "--agents", "rb_user_agents:make", "--conditions", "fresh-steel-12.7", "--trials", "1"]
        argv += ["--max-observations", "4", "--backend", "ray", "--out", str(tmp_path / "o"), "--no-progress"]
        code = main(argv)
        err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("electroloc")]  # not Ray's log
        assert code == 2 and len(err) == 1 and err[0].startswith("electroloc bench: error: "), err
        assert "its predict() raised RuntimeError: boom" in err[0] and "Ray" not in err[0], err
        assert ray.is_initialized()
    finally:
        ray.shutdown()
