"""Agents see only the agent view: no route to the ground truth from what the benchmark, the rollout, the
controllers and the torch backend's ``sub_env`` hand them (electroloc_gym/envs/agent_view.py)."""

from __future__ import annotations

import copy
import inspect
import pickle
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401
from electroloc_gym.baselines import make_agent
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.bench import run
from electroloc_gym.bench.agents import register_object_agent
from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.envs.agent_view import AGENT_METHODS, AGENT_VALUES, AgentView, agent_view

SMALL = {"n_particles": 200, "max_observations": 4}
#: What an agent must never reach: the truth, the env itself, its internals, its noise stream, its controls.
FORBIDDEN = (
    "truth_mm",
    "target_mm",
    "hidden_state",
    "hidden_keys",
    "unwrapped",
    "env",
    "_env",
    "_core",
    "_state",
    "_sim",
    "_task",
    "state",
    "params",
    "spec",
    "np_random",
    "step",
    "reset",
    "render",
    "close",
    "entry",
    "get_wrapper_attr",
    "__dict__",
)


class Peeker:
    """A plug-in agent that tries to read the truth through what ``reset`` hands it, and records what it got."""

    name = "peeker"

    def __init__(self) -> None:
        self.env_kwargs: dict[str, Any] = {}
        self.got: dict[str, str] = {}
        self.bound: list[Any] = []

    def reset(self, env: Any) -> None:
        self.bound.append(env)
        self.shape = env.action_space.shape
        targets = {"": env, "belief.": env.belief, "sensor_model.": env.sensor_model, "condition.": env.condition}
        for prefix, obj in targets.items():
            for name in (*FORBIDDEN, "target_xy_mm", "condition", "_state", "_index"):
                try:
                    getattr(obj, name)
                except AttributeError:
                    continue
                if prefix == "" and name == "condition":
                    continue  # the condition's view: checked under "condition."
                self.got[prefix + name] = type(getattr(obj, name)).__name__

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.zeros(self.shape, dtype=np.float32), state


def _assert_no_peek(agent: Peeker) -> None:
    assert agent.bound and all(isinstance(v, AgentView) for v in agent.bound)
    assert agent.got == {}, f"the agent reached {agent.got}"


# ---- through the benchmark, the rollout and the torch backend ----------------------------------------------------
@pytest.mark.parametrize("env", ["target", "global", "unknown-target", "dynamic-gain"])
def test_a_benchmark_agent_cannot_read_the_truth(env: str) -> None:
    agent = Peeker()
    result = run([agent], env=env, conditions="fresh-steel-12.7" if env != "global" else "all", trials=1, **SMALL)
    assert len((result.out / "trials.jsonl").read_text().splitlines()) == 1
    _assert_no_peek(agent)


@pytest.mark.parametrize("extra", [{"distractors": 2}, {"sensor_layout": "ring-8"}])
def test_a_benchmark_agent_cannot_read_the_truth_with_distractors_or_an_array(tmp_path, extra: dict) -> None:
    agent = Peeker()
    register_object_agent("peeker-extra", agent)
    config = BenchConfig(
        agents=("peeker-extra",),
        conditions=("fresh-steel-12.7",),
        trials=1,
        seed=0,
        sensor_model="analytic",
        **SMALL,
        **extra,
    )
    run_benchmark(config, tmp_path / "out", backend="serial", progress=False, log=None)
    _assert_no_peek(agent)


def test_the_rollout_hands_the_agent_view_not_the_env() -> None:
    env = gym.make("ElectroLoc-v0", **SMALL)
    agent = Peeker()
    run_episode(env, agent, 0)
    _assert_no_peek(agent)
    assert agent.bound[0] is not env and agent.bound[0] is not env.unwrapped


def test_the_torch_sub_env_is_an_agent_view() -> None:
    torch = pytest.importorskip("torch")
    from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv

    env = TorchElectroLocVectorEnv(num_envs=2, n_particles=200)
    env.reset(seed=0)
    view = env.sub_env(1)
    assert isinstance(view, AgentView)
    for name in (*FORBIDDEN, "_index", "consts"):
        with pytest.raises(AttributeError):
            getattr(view, name)
    for name in ("_env", "_index", "_state"):
        with pytest.raises(AttributeError):
            getattr(view.belief, name)
    assert not hasattr(view.condition, "target_xy_mm")
    agent = make_agent("min-var", seed=0)
    agent.reset(view)  # the controllers read only the agent accessors
    action, _ = agent.predict(None)
    env.step(torch.as_tensor(np.stack([np.zeros(2, dtype=np.float32), action])))
    assert view.n_observations == 2


