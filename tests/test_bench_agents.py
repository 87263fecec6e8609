"""The benchmark's agent registry (controllers, shipped models by name, paths) and the shared rollout loop."""

from __future__ import annotations

import importlib.util
import os
import pickle
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.agent import make_agent
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.bench import default_run
from electroloc_gym.bench.agents import (
    agent_display_name,
    agent_kind,
    make_bench_agent,
    shipped_models,
)
from electroloc_gym.bench.config import BenchConfig, make_trial_specs
from electroloc_gym.bench.default_run import default_agents
from electroloc_gym.bench.trials import run_trial
from electroloc_gym.cli import main as cli_main
from electroloc_gym.registry import BENCH_ENVS
from electroloc_gym.world.conditions import get_condition

HAS_TRAIN = all(importlib.util.find_spec(m) is not None for m in ("torch", "stable_baselines3"))
ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
FAST = [
    "--conditions",
    "fresh-steel-12.7",
    "--trials",
    "1",
    "--n-particles",
    "100",
    "--max-observations",
    "4",
    "--sensor-model",
    "analytic",
    "--no-progress",
]


# ---- names, kinds, labels ------------------------------------------------------------------------------------
def test_shipped_models_are_found_by_name() -> None:
    models = shipped_models()
    assert {"ppo-belief", "ppo-raw-framestack"} <= set(models)
    assert all(p.is_dir() and (p / "policy.safetensors").is_file() for p in models.values())
    assert agent_kind("ppo-belief") == "shipped"
    assert agent_kind("min-var[n_voters=16]") == "baseline"
    assert agent_kind("runs/x") == "path" and agent_kind("x.zip") == "path" and agent_kind("./x") == "path"
    # a slash inside an option's value is the value's: the spec is still a factory or a controller
    assert agent_kind("my_pkg.agents:make[log='runs/a']") == "factory"
    assert agent_kind("min-var[note='a/b']") == "baseline"


def test_unknown_agent_lists_every_choice() -> None:
    with pytest.raises(ValueError, match=r"unknown agent 'nope'.*rnd-wlk.*ppo-belief"):
        make_bench_agent("nope")
    with pytest.raises(ValueError, match="non-empty"):
        agent_kind(" ")
    with pytest.raises(ValueError, match="does not exist"):
        make_bench_agent("runs/missing-model")
    for build in (make_bench_agent, make_agent):  # one refusal of a shipped policy given options, whichever door
        with pytest.raises(
            ValueError, match=r"^the shipped policy 'ppo-belief' takes no options, got 'ppo-belief\[x=1\]'$"
        ):
            build("ppo-belief[x=1]")


@pytest.mark.parametrize(
    "spec,name",
    [
        ("rnd-wlk", "rnd-wlk"),
        ("min-var[n_voters=16]", "min-var[n_voters=16]"),
        ("ppo-belief", "ppo-belief"),
        ("/tmp/runs/ppo-s1000/", "ppo-s1000"),
        ("/tmp/runs/ppo-s1000/model.zip", "ppo-s1000"),
        ("/tmp/runs/ppo-s1000/policy.json", "ppo-s1000"),
        ("a/best.zip", "best"),
        ("best.zip", "best"),  # a path however it is spelled: ./best.zip too
        ("./best.zip", "best"),
    ],
)
def test_display_names_are_short(spec, name) -> None:
    assert agent_display_name(spec) == name


def test_a_model_folder_whose_name_is_no_agent_spec_is_a_path(tmp_path, monkeypatch) -> None:
    import shutil

    shutil.copytree(shipped_models()["ppo-belief"], tmp_path / "run.v2")
    monkeypatch.chdir(tmp_path)
    assert agent_kind("run.v2") == "path" and make_bench_agent("run.v2").name == "run.v2"
    with pytest.raises(ValueError, match="malformed"):  # no such folder: still the spec's own error
        agent_kind("run.v3")


def test_controllers_do_not_import_the_training_package() -> None:
    code = (
        "import sys, electroloc_gym.baselines as b; b.make_agent('min-var')\n"
        "import electroloc_gym.bench.bench_command\n"
        "bad = [m for m in sys.modules if m.startswith(('electroloc_gym.train', 'torch', 'stable_baselines3'))]\n"
        "assert not bad, bad"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=120)
    assert proc.returncode == 0, proc.stderr


