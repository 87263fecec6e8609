"""What a plug-in agent cannot do to a benchmark: change the protocol, crash it with a traceback, run where it
cannot; and the planners' cost checks, all before any folder is written."""

from __future__ import annotations

import json
import textwrap

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from electroloc_gym.baselines.agent import make_agent
from electroloc_gym.bench.agents import agent_env_kwargs, bench_env_kwargs, plug_in_problem
from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.cli import main as cli_main
from electroloc_gym.registry import ENVS

TINY = [
    "--conditions",
    "fresh-steel-12.7",
    "--trials",
    "3",
    "--n-particles",
    "200",
    "--max-observations",
    "6",
    "--sensor-model",
    "analytic",
    "--no-progress",
]

USER_MODULE = """
import os, sys
import numpy as np

class Agent:
    def __init__(self, fail=None, method="predict", after=0, env_kwargs=None):
        self.fail, self.method, self.after, self.calls = fail, method, int(after), 0
        self.env_kwargs = dict(env_kwargs or {})

    def _maybe(self, method):
        if self.fail is None or method != self.method:
            return
        self.calls += 1
        if self.calls <= self.after:
            return
        if self.fail == "exit":
            sys.exit(3)
        if self.fail == "os_exit":
            os._exit(7)
        if self.fail == "recursion":
            def f():
                return f()
            f()
        raise {"value": ValueError, "memory": MemoryError, "runtime": RuntimeError, "key": KeyError,
               "type": TypeError}[self.fail]("boom\\nsecond line")

    def seed(self, seed):
        self._maybe("seed")

    def reset(self, env):
        self._maybe("reset")

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self._maybe("predict")
        return np.array([0.5, 0.0], dtype=np.float32), state


def make(**kwargs):
    return Agent(**kwargs)
"""