# ---- what each env's view shows and hides ------------------------------------------------------------------------
def _view(env_id: str, **kwargs: Any) -> tuple[Any, AgentView]:
    env = gym.make(env_id, **SMALL, **kwargs)
    env.reset(seed=3)
    return env.unwrapped, agent_view(env)


def test_the_target_env_shows_its_sphere_but_never_the_target_position() -> None:
    core, view = _view("ElectroLoc-v0")
    c = view.condition
    assert c.target == core.condition.target and c.name == core.condition.name
    assert (
        c.noise_std_V == core.condition.noise_std_V and c.allowed_half_width_mm == core.condition.allowed_half_width_mm
    )
    with pytest.raises(AttributeError, match="target_xy_mm"):
        _ = c.target_xy_mm
    for name in ("replace", "to_dict", "with_noise_factor"):  # no route back to a full Condition
        assert not hasattr(c, name)
    np.testing.assert_array_equal(view.position_mm, core.position_mm)  # the carriage is not hidden here


def test_the_unknown_target_env_hides_the_sphere_and_the_condition_name() -> None:
    core, view = _view("ElectroLocUnknownTarget-v0")
    c = view.condition
    for name in ("target", "name", "chi", "depth_mm", "detection_distance_mm", "target_xy_mm"):
        assert not hasattr(c, name), name
    assert c.noise_std_V == core.condition.noise_std_V and c.saturation_V == core.condition.saturation_V
    assert view.belief.particles.shape[1] == 4
    assert not hasattr(view.sensor_model, "condition")


def test_the_global_env_hides_the_true_carriage_position_and_path() -> None:
    core, view = _view("ElectroLocGlobal-v0")
    for name in ("position_mm", "path_mm", "truth_mm"):
        assert not hasattr(view, name), name
    np.testing.assert_array_equal(view.odometry_mm, core.odometry_mm)
    assert view.scene == core.scene and view.belief_frame == "robot"
    np.testing.assert_array_equal(view.move_bounds_mm[1], core.move_bounds_mm[1])


@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocGlobal-v0", "ElectroLocUnknownTarget-v0"])
def test_the_view_answers_as_the_env_does(env_id: str) -> None:
    core, view = _view(env_id)
    p = view.belief.particles
    assert p is not None and np.array_equal(p, core.belief.particles)
    np.testing.assert_array_equal(view.belief.covariance(), core.belief.covariance())
    moves = np.array([[1.0, 2.0], [-3.0, 0.5]])
    for got, want in zip(view.predicted_reading_model(p, moves), core.predicted_reading_model(p, moves)):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(view.predicted_particles_mm(p, moves), core.predicted_particles_mm(p, moves))
    offsets = np.zeros((3, 2)) if p.shape[1] == 2 else None
    if offsets is not None:
        for got, want in zip(view.sensor_model.mean_std(offsets), core.sensor_model.mean_std(offsets)):
            np.testing.assert_array_equal(got, want)
    assert view.n_observations == core.n_observations == 1
    assert view.action_space is core.action_space and view.success_spread_mm == core.success_spread_mm
    with pytest.raises(ValueError, match="moves_mm"):  # the env's own argument checks
        view.predicted_reading_model(p, np.zeros(3))


def test_the_view_reads_the_live_state() -> None:
    env = gym.make("ElectroLoc-v0", **SMALL)
    env.reset(seed=0)
    view = agent_view(env)
    env.step(np.array([1.0, 0.0], dtype=np.float32))
    assert view.n_observations == 2
    np.testing.assert_array_equal(view.position_mm, env.unwrapped.position_mm)
    env.reset(seed=1)
    assert view.n_observations == 1