# ---- learned policies ----------------------------------------------------------------------------------------
@pytest.mark.skipif(not HAS_TRAIN, reason="the training extra is not installed")
def test_shipped_model_loads_by_name_without_pickle() -> None:
    agent = make_bench_agent("ppo-belief")
    assert agent.name == "ppo-belief"
    assert agent.env_kwargs["observation"] == "belief"


@pytest.mark.skipif(not HAS_TRAIN, reason="the training extra is not installed")
def test_cli_runs_a_shipped_model_by_name(tmp_path, capsys) -> None:
    assert cli_main(["bench", "--agents", "ppo-belief", *FAST, "--backend", "serial", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "agents: ppo-belief (learned policy: shipped, belief observation)" in out
    assert "| ppo-belief |" in (tmp_path / "table.md").read_text()


class _Payload:
    """Unpickling this creates ``marker``: a stand-in for a command run by a crafted model file."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.makedirs, (str(self.marker),))


def _crafted_model(folder: Path, marker: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with zipfile.ZipFile(folder / "model.zip", "w") as z:
        z.writestr("data", '{"policy_class": {":type:": "<class \'abc.ABCMeta\'>", ":serialized:": "gAR9lC4="}}')
        z.writestr("policy.pth", b"")
    return folder


def test_crafted_model_files_run_no_code_by_default(tmp_path) -> None:
    marker = tmp_path / "PWNED"
    _crafted_model(tmp_path / "models" / "evil", marker)
    # A plain run in a downloaded folder ignores ./models (only the installed models are defaults) ...
    proc = subprocess.run(
        [sys.executable, "-m", "electroloc_gym.cli", "bench", *FAST, "--workers", "1", "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=ENV,
        cwd=tmp_path,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert "evil" not in proc.stdout + proc.stderr and not marker.exists()
    # ... and naming the folder, or its zip, is refused without --trust-pickle.
    for spec in ("models/evil", "models/evil/model.zip", str(tmp_path / "models" / "evil")):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "electroloc_gym.cli",
                "bench",
                "--agents",
                spec,
                *FAST,
                "--out",
                str(tmp_path / "out2"),
            ],
            capture_output=True,
            text=True,
            env=ENV,
            cwd=tmp_path,
            timeout=300,
        )
        assert proc.returncode == 2, proc.stderr
        assert "Traceback" not in proc.stderr and "trust" in proc.stderr and len(proc.stderr.splitlines()) == 1
        assert not marker.exists()


def test_default_agents_say_why_a_model_is_skipped(monkeypatch, tmp_path, capsys) -> None:
    monkeypatch.setattr(default_run, "_training_extra_missing", lambda: "the training extra is not installed (test)")
    choices = default_agents()
    assert [c.spec for c in choices if not c.skipped] == ["rnd-wlk", "min-var", "zero-crossing"]
    other_env = {
        "ppo-belief-unknown": "trained on ElectroLocUnknownTarget-v0, not ElectroLoc-v0",
        "ppo-belief-gain": "trained on ElectroLoc-v0 with gain_levels=[0.25, 1.0, 4.0], not ElectroLoc-v0",
        "ppo-belief-global": "trained on ElectroLocGlobal-v0, not ElectroLoc-v0",
        "ppo-belief-grid-2x2": "trained with sensor_layout='grid-2x2', not 'single'",
        "ppo-belief-track": "trained on ElectroLocTrack-v0, not ElectroLoc-v0",
    }
    assert {c.spec: c.skipped for c in choices if c.skipped} == {
        name: other_env.get(name, "the training extra is not installed (test)") for name in shipped_models()
    }
    assert cli_main(["bench", *FAST, "--backend", "serial", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "electroloc bench: skipping ppo-belief: the training extra is not installed (test)" in captured.err
    # the policies of other settings: one plain line saying where each runs, no "skipping" line each
    assert (
        "electroloc bench: the shipped policies trained for other settings run there: "
        "ppo-belief-gain (--env dynamic-gain), ppo-belief-global (--env global), "
        "ppo-belief-grid-2x2 (--sensor-layout grid-2x2), ppo-belief-track (--env track), "
        "ppo-belief-unknown (--env unknown-target)"
    ) in captured.err
    assert "skipping ppo-belief-global" not in captured.err
    for env_name in ("global", "dynamic-gain", "unknown-target", "track"):  # each option named is a real bench row
        assert env_name in BENCH_ENVS
    assert "agents: rnd-wlk; min-var; zero-crossing" in captured.out
    assert [c.spec for c in default_agents(names=("rnd-wlk", "min-var")) if not c.skipped] == ["rnd-wlk", "min-var"]


def test_a_default_model_that_does_not_load_is_skipped_with_the_reason(monkeypatch) -> None:
    """A shipped model of the run's settings is loaded before it is chosen: one that cannot load (a damaged file,
    a missing library) is skipped with the loader's words, and the run goes on with the others."""

    def refuse(name, trust_pickle=False):
        if name == "ppo-belief":
            raise ValueError("policy.safetensors does not match the sha256 recorded in policy.json")
        return object()

    monkeypatch.setattr(default_run, "_training_extra_missing", lambda: None)
    monkeypatch.setattr(default_run, "cached_agent", refuse)
    skipped = {c.spec: c.skipped for c in default_agents() if c.skipped}
    assert skipped["ppo-belief"] == "policy.safetensors does not match the sha256 recorded in policy.json"
    assert "ppo-raw-framestack" not in skipped


def test_global_env_refuses_learned_policies_and_zero_crossing(tmp_path, capsys) -> None:
    for spec in ("zero-crossing", "ppo-belief"):
        assert (
            cli_main(["bench", "--env", "global", "--agents", f"rnd-wlk,{spec}", *FAST[2:], "--out", str(tmp_path)])
            == 2
        )
        assert f"not applicable: ['{spec}']" in capsys.readouterr().err


@pytest.mark.parametrize("naming", ["folder", "policy.json", "run folder"])
def test_global_env_takes_a_policy_folder_trained_on_it(tmp_path, capsys, naming) -> None:
    """A policy path is read as loading it reads it, however it names the folder: the folder, its
    ``policy.json``, or an rl-zoo3 run folder holding it as ``best/``."""
    import shutil

    def named(model: str, name: str) -> Path:  # a user's own export of a shipped policy, named by path
        folder = tmp_path / name / "best" if naming == "run folder" else tmp_path / name
        shutil.copytree(shipped_models()[model], folder)
        return folder / "policy.json" if naming == "policy.json" else tmp_path / name

    mine, other = named("ppo-belief-global", "my-global"), named("ppo-belief", "my-target")
    assert (
        cli_main(
            [
                "bench",
                "--env",
                "global",
                "--agents",
                f"rnd-wlk,{mine}",
                *FAST[2:],
                "--workers",
                "1",
                "--out",
                str(tmp_path / "ok"),
            ]
        )
        == 0
    )
    assert "| my-global |" in (tmp_path / "ok" / "table.md").read_text()  # its row, by the name the path gives
    assert (
        cli_main(
            ["bench", "--env", "global", "--agents", f"rnd-wlk,{other}", *FAST[2:], "--out", str(tmp_path / "refused")]
        )
        == 2
    )
    assert f"not applicable: ['{other}']" in capsys.readouterr().err
    # on the env of the run, the policy's own record decides: refused, naming where it was trained
    assert cli_main(["bench", "--agents", str(mine), *FAST, "--out", str(tmp_path / "other-env")]) == 2
    assert "trained on ElectroLocGlobal-v0" in capsys.readouterr().err


def test_a_policy_record_whose_gain_levels_are_no_list_is_one_line(tmp_path, capsys) -> None:
    """``env_kwargs`` is the training run's plain record: a ``gain_levels`` that is no list of numbers is named."""
    import json
    import shutil

    mine = tmp_path / "bad-gain"
    shutil.copytree(shipped_models()["ppo-belief"], mine)
    meta = json.loads((mine / "policy.json").read_text())
    meta["env_kwargs"]["gain_levels"] = 4
    (mine / "policy.json").write_text(json.dumps(meta))
    assert cli_main(["bench", "--agents", str(mine), *FAST, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "env_kwargs.gain_levels must be a list of numbers, got 4" in err[0], err


def _edited_policy(folder: Path, edit) -> Path:
    import json
    import shutil

    shutil.copytree(shipped_models()["ppo-belief"], folder)
    meta = json.loads((folder / "policy.json").read_text())
    edit(meta)
    (folder / "policy.json").write_text(json.dumps(meta))
    return folder


def _frame_of(n: int):
    def edit(meta):
        obs, norm = meta["observation"], meta["normalization"]
        obs.update(frame_dim=n, shape=[n])
        obs["space"].update(shape=[n], low=obs["space"]["low"][:n], high=obs["space"]["high"][:n])
        norm.update(obs_mean=norm["obs_mean"][:n], obs_var=norm["obs_var"][:n])

    return edit


def _action_space(action_type: str, space: dict):
    def edit(meta):
        meta["action"] = {"action_type": action_type, "space": space}

    return edit


@pytest.mark.parametrize(
    "edit, action_type, says",
    [
        (
            _frame_of(80),
            "continuous",
            "its observation frame has 80 entries, ElectroLoc-v0's (belief observation) has 81",
        ),
        (
            _action_space(
                "continuous", {"type": "Box", "shape": [3], "dtype": "float32", "low": [-1.0] * 3, "high": [1.0] * 3}
            ),
            "continuous",
            "its action space has shape (3,), ElectroLoc-v0's is Box(2,)",
        ),
        (
            _action_space("discrete", {"type": "Discrete", "n": 5}),
            "discrete",
            "its action space is Discrete(5), ElectroLoc-v0's is Discrete(9)",
        ),
    ],
    ids=["observation-frame", "box-shape", "discrete-n"],
)
def test_a_policy_whose_spaces_do_not_fit_the_env_is_named_by_what_differs(tmp_path, edit, action_type, says) -> None:
    """The fit check compares the observation frame and the action space a policy records with the run's env built
    with the policy's own env kwargs, and names the one that differs."""
    from types import SimpleNamespace

    from electroloc_gym.bench.policy_fit import policy_env_problem

    folder = _edited_policy(tmp_path / "p", edit)
    agent = SimpleNamespace(env_kwargs={"observation": "belief", "action_type": action_type})
    assert policy_env_problem(str(folder), agent, "ElectroLoc-v0", None) == says
    fits = SimpleNamespace(env_kwargs={"observation": "belief", "action_type": "continuous"})
    assert policy_env_problem(str(shipped_models()["ppo-belief"]), fits, "ElectroLoc-v0", None) is None


def test_a_shipped_name_is_the_shipped_policy_from_every_front_end(tmp_path, monkeypatch) -> None:
    """``ppo-belief`` is the shipped policy for load_policy, make_agent and the benchmark alike, whatever the
    working directory holds; a folder of that name there is ``./ppo-belief``."""
    import shutil

    from electroloc_gym.policy import load_policy

    shutil.copytree(shipped_models()["ppo-raw-framestack"], tmp_path / "ppo-belief")
    monkeypatch.chdir(tmp_path)
    for agent in (load_policy("ppo-belief"), load_policy(" ppo-belief "), make_agent("ppo-belief")):
        assert agent.env_kwargs["observation"] == "belief" and agent.frame_stack == 1
    assert make_bench_agent("ppo-belief").env_kwargs["observation"] == "belief"
    for local in (load_policy("./ppo-belief"), make_bench_agent("./ppo-belief")):
        assert local.env_kwargs["observation"] == "raw"


def test_a_learned_agent_says_what_it_is() -> None:
    """``repr`` of a loaded policy: its class, name, frames, normalisation and env kwargs."""
    from electroloc_gym.policy import load_policy

    text = repr(load_policy("ppo-belief"))
    assert text == (
        "LearnedAgent(ActorCriticPolicy, name='ppo-belief', frame_stack=1, normalised=True, "
        "env_kwargs={'observation': 'belief', 'action_type': 'continuous'})"
    ), text


# ---- one rollout loop -----------------------------------------------------------------------------------------
def test_run_episode_ends_by_env_or_by_agent() -> None:
    env = gym.make(
        "ElectroLoc-v0", condition="fresh-steel-12.7", n_particles=200, sensor_model="analytic", max_observations=5
    )
    ep = run_episode(env, make_agent("rnd-wlk"), seed=4, agent_seed=9)
    assert ep.ended_by in ("success", "cap") and (ep.terminated or ep.truncated)
    assert len(ep.decision_s) == ep.info["n_observations"] - 1  # the first reading is taken by reset
    again = run_episode(env, make_agent("rnd-wlk"), seed=4, agent_seed=9)
    np.testing.assert_array_equal(again.info["estimate_mm"], ep.info["estimate_mm"])
    env.close()
    zc = make_agent("zero-crossing")
    env = gym.make("ElectroLoc-v0", condition=zc.adapt_condition(get_condition("fresh-steel-12.7")), **zc.env_kwargs)
    ep = run_episode(env, zc, seed=4)
    assert ep.ended_by == "agent" and not ep.terminated and zc.done and len(ep.decision_s) >= 2
    env.close()


def test_run_trial_is_run_episode_plus_the_record() -> None:
    spec = make_trial_specs(
        BenchConfig(
            agents=("rnd-wlk",),
            conditions=("salt-steel-12.7",),
            trials=1,
            n_particles=200,
            sensor_model="analytic",
            max_observations=8,
        )
    )[0]
    rec = run_trial(spec)
    env = gym.make(
        "ElectroLoc-v0",
        condition=get_condition("salt-steel-12.7", spec.signal),
        n_particles=200,
        sensor_model="analytic",
        max_observations=8,
    )
    ep = run_episode(env, make_agent("rnd-wlk"), seed=spec.env_seed, agent_seed=spec.agent_seed)
    assert rec["readings"] == ep.info["n_observations"] and rec["ended_by"] == ep.ended_by
    assert rec["estimate"] == [float(v) for v in ep.info["estimate_mm"]]
    assert rec["start"] == [float(v) for v in ep.start_info["position_mm"]]
    assert (rec["seed"], rec["agent_seed"], rec["env_id"], rec["n_particles"]) == (
        spec.env_seed,
        spec.agent_seed,
        "ElectroLoc-v0",
        200,
    )
    env.close()


def test_agents_list_splits_only_outside_brackets() -> None:
    from electroloc_gym.utils.agentspec import split_specs as split_agents

    assert split_agents("lookahead[depth=3,branches=16],min-var") == ["lookahead[depth=3,branches=16]", "min-var"]
    assert split_agents("rnd-wlk") == ["rnd-wlk"]
    assert split_agents("a[x=1,y=2],b[z=3],c") == ["a[x=1,y=2]", "b[z=3]", "c"]


def test_global_env_runs_the_policy_trained_on_it() -> None:
    from electroloc_gym.bench.bench_command import _runs_on_map_env

    def _runs_on_global(spec: str) -> bool:
        return _runs_on_map_env(spec, "ElectroLocGlobal-v0")

    assert _runs_on_global("ppo-belief-global") and _runs_on_global("min-var")
    assert not _runs_on_global("ppo-belief") and not _runs_on_global("zero-crossing")


def test_a_worker_keeps_a_few_envs_and_closes_them_when_it_lets_them_go(monkeypatch) -> None:
    """A worker reuses an env per (env, condition, agent, kwargs) and keeps at most 17: beyond, every kept env is
    closed (its renderer and buffers let go) before a new one is made."""
    from types import SimpleNamespace

    from electroloc_gym.bench import trials
    from electroloc_gym.bench.backends import WorkerLost

    closed: list[int] = []
    kept = {(k,): SimpleNamespace(close=lambda k=k: closed.append(k)) for k in range(17)}
    monkeypatch.setattr(trials, "_ENVS", dict(kept))
    spec = make_trial_specs(BenchConfig(agents=("rnd-wlk",), conditions=("fresh-steel-12.7",), trials=1))[0]
    env = trials._env(spec, make_bench_agent("rnd-wlk"))
    assert sorted(closed) == list(range(17)) and list(trials._ENVS.values()) == [env]
    env.close()
    assert str(WorkerLost([spec], "SIGKILL")) == "a worker process died (SIGKILL)"  # its words, wherever it is shown


# ---- a plug-in agent's code, whatever raises: one line naming the agent and the attribute ----------------------
PLUG_MODULE = '''
import numpy as np


def _boom(error):
    raise {"runtime": RuntimeError, "attribute": AttributeError, "exit": SystemExit}[error]("boom\\nsecond line")


class Plain:
    def reset(self, env):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.array([0.5, 0.0], dtype=np.float32), state


def make(broken="", how="property", error="runtime", done=False):
    """An agent whose attribute ``broken`` raises when read (``how="property"``) or called (``"method"``)."""
    if broken == "factory":
        _boom(error)
    attrs = {}
    if done:  # an agent that ends its trials itself: its estimate is read
        attrs["done"] = True
    if how == "property":
        attrs[broken] = property(lambda self: _boom(error))
    else:
        attrs[broken] = lambda self, *args, **kwargs: _boom(error)
    return type("Plug", (Plain,), attrs)()
'''

#: Every attribute and method of the agent protocol the benchmark reads (its checks, the rollout loop, the
#: trial record): (attribute, read or called, what the one line says, make()'s other options).
PROTOCOL_FAILURES = [
    ("factory", "method", "make(broken='factory') raised RuntimeError: boom", {}),
    ("env_kwargs", "property", "reading its env_kwargs raised RuntimeError: boom", {}),
    ("env_kwargs", "property", "reading its env_kwargs raised AttributeError: boom", {"error": "attribute"}),
    ("name", "property", "reading its name raised RuntimeError: boom", {}),
    ("table_layout", "property", "reading its table_layout raised RuntimeError: boom", {}),
    ("adapt_condition", "property", "reading its adapt_condition raised RuntimeError: boom", {}),
    ("sensor_layouts", "property", "reading its sensor_layouts raised RuntimeError: boom", {}),
    ("memory_bytes", "method", "its memory_bytes() raised RuntimeError: boom", {}),
    ("depth", "property", "reading its depth raised RuntimeError: boom", {}),
    ("decision_seconds", "method", "its decision_seconds() raised RuntimeError: boom", {}),
    ("seed", "method", "its seed() raised RuntimeError: boom", {}),
    ("seed", "property", "reading its seed raised SystemExit: boom", {"error": "exit"}),
    ("reset", "method", "its reset() raised RuntimeError: boom", {}),
    ("reset", "property", "reading its reset raised RuntimeError: boom", {}),
    ("predict", "method", "its predict() raised RuntimeError: boom", {}),
    ("predict", "property", "reading its predict raised RuntimeError: boom", {}),
    ("done", "property", "reading its done raised RuntimeError: boom", {}),
    ("estimate_mm", "property", "reading its estimate_mm raised RuntimeError: boom", {"done": True}),
]


@pytest.fixture
def plug_module(tmp_path, monkeypatch):
    import importlib

    from electroloc_gym.bench import agents

    (tmp_path / "ba_plug_agents.py").write_text(PLUG_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("ba_plug_agents", None)
    importlib.invalidate_caches()
    agents._CACHE.clear()
    yield "ba_plug_agents"
    sys.modules.pop("ba_plug_agents", None)
    agents._CACHE.clear()


def _options(attr: str, how: str, extra: dict) -> str:
    opts = {"broken": attr, **({} if attr == "factory" else {"how": how}), **extra}
    return ",".join(f"{k}={v!r}" for k, v in opts.items())


@pytest.mark.parametrize(
    "attr,how,says,extra", PROTOCOL_FAILURES, ids=[f"{r[0]}-{r[1]}-{i}" for i, r in enumerate(PROTOCOL_FAILURES)]
)
def test_any_plug_in_attribute_that_raises_is_one_line_naming_the_agent_and_the_attribute(
    plug_module, tmp_path, capsys, attr, how, says, extra
) -> None:
    spec = f"{plug_module}:make[{_options(attr, how, extra)}]"
    code = cli_main(["bench", "--agents", spec, *FAST, "--backend", "serial", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"agent {spec!r}" in err and says in err and "second line" not in err, err


@pytest.mark.parametrize("attr,how,says,extra", [r for r in PROTOCOL_FAILURES if r[0] != "factory"])
def test_an_agent_object_whose_attribute_raises_is_one_value_error(
    plug_module, tmp_path, attr, how, says, extra
) -> None:
    import importlib

    from electroloc_gym.bench.api import run

    agent = importlib.import_module(plug_module).make(broken=attr, how=how, **extra)
    with pytest.raises(ValueError) as info:
        run(
            [agent],
            conditions=["fresh-steel-12.7"],
            trials=1,
            n_particles=100,
            max_observations=4,
            sensor_model="analytic",
            out=tmp_path / "out",
            progress=False,
            log=None,
        )
    text = str(info.value)
    assert "\n" not in text and says in text, text


#: The attributes ``electroloc dataset`` reads of its agent before any episode (its checks and env arguments).
DATASET_READS = [r for r in PROTOCOL_FAILURES if r[0] in ("factory", "env_kwargs", "table_layout")]


@pytest.mark.minari
@pytest.mark.parametrize("attr,how,says,extra", DATASET_READS, ids=[f"{r[0]}-{r[2][:20]}" for r in DATASET_READS])
def test_the_dataset_command_reads_a_plug_in_through_the_same_guard(
    plug_module, tmp_path, monkeypatch, capsys, attr, how, says, extra
) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    spec = f"{plug_module}:make[{_options(attr, how, extra)}]"
    code = cli_main(["dataset", "--agent", spec, "--episodes", "1", "--id", "mine/plug-v0", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert says in err and not (tmp_path / "datasets" / "mine").exists(), err


def test_a_learned_policy_keeps_the_agent_options_it_was_trained_with(tmp_path) -> None:
    """A track policy trained with the velocity belief is run with it (its policy.json's ``motion_model``, an
    option the task declares the agent's own); the protocol's options in the same record are not taken."""
    import json
    import shutil

    from electroloc_gym.models import shipped_models
    from electroloc_gym.policy import load_policy

    src = shipped_models()["ppo-belief-track"]
    dst = tmp_path / "swimmer-policy"
    shutil.copytree(src, dst)
    meta = json.loads((dst / "policy.json").read_text(encoding="utf-8"))
    assert "motion_model" not in load_policy(src).env_kwargs
    meta["env_kwargs"] = {**meta["env_kwargs"], "motion_model": "swimmer", "max_observations": 9}
    (dst / "policy.json").write_text(json.dumps(meta), encoding="utf-8")
    assert load_policy(dst).env_kwargs == {
        "observation": "belief",
        "action_type": "continuous",
        "motion_model": "swimmer",
    }


class _Walker:
    def reset(self, env):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.zeros(2, dtype=np.float32), state


def test_the_guard_and_its_error_cross_process_boundaries_and_forward_writes() -> None:
    """A guarded plug-in agent and the error of a failed read go to worker processes and back by pickle: each comes
    back as it went (the error's message and parts, the agent's class); a write reaches the agent itself."""
    from electroloc_gym.bench.agents import AgentAttributeError, PluginAgent

    err = pickle.loads(pickle.dumps(AgentAttributeError("depth", "RuntimeError: boom")))
    assert type(err) is AgentAttributeError and (err.method, err.error) == ("depth", "RuntimeError: boom")
    assert str(err) == "reading its depth raised RuntimeError: boom"
    guarded = PluginAgent(_Walker())
    guarded.note = "written through"
    assert guarded.wrapped.note == "written through" and repr(guarded) == "PluginAgent(_Walker)"
    back = pickle.loads(pickle.dumps(guarded))
    assert type(back) is PluginAgent and type(back.wrapped) is _Walker and back.note == "written through"


@pytest.mark.parametrize("own", [lambda n: 2.5, lambda n: "2.5", lambda n: "fast", lambda n: None, None])
def test_an_agent_s_own_decision_time_is_a_number_or_none_given(own) -> None:
    """The agent's estimate of one decision (``decision_seconds(n_particles)``), s: taken where it is a number or
    reads as one; 0 (no estimate, no announcement) where it is not, or where the agent has none."""
    from types import SimpleNamespace

    from electroloc_gym.bench.agents import decision_seconds

    agent = SimpleNamespace() if own is None else SimpleNamespace(decision_seconds=own)
    expected = 2.5 if own is not None and own(0) in (2.5, "2.5") else 0.0
    assert decision_seconds(agent, 2500) == expected