@pytest.fixture
def user_module(tmp_path, monkeypatch):
    (tmp_path / "pb_user_agents.py").write_text(textwrap.dedent(USER_MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    _forget("pb_user_agents")
    yield "pb_user_agents"
    _forget("pb_user_agents")


def _forget(module: str) -> None:
    """Drop the module and the agents built from it (each test writes its own)."""
    import importlib
    import sys

    from electroloc_gym.bench import agents

    sys.modules.pop(module, None)
    importlib.invalidate_caches()
    agents._CACHE.clear()


def _bench(capsys, out, *args) -> tuple[int, str]:
    code = cli_main(["bench", "--out", str(out), *TINY, *args])
    captured = capsys.readouterr()
    return code, captured.err


# ---- the protocol ----------------------------------------------------------------------------------------
def test_an_agent_that_sets_its_own_success_criterion_is_refused(user_module, tmp_path, capsys) -> None:
    spec = f"{user_module}:make[env_kwargs={{'max_observations': 1000000, 'success_spread_mm': 1e9}}]"
    code, err = _bench(capsys, tmp_path / "out", "--agents", spec, "--backend", "serial")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "['max_observations', 'success_spread_mm']" in err and "fixes for every agent" in err
    assert not (tmp_path / "out").exists()


_ANY_VALUE = st.one_of(
    st.none(), st.booleans(), st.integers(-(10**9), 10**9), st.floats(allow_nan=True), st.text(max_size=5)
)
_KEYS = sorted({k for e in ENVS for k in e.all_arguments} | {"render_mode", "target_draw", "zz"})


@settings(max_examples=150, deadline=None)
@given(
    kwargs=st.dictionaries(st.sampled_from(_KEYS), _ANY_VALUE, max_size=6),
    env=st.sampled_from([e.env_id for e in ENVS]),
)
def test_no_env_kwargs_of_a_plug_in_agent_change_the_protocol(kwargs, env) -> None:
    class Plug:
        env_kwargs = kwargs

    cfg = BenchConfig(env_id=env, sensor_model="analytic")
    run = dict(
        condition=None if env == "ElectroLocGlobal-v0" else "fresh-steel-12.7",
        signal=cfg.signal,
        sensor_model=cfg.sensor_model,
        n_particles=cfg.n_particles,
        max_observations=cfg.max_observations,
        success_spread_mm=cfg.success_spread_mm,
    )
    honest = bench_env_kwargs(env, None, None, **run)
    got = bench_env_kwargs(env, Plug(), None, **run)
    own = agent_env_kwargs(env)
    assert {k: v for k, v in got.items() if k not in own} == honest
    assert (plug_in_problem(Plug(), env) is None) == all(k in own for k in kwargs)


def test_a_task_declares_which_of_its_options_are_the_agents_own(tmp_path, capsys) -> None:
    """The moving target's filter options are the agent's (how it observes): a plug-in agent may set them on
    that env only; a controller takes them in its spec; a learned policy keeps them from its training."""
    track = {e.env_id: e for e in ENVS}["ElectroLocTrack-v0"]
    assert track.agent_arguments == ("motion_model", "motion_step_mm", "motion_turn_std_rad", "motion_speed_mm")
    assert {e.env_id: e.agent_arguments for e in ENVS if e.env_id != track.env_id} == {
        e.env_id: () for e in ENVS if e.env_id != track.env_id
    }

    class Swimmer:
        env_kwargs = {"motion_model": "swimmer"}

    assert plug_in_problem(Swimmer(), "ElectroLocTrack-v0") is None
    assert "fixes for every agent" in (plug_in_problem(Swimmer(), "ElectroLoc-v0") or "")
    kw = bench_env_kwargs("ElectroLocTrack-v0", Swimmer(), None, condition="fresh-steel-12.7", signal="fitted")
    assert kw["motion_model"] == "swimmer"
    assert make_agent("min-var[motion_model=swimmer]").env_kwargs == {"motion_model": "swimmer"}
    code, err = _bench(capsys, tmp_path / "bad", "--env", "track", "--agents", "min-var[motion_model=fish]")
    assert code == 2 and err.count("\n") == 1 and "motion_model" in err and "Traceback" not in err
    assert not (tmp_path / "bad").exists()
    # a controller that cannot read the velocity belief is refused before the folder, not at its first trial
    code, err = _bench(capsys, tmp_path / "la", "--env", "track", "--agents", "lookahead[motion_model=swimmer]")
    assert code == 2 and err.count("\n") == 1 and "plans over position hypotheses" in err and "(200, 4)" in err
    assert not (tmp_path / "la").exists()


def test_plug_in_hooks_that_change_the_trial_are_refused() -> None:
    class Moves:
        env_kwargs: dict = {}

        def adapt_condition(self, condition):
            return condition

    class Table1:
        env_kwargs: dict = {}
        table_layout = "table1"

    assert "adapt_condition" in plug_in_problem(Moves())
    assert "Table-4 layout" in plug_in_problem(Table1())


def test_the_protocol_is_in_config_json_and_resume_compares_it(tmp_path) -> None:
    from electroloc_gym.bench.runner import run_benchmark

    cfg = BenchConfig(
        agents=("rnd-wlk",),
        conditions=("fresh-steel-12.7",),
        trials=1,
        n_particles=100,
        max_observations=4,
        sensor_model="analytic",
    )
    run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None)
    stored = json.loads((tmp_path / "config.json").read_text())
    assert stored["success_spread_mm"] == 10.0 and stored["max_observations"] == 4 and stored["n_particles"] == 100
    stored["success_spread_mm"] = 1e9
    (tmp_path / "config.json").write_text(json.dumps(stored))
    with pytest.raises(ValueError, match="success_spread_mm"):
        run_benchmark(cfg, tmp_path, backend="serial", progress=False, log=None, resume=True)


# ---- failures mid-trial ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "fail,method",
    [
        ("runtime", "predict"),
        ("memory", "predict"),
        ("recursion", "reset"),
        ("value", "predict"),
        ("exit", "seed"),
        ("key", "reset"),
    ],
)
def test_an_agent_that_raises_mid_trial_is_one_line_and_resume_goes_on(
    user_module, tmp_path, capsys, fail, method
) -> None:
    out = tmp_path / "out"
    spec = f"{user_module}:make[fail='{fail}',method='{method}',after=1]"
    code, err = _bench(capsys, out, "--agents", spec, "--backend", "serial")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"agent {spec!r} in trial 1 of fresh-steel-12.7" in err and f"its {method}() raised" in err
    assert "--resume" in err
    kept = (out / "trials.jsonl").read_text().splitlines()
    assert len(kept) == 1