@pytest.mark.parametrize("env_id", ["ElectroLoc-v0", "ElectroLocGlobal-v0", "ElectroLocUnknownTarget-v0"])
def test_no_attribute_walk_reaches_the_env(env_id: str) -> None:
    """Every value reachable by public or private (non-dunder) attribute names, four levels deep, is neither the
    env, its core, its state nor its task."""
    env = gym.make(env_id, **SMALL, distractors=1) if env_id == "ElectroLoc-v0" else gym.make(env_id, **SMALL)
    env.reset(seed=0)
    core = env.unwrapped
    forbidden = {id(env), id(core), id(core._state), id(core._task), id(core._sim), id(core.params)}
    seen: set[int] = set()
    frontier = [("view", agent_view(env))]
    for _ in range(4):
        nxt = []
        for path, obj in frontier:
            if id(obj) in seen or isinstance(obj, (str, bytes, int, float, bool, type(None), np.ndarray, np.generic)):
                continue
            seen.add(id(obj))
            assert id(obj) not in forbidden, f"{path} is the env or its internals"
            assert getattr(obj, "__self__", None) is not core, f"{path} is a bound method of the env"
            owner = getattr(obj, "__self__", None)  # a bound method holds its object: never one holding the truth
            assert not hasattr(owner, "target_xy_mm"), f"{path} is a bound method of the condition"
            for name in dir(obj):
                if name.startswith("__"):
                    continue
                try:
                    value = getattr(obj, name)
                except Exception:  # noqa: BLE001 - an accessor that needs arguments or a state: nothing to walk
                    continue
                nxt.append((f"{path}.{name}", value))
            if isinstance(obj, (tuple, list)):
                nxt += [(f"{path}[{i}]", v) for i, v in enumerate(obj)]
        frontier = nxt


def test_a_view_cannot_be_written_or_unpickled_and_copies_are_itself() -> None:
    _, view = _view("ElectroLoc-v0")
    with pytest.raises(AttributeError, match="read-only"):
        view.position_mm = np.zeros(2)
    with pytest.raises(AttributeError, match="read-only"):
        view.belief.particles = None
    with pytest.raises(TypeError):
        vars(view)
    with pytest.raises(TypeError, match="cannot be pickled"):
        pickle.dumps(view)
    assert copy.copy(view) is view and copy.deepcopy(view) is view
    assert set(dir(view)) <= set(AGENT_VALUES) | set(AGENT_METHODS)
    with pytest.raises(AttributeError, match="an agent sees only"):
        _ = view.truth_mm
    assert agent_view(view) is view


# ---- the controllers run on the view; the layouts they cannot run on are one ValueError --------------------------
@pytest.mark.parametrize(
    "name", ["rnd-wlk", "min-var", "zero-crossing", "lookahead[depth=2,branches=4]", "infotaxis", "eedi"]
)
def test_every_controller_binds_to_the_view(name: str) -> None:
    env = gym.make("ElectroLoc-v0", **SMALL)
    agent = make_agent(name, seed=0)
    ep = run_episode(env, agent, 0, agent_seed=1)
    assert isinstance(agent.env, AgentView) and ep.decision_s
    agent.reset(env)  # given the env itself, a controller binds to its view too
    assert isinstance(agent.env, AgentView)


@pytest.mark.parametrize("name", ["infotaxis", "eedi", "zero-crossing"])
@pytest.mark.parametrize("layout", ["line-4", "grid-2x2", "ring-8"])
def test_single_pair_controllers_refuse_an_array_at_reset(name: str, layout: str) -> None:
    env = gym.make("ElectroLoc-v0", sensor_layout=layout, **SMALL)
    env.reset(seed=0)
    agent = make_agent(name, seed=0)
    with pytest.raises(
        ValueError,
        match=rf"^{name} cannot run on this env's sensor layout: .*\['single'\] only, not '{layout}' "
        r"\(make the env with sensor_layout='single'\)$",
    ):
        agent.reset(env)


