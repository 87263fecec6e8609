"""Any agent in the table: the agent-spec parser, user factories (module:factory) and the Python API."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from electroloc_gym.bench.agents import make_bench_agent, protocol_problem
from electroloc_gym.cli import main as cli_main
from electroloc_gym.utils.agentspec import parse_agent_spec, split_specs

DOCS = Path(__file__).resolve().parents[1] / "docs" / "benchmark.md"
TINY_CLI = [
    "--conditions",
    "fresh-steel-12.7",
    "--trials",
    "2",
    "--n-particles",
    "200",
    "--max-observations",
    "5",
    "--sensor-model",
    "analytic",
    "--backend",
    "serial",
    "--no-progress",
]
USER_MODULE = '''
import numpy as np


class Toward:
    """Moves a fixed step along a direction (an agent without any library)."""

    def __init__(self, dx=0.5, dy=0.0):
        self.dx, self.dy = float(dx), float(dy)
        self.name = f"toward({dx},{dy})"

    def reset(self, env):
        pass

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.array([self.dx, self.dy], dtype=np.float32), state


def make(dx=0.5, dy=0.0):
    return Toward(dx, dy)


def broken(**kwargs):
    raise RuntimeError("no weights at /nowhere")


class NoPredict:
    def reset(self, env):
        pass


def no_predict():
    return NoPredict()
'''


# ---- the one spec parser -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "text,name,options",
    [
        ("min-var", "min-var", {}),
        ("min-var[vote=expected]", "min-var", {"vote": "expected"}),
        ("lookahead[objective=(a,b)]", "lookahead", {"objective": ("a", "b")}),
        ("x[w=[1,2,3],name='a,b']", "x", {"w": [1, 2, 3], "name": "a,b"}),
        ('pkg.mod:make[k=1, s="x]"]', "pkg.mod:make", {"k": 1, "s": "x]"}),
        ("min-var[n_voters=None]", "min-var", {"n_voters": None}),
    ],
)
def test_specs_parse_with_commas_and_brackets_inside_values(text, name, options) -> None:
    spec = parse_agent_spec(text)
    assert (spec.name, spec.options, spec.text) == (name, options, text.strip())


@pytest.mark.parametrize(
    "text,match",
    [
        ("lookahead[depth=2,depth=3]", "'depth' given twice"),
        ("a[b]", "must be key=value"),
        ("a[=1]", "key ''"),
        ("a[x=1]]", "unbalanced"),
        ("a b", "malformed"),
        ("a[x='open]", "unclosed quote"),
        ("", "non-empty"),
        ("x" * 3000, "at most"),
        ("a[x=@]", "neither"),
    ],
)
def test_malformed_specs_are_one_clear_error(text, match) -> None:
    with pytest.raises(ValueError, match=re.escape(match)):
        parse_agent_spec(text)


def test_agent_lists_split_outside_brackets_and_quotes() -> None:
    assert split_specs("lookahead[depth=3,branches=16],min-var, x[a='b,c']") == [
        "lookahead[depth=3,branches=16]",
        "min-var",
        "x[a='b,c']",
    ]


# ---- module:factory ---------------------------------------------------------------------------------------
@pytest.fixture
def user_module(tmp_path, monkeypatch):
    (tmp_path / "h2_user_agents.py").write_text(textwrap.dedent(USER_MODULE))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    return "h2_user_agents"


def test_a_good_factory_is_built_with_its_options(user_module) -> None:
    agent = make_bench_agent(f"{user_module}:make[dx=-0.25,dy=1]")
    assert (agent.dx, agent.dy) == (-0.25, 1.0) and protocol_problem(agent) is None


def test_a_factory_runs_in_the_table(user_module, tmp_path, capsys) -> None:
    out = tmp_path / "run"
    assert cli_main(["bench", "--agents", f"{user_module}:make[dx=0.5],rnd-wlk", "--out", str(out), *TINY_CLI]) == 0
    table = (out / "table.md").read_text()
    assert f"{user_module}:make[dx=0.5]" in table and "rnd-wlk" in table


@pytest.mark.parametrize(
    "spec,match",
    [
        ("no_such_module_h2:make", "cannot import module 'no_such_module_h2' (ModuleNotFoundError"),
        ("{m}:broken[a=1]", "broken(a=1) raised RuntimeError: no weights at /nowhere"),
        ("{m}:no_predict", "the NoPredict object {m}:no_predict returned is not an agent: it lacks a predict() method"),
        ("{m}:missing", "module '{m}' has no callable 'missing'"),
    ],
)
def test_a_bad_factory_is_one_line_before_any_trial(user_module, tmp_path, capsys, spec, match) -> None:
    spec, match = spec.format(m=user_module), match.format(m=user_module)
    out = tmp_path / "run"
    assert cli_main(["bench", "--agents", spec, "--out", str(out), *TINY_CLI]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and repr(spec) in err[0], err
    assert not out.exists()  # nothing written


# ---- the Python API ---------------------------------------------------------------------------------------
def _docs_example() -> str:
    text = DOCS.read_text(encoding="utf-8")
    block = text.split("<!-- example: torch-policy -->", 1)[1]
    return block.split("```python", 1)[1].split("```", 1)[0]


def test_the_documented_torch_policy_runs_beside_min_var(capsys) -> None:
    pytest.importorskip("torch")
    scope: dict = {}
    exec(compile(_docs_example(), str(DOCS), "exec"), scope)  # noqa: S102 - the docs' own example
    result = scope["result"]
    rows = {(r["condition"], r["agent"]): r for r in result.summary["rows"]}
    assert rows[("fresh-steel-12.7", "torch-mlp")]["trials"] == rows[("fresh-steel-12.7", "min-var")]["trials"] == 3
    assert "| torch-mlp |" in result.table and "| min-var |" in result.table
    assert (result.out / "trials.jsonl").is_file() and "torch-mlp" in capsys.readouterr().out


def test_agent_objects_need_the_serial_backend_and_the_protocol(user_module, tmp_path) -> None:
    from electroloc_gym.bench import run

    toward = make_bench_agent(f"{user_module}:make")
    with pytest.raises(ValueError, match="backend must be 'serial'"):
        run(agents=[toward], backend="process", out=tmp_path / "a")

    class NoReset:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return obs[:2], state

    with pytest.raises(ValueError, match="lacks a reset"):
        run(agents=[NoReset()], out=tmp_path / "b")


def test_objects_and_specs_give_the_same_trials(user_module, tmp_path) -> None:
    from electroloc_gym.bench import run

    kw = dict(conditions="fresh-steel-12.7", trials=2, n_particles=200, max_observations=5, sensor_model="analytic")
    a = run(agents=[make_bench_agent(f"{user_module}:make[dx=0.5]")], out=tmp_path / "obj", **kw)
    b = run(agents=[f"{user_module}:make[dx=0.5]"], out=tmp_path / "spec", backend="serial", **kw)
    strip = ("agent", "agent_label", "decision_ms_median", "decision_ms_mean", "wall_s")
    ra = [{k: v for k, v in r.items() if k not in strip} for r in map(eval_json, (a.out / "trials.jsonl").open())]
    rb = [{k: v for k, v in r.items() if k not in strip} for r in map(eval_json, (b.out / "trials.jsonl").open())]
    assert ra == rb and len(ra) == 2


@pytest.mark.parametrize("name", ["min-var", "ppo-belief"])  # a built-in controller's, a shipped model's
def test_an_object_named_like_a_built_in_agent_runs_under_a_free_name(name, tmp_path) -> None:
    from electroloc_gym.bench import run

    agent = make_bench_agent("rnd-wlk")
    agent.name = name
    result = run(agents=[agent], conditions="fresh-steel-12.7", trials=1, n_particles=100, out=tmp_path)
    assert [r["agent"] for r in result.summary["rows"] if r["condition"] == "fresh-steel-12.7"] == [f"{name}-2"]


def eval_json(line: str) -> dict:
    import json

    return json.loads(line)