def test_a_fixed_agent_resumes_where_the_broken_one_stopped(user_module, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    (tmp_path / "pb_user_agents.py").write_text(
        textwrap.dedent(USER_MODULE).replace(
            "def make(**kwargs):\n    return Agent(**kwargs)",
            "def make(**kwargs):\n    return Agent('runtime', after=2)",
        )
    )
    code, _ = _bench(capsys, out, "--agents", f"{user_module}:make", "--backend", "serial")
    assert code == 2
    (tmp_path / "pb_user_agents.py").write_text(textwrap.dedent(USER_MODULE))
    _forget(user_module)
    code, _ = _bench(capsys, out, "--agents", f"{user_module}:make", "--backend", "serial", "--resume")
    assert code == 0
    assert len((out / "trials.jsonl").read_text().splitlines()) == 3


def test_a_worker_that_exits_is_one_line_naming_the_agent(user_module, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    spec = f"{user_module}:make[fail='os_exit',method='predict',after=1]"
    code, err = _bench(capsys, out, "--agents", spec, "--workers", "2")
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "a worker process died" in err and f"agent {spec!r}" in err


@settings(max_examples=12, deadline=None)
@given(
    fail=st.sampled_from(["runtime", "memory", "value", "exit", "key", "type", "recursion"]),
    method=st.sampled_from(["seed", "reset", "predict"]),
    after=st.integers(0, 3),
)
def test_random_exceptions_from_random_methods_give_one_line(fail, method, after) -> None:
    import sys
    import types

    from electroloc_gym.bench.agents import register_object_agent
    from electroloc_gym.bench.config import make_trial_specs
    from electroloc_gym.bench.trials import TrialFailed, run_trial

    module = types.ModuleType("pb_random")
    exec(textwrap.dedent(USER_MODULE), module.__dict__)  # noqa: S102 - the test's own agent code
    sys.modules["pb_random"] = module
    register_object_agent("pb-random", module.Agent(fail, method, after))
    cfg = BenchConfig(
        agents=("pb-random",),
        conditions=("fresh-steel-12.7",),
        trials=5,
        n_particles=100,
        max_observations=5,
        sensor_model="analytic",
    )
    for spec in make_trial_specs(cfg):
        try:
            run_trial(spec)
        except TrialFailed as exc:
            text = str(exc)
            assert "\n" not in text and "'pb-random'" in text and f"trial {spec.trial}" in text
            assert f"its {method}() raised" in text
            return
    raise AssertionError("the agent never failed")


# ---- layouts and costs, before any folder ------------------------------------------------------------------
@pytest.mark.parametrize("agent", ["infotaxis", "eedi", "zero-crossing"])
@pytest.mark.parametrize("layout", ["line-4", "grid-2x2", "ring-8"])
def test_agents_that_cannot_run_on_a_layout_are_refused_before_the_folder(tmp_path, capsys, agent, layout) -> None:
    code, err = _bench(capsys, tmp_path / "out", "--agents", agent, "--sensor-layout", layout)
    assert code == 2 and err.count("\n") == 1
    assert f"agent {agent!r} cannot run with --sensor-layout {layout}" in err
    assert not (tmp_path / "out").exists()


def test_infotaxis_has_a_memory_estimate_checked_before_the_first_trial(tmp_path, capsys) -> None:
    from electroloc_gym.baselines.infotaxis import InfotaxisAgent

    small = InfotaxisAgent(n_options=16, n_particles=500, n_voters=128, nodes=3)
    assert small.memory_bytes(2500) == 32 * 16 * 500 + 8 * 128 * 3 * 500
    code, err = _bench(capsys, tmp_path / "out", "--agents", "infotaxis[n_options=100000000]")
    assert code == 2 and err.count("\n") == 1 and "GiB per decision" in err
    assert not (tmp_path / "out").exists()


def test_a_slow_eedi_is_announced_before_the_run(tmp_path, capsys, monkeypatch) -> None:
    from electroloc_gym.baselines.eedi import EEDIAgent
    from electroloc_gym.bench import runner

    slow = EEDIAgent(n_particles=5000, n_coefficients=32, grid_mm=1)
    assert slow.decision_seconds(2500) > 10 * EEDIAgent().decision_seconds(2500) > 0
    monkeypatch.setattr(runner, "_memory_budget", lambda: 2**50)
    monkeypatch.setattr(runner, "SLOW_DECISION_S", EEDIAgent().decision_seconds(2500) * 2)
    lines: list[str] = []
    with pytest.raises(ValueError):  # stopped right after the checks: the warning is what is tested
        runner.run_benchmark(
            BenchConfig(
                agents=("eedi[n_particles=5000,n_coefficients=32,grid_mm=1]",),
                conditions=("fresh-steel-12.7",),
                trials=1,
            ),
            tmp_path / "x" / "y",
            backend="nope",
            progress=False,
            log=lines.append,
        )
    assert any("warning" in line and "s per decision" in line for line in lines)


# ---- integer options ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "option,value",
    [
        ("--distractors", "٣"),
        ("--trials", "３"),
        ("--seed", "²"),
        ("--workers", "1_0"),
        ("--max-observations", " 5"),
        ("--n-particles", "+100"),
    ],
)
def test_integer_options_take_ascii_digits_only(tmp_path, capsys, option, value) -> None:
    with pytest.raises(SystemExit) as info:
        cli_main(["bench", "--out", str(tmp_path / "out"), *TINY, "--agents", "rnd-wlk", option, value])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1 and option in err and "ASCII digits" in err
    assert not (tmp_path / "out").exists()