def test_the_spaces_are_the_wrapped_envs() -> None:
    """The agent acts on the env the rollout steps: a wrapper's spaces, not the core's."""
    low, high = np.full(2, -2.0, dtype=np.float32), np.full(2, 2.0, dtype=np.float32)
    env = gym.wrappers.RescaleAction(gym.make("ElectroLoc-v0", **SMALL), low, high)
    env.reset(seed=0)
    view = agent_view(env)
    assert view.action_space == env.action_space and float(view.action_space.high[0]) == 2.0
    assert not view.action_space.high.flags.writeable  # the wrapper's space, as a read-only copy
    assert env.action_space.high.flags.writeable  # the wrapper's own arrays untouched
    assert view.observation_space is env.observation_space  # the env's own: read-only, handed out as it is
    assert float(env.unwrapped.action_space.high[0]) == 1.0


@pytest.mark.parametrize(
    "env_id,name,pattern",
    [
        ("ElectroLocGlobal-v0", "zero-crossing", "zero-crossing needs a belief over the target's position"),
        ("ElectroLocGlobal-v0", "infotaxis", "infotaxis needs a belief over the target's position"),
        ("ElectroLocGlobal-v0", "eedi", "eedi needs a belief over the target's position"),
        ("ElectroLocUnknownTarget-v0", "lookahead", r"lookahead plans over position hypotheses \(M, 2\)"),
    ],
)
def test_controllers_refuse_an_env_they_cannot_act_in_at_reset(env_id: str, name: str, pattern: str) -> None:
    env = gym.make(env_id, **SMALL)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=pattern):
        make_agent(name, seed=0).reset(env)


# ---- nothing a view returns can write the env: every value and method result, on every env and engine -------------
def _write_route(a: np.ndarray) -> str | None:
    """How ``a`` could be written (itself, or an array or buffer its ``.base`` chain reaches), or None."""
    depth, x = 0, a
    while isinstance(x, np.ndarray):
        if x.flags.writeable:
            return "writable" if depth == 0 else f"its .base{'.base' * (depth - 1)} is writable"
        depth, x = depth + 1, x.base
    return None if x is None or isinstance(x, bytes) else f"its .base chain reaches a {type(x).__name__}"


def _stored(obj: Any) -> list[tuple[str, Any]]:
    """What a returned record holds: its instance fields (``__dict__`` and ``__slots__``), and a container's items."""
    if isinstance(obj, (tuple, list)):
        return [(f"[{i}]", v) for i, v in enumerate(obj)]
    if isinstance(obj, dict):
        return [(f"[{k!r}]", v) for k, v in obj.items()]
    fields = dict(getattr(obj, "__dict__", {}))
    for cls in type(obj).__mro__:
        for name in getattr(cls, "__slots__", ()):
            if name not in fields and hasattr(obj, name):
                fields[name] = getattr(obj, name)
    return [(f".{k}", v) for k, v in fields.items()]


def _writable_arrays(path: str, value: Any, seen: set[int], depth: int = 0) -> list[str]:
    """Every numpy array ``value`` reaches (records and containers walked through what they hold) that could be
    written, as ``path: how``. Agent views are walked by their own names (:func:`_view_calls`)."""
    if depth > 6 or id(value) in seen or isinstance(value, (AgentView, str, bytes, int, float, type(None), np.generic)):
        return []
    seen.add(id(value))
    if isinstance(value, np.ndarray):
        route = _write_route(value)
        return [] if route is None else [f"{path}: {route}"]
    if isinstance(value, type) or callable(value) and not isinstance(value, gym.Space):
        return []
    bad = []
    for name, v in _stored(value):
        bad += _writable_arrays(path + name, v, seen, depth + 1)
    return bad


def _method_args(root: AgentView) -> dict[str, list[tuple[tuple[Any, ...], dict[str, Any]]]]:
    """Arguments for every method an agent view may show (a new method needs its arguments here)."""
    p = np.asarray(root.belief.particles)
    move, moves = np.array([1.0, -2.0]), np.array([[1.0, 2.0], [-3.0, 0.5], [0.0, 0.0]])
    predict = [((p, move), {}), ((p, moves), {})]
    if getattr(root, "gain_levels", None) is not None:
        predict.append(((p, moves), {"gain_level": 0}))
    offsets = p[:, :2] - np.asarray(root.position_mm if hasattr(root, "position_mm") else np.zeros(2))
    shape = (p[:, 2], p[:, 3]) if p.shape[1] == 4 else ()
    readings = root.last_readings_V if hasattr(root, "last_readings_V") else np.array([root.last_reading_V])
    reading = readings if len(readings) > 1 else float(readings[0])
    return {
        "predicted_reading_model": predict,
        "predicted_particles_mm": [((p, move), {}), ((p, moves), {})],
        "gain_action": [((0,), {})],
        "mean": [((), {})],
        "covariance": [((), {})],
        "spread": [((), {})],
        "detection_distance_mm": [((), {}), ((3.0,), {})],
        "mean_std": [((offsets, *shape), {})],
        "log_likelihood": [((reading, offsets, *shape), {})],
    }


def _view_problems(root: AgentView) -> tuple[list[str], int]:
    """(every writable route from what ``root`` and its nested views return, how many values and calls were read)."""
    args, bad, n = _method_args(root), [], 0
    frontier: list[tuple[str, AgentView]] = [("view", root)]
    while frontier:
        path, view = frontier.pop()
        for name in dir(view):
            if not hasattr(view, name):  # hasattr answers as on the env (the unknown target's sensor_layout)
                continue
            value = getattr(view, name)
            if isinstance(inspect.getattr_static(type(view), name), property):  # a value
                assert not callable(value) or isinstance(value, AgentView), f"{path}.{name} is a callable value"
                calls = [(f"{path}.{name}", value)]
            else:  # a method: called with every argument set of the table
                assert name in args, f"{path}.{name}: a method with no arguments in this test (add them)"
                calls = [(f"{path}.{name}{i}", value(*a, **kw)) for i, (a, kw) in enumerate(args[name])]
            for where, got in calls:
                n += 1
                bad += _writable_arrays(where, got, set())
                if isinstance(got, AgentView) and path == "view":
                    frontier.append((where, got))
    return bad, n


def _views_of_every_env() -> list[Any]:
    from electroloc_gym.registry import ENV_IDS, env_entry

    cases = []
    for env_id in ENV_IDS:
        cases.append(pytest.param(env_id, "numba", {}, id=f"{env_id}-numba"))
        if "torch" in env_entry(env_id).backends:
            cases.append(pytest.param(env_id, "torch", {}, id=f"{env_id}-torch"))
    cases.append(pytest.param("ElectroLoc-v0", "numba", {"sensor_layout": "ring-8"}, id="ElectroLoc-v0-array"))
    cases.append(pytest.param("ElectroLoc-v0", "numba", {"gain_levels": (0.5, 1.0, 2.0)}, id="ElectroLoc-v0-gain"))
    return cases


def _agent_view_of(env_id: str, engine: str, kwargs: dict[str, Any]) -> tuple[AgentView, Any]:
    """(the agent view of a reset env of ``engine``, the env)."""
    if engine == "torch":
        pytest.importorskip("torch")
        from electroloc_gym.envs.torch_vector import TorchElectroLocVectorEnv

        venv = TorchElectroLocVectorEnv(num_envs=2, n_particles=200, **kwargs)
        venv.reset(seed=0)
        return venv.sub_env(1), venv
    env = gym.make(env_id, **SMALL, **kwargs)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    return agent_view(env), env


@pytest.mark.parametrize(("env_id", "engine", "kwargs"), _views_of_every_env())
def test_nothing_a_view_returns_is_writable_or_has_a_writable_base(env_id: str, engine: str, kwargs: dict) -> None:
    """Every value and every method result of the view and its belief, sensor-model and condition views: no numpy
    array it reaches (inside tuples, dicts, records, spaces) is writable or has a ``.base`` chain to a writable
    array or buffer (the engine's live state)."""
    view, _ = _agent_view_of(env_id, engine, kwargs)
    bad, n = _view_problems(view)
    assert n >= 25, f"only {n} values and calls read"
    print(f"{env_id} {engine} {kwargs}: {n} values and calls")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("engine", ["numba", "torch"])
def test_an_agent_cannot_rewrite_the_belief_through_the_particles_base(engine: str) -> None:
    view, env = _agent_view_of("ElectroLoc-v0", engine, {})
    before = np.array(view.belief.particles)
    x = view.belief.particles
    while isinstance(x, np.ndarray):  # the array and every array under it
        with pytest.raises(ValueError, match="read-only"):
            x[...] = x[..., :1]
        x = x.base
    np.testing.assert_array_equal(view.belief.particles, before)
