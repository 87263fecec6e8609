"""The torch engine's input checks: actions (on the host, and on the device without a synchronisation),
the constructor's arguments, the memory estimate, ``reset``'s seeds and options, and a closed env — each
one clear error as the numba engine gives, and nothing invalid in the state.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch.utils._python_dispatch import TorchDispatchMode  # noqa: E402

import electroloc_gym  # noqa: E402,F401 - registers the ids
from electroloc_gym.engines.torch_core import device as D  # noqa: E402
from electroloc_gym.envs import ElectroLocVectorEnv  # noqa: E402
from electroloc_gym.envs.torch_vector import MAX_NUM_ENVS, TorchElectroLocVectorEnv, numpy_view  # noqa: E402

torch.set_num_threads(1)
NAN, INF = float("nan"), float("inf")


def make(n: int = 3, **kw) -> TorchElectroLocVectorEnv:
    return TorchElectroLocVectorEnv(num_envs=n, **{"n_particles": 50, **kw})


def snapshot(env: TorchElectroLocVectorEnv) -> dict:
    return {k: v.clone() for k, v in env.state.items()}


def assert_same_state(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def assert_finite_state(env: TorchElectroLocVectorEnv) -> None:
    for k, v in env.state.items():
        if v.is_floating_point():
            assert torch.isfinite(v).all(), k


# ---- actions checked on the host ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("kw", "actions", "match"),
    [
        ({}, torch.tensor([[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]]), "finite"),
        ({}, torch.tensor([[INF, 0.0], [0.0, 0.0], [0.0, 0.0]]), "finite"),
        ({}, np.array([[0.0, -INF], [0.0, 0.0], [0.0, 0.0]]), "finite"),
        ({}, [[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]], "finite"),
        ({}, torch.zeros(3, 2, dtype=torch.complex64), "integers or reals"),
        ({}, torch.zeros(3, 2, dtype=torch.bool), "integers or reals"),
        ({}, None, "actions"),
        ({}, "left", "actions"),
        ({}, torch.zeros(3, 3), "shape"),
        ({}, torch.zeros(2, 2), "shape"),
        ({"action_type": "discrete"}, torch.tensor([-1, 0, 0]), r"in \[0, 8\]"),
        ({"action_type": "discrete"}, torch.tensor([9, 0, 0]), r"in \[0, 8\]"),
        ({"action_type": "discrete"}, torch.tensor([NAN, 0.0, 0.0]), r"in \[0, 8\]"),
        ({"action_type": "discrete"}, torch.tensor([1.0, 0.0, 0.0]), r"in \[0, 8\]"),
        ({"action_type": "discrete"}, torch.tensor([True, False, False]), "integers or reals"),
        ({"action_type": "discrete"}, np.array([1, 2, 3], dtype=np.complex128), "integers or reals"),
        ({"action_type": "discrete"}, None, "actions"),
    ],
)
def test_host_checked_actions_are_refused_before_anything_changes(kw, actions, match):
    env = make(**kw)
    env.reset(seed=0)
    before = snapshot(env)
    with pytest.raises(ValueError, match=match):
        env.step(actions)
    assert_same_state(before, snapshot(env))


@pytest.mark.parametrize("check", ["host", "device"])
@pytest.mark.parametrize(
    ("actions", "match"),
    [
        (torch.zeros(3, 2, device="meta"), "got a meta tensor"),
        (torch.zeros(3, 2).to_sparse(), "got a sparse_coo tensor"),
        (torch.zeros(3, 2).to_sparse_csr(), "got a sparse_csr tensor"),
    ],
)
def test_tensors_without_readable_values_are_one_error_naming_actions(check, actions, match):
    env = make(action_check=check)
    env.reset(seed=0)
    before = snapshot(env)
    with pytest.raises(ValueError, match=f"actions must be a number array or a dense tensor holding values, {match}"):
        env.step(actions)
    assert_same_state(before, snapshot(env))


def test_host_check_gives_the_numba_engines_messages():
    numba = ElectroLocVectorEnv(num_envs=3, n_particles=50)
    torch_env = make()
    numba.reset(seed=0)
    torch_env.reset(seed=0)
    for bad in (np.array([[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]]), np.zeros((3, 3)), None, "x", np.zeros((3, 2), bool)):
        with pytest.raises(ValueError) as a:
            numba.step(bad)
        with pytest.raises(ValueError) as b:
            torch_env.step(bad)
        assert str(a.value) == str(b.value)


def test_host_accepts_what_the_numba_engine_accepts():
    env = make()
    env.reset(seed=0)
    env.step([[0.5, -0.5], [2.0, 0.0], [0, 1]])  # a list; outside [-1, 1] is clipped
    env.step(torch.zeros(3, 2, dtype=torch.bfloat16))  # widened for the host check
    env.step(torch.zeros(3, 2, requires_grad=True))
    env.step(np.zeros((3, 2), dtype=np.int64))
    disc = make(action_type="discrete")
    disc.reset(seed=0)
    _, _, _, _, info = disc.step(np.array([0, 4, 8], dtype=np.uint8))
    assert not info["invalid_action"].any()


# ---- actions checked on the device ----------------------------------------------------------------


def test_device_check_turns_an_invalid_action_into_no_move_and_reports_it():
    dev = make(action_check="device", randomize_target=True)
    host = make(action_check="host", randomize_target=True)
    dev.reset(seed=4)
    host.reset(seed=4)
    bad = torch.tensor([[NAN, 0.3], [0.2, INF], [0.5, -0.5]])
    obs_d, r_d, te_d, tr_d, info_d = dev.step(bad)
    obs_h, r_h, te_h, tr_h, info_h = host.step(torch.tensor([[0.0, 0.0], [0.0, 0.0], [0.5, -0.5]]))
    assert torch.equal(obs_d, obs_h) and torch.equal(r_d, r_h) and torch.equal(te_d | tr_d, te_h | tr_h)
    assert_same_state(snapshot(dev), snapshot(host))
    assert info_d["invalid_action"].tolist() == [True, True, False]
    assert not info_h["invalid_action"].any()
    assert_finite_state(dev)
    assert torch.isfinite(obs_d).all()
    dev.step(torch.tensor([[0.1, 0.1], [-INF, 0.0], [0.0, 0.0]]))
    assert dev.invalid_action_count == 3
    before = snapshot(dev)
    with pytest.raises(ValueError, match=r"actions: 3 invalid action\(s\)"):
        dev.reset(seed=5)
    assert_same_state(before, snapshot(dev))  # the reset raised before anything changed
    assert dev.invalid_action_count == 0  # reported once
    dev.reset(seed=5)


def test_device_check_of_discrete_actions():
    dev = make(action_type="discrete", action_check="device")
    host = make(action_type="discrete", action_check="host")
    dev.reset(seed=1)
    host.reset(seed=1)
    obs_d, *_, info = dev.step(torch.tensor([-1, 9, 2]))
    obs_h, *_ = host.step(torch.tensor([4, 4, 2]))  # 4: stay
    assert torch.equal(obs_d, obs_h)
    assert info["invalid_action"].tolist() == [True, True, False]
    assert dev.invalid_action_count == 2


@pytest.mark.parametrize(
    ("kw", "actions", "match"),
    [
        ({}, torch.zeros(3, 2, dtype=torch.complex64), "dtype"),
        ({}, torch.zeros(3, 2, dtype=torch.bool), "dtype"),
        ({}, torch.zeros(3), "shape"),
        ({"action_type": "discrete"}, torch.zeros(3), "dtype"),
        ({"action_type": "discrete"}, torch.zeros(3, 1, dtype=torch.int64), "shape"),
    ],
)
def test_device_check_refuses_dtype_and_shape_at_once(kw, actions, match):
    env = make(action_check="device", **kw)
    env.reset(seed=0)
    before = snapshot(env)
    with pytest.raises(ValueError, match=match):
        env.step(actions)
    assert_same_state(before, snapshot(env))


def test_host_side_inputs_are_checked_on_the_host_in_device_mode():
    env = make(action_check="device")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="actions"):
        env.step(None)


class _Ops(TorchDispatchMode):
    """The aten operations dispatched inside the block."""

    def __init__(self) -> None:
        super().__init__()
        self.ops: list = []

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        self.ops.append(func)
        return func(*args, **(kwargs or {}))


def test_device_check_has_no_host_synchronisation():
    """No operation of the device check reads a value to the host (``.item()``, ``bool()``, ``nonzero``)."""
    env = make(action_check="device")
    env.reset(seed=0)
    for actions in (torch.tensor([[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]]), torch.zeros(3, 2)):
        with _Ops() as seen:
            env._device_actions(actions)
        names = {str(op) for op in seen.ops}
        assert names and not names & {"aten._local_scalar_dense.default", "aten.nonzero.default", "aten.item.default"}


def test_numpy_view_checks_actions_on_the_host():
    if not hasattr(gym.wrappers.vector, "ArrayConversion"):  # gymnasium 1.1 has no view (test_torch_backend)
        return
    view = numpy_view(make(action_check="device"))
    view.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        view.step(np.array([[NAN, 0.0], [0.0, 0.0], [0.0, 0.0]], dtype=np.float32))
    view.step(np.zeros((3, 2), dtype=np.float32))
    view.reset(options={"reset_mask": np.array([True, False, False])})
    for bad in (
        np.zeros((3, 2), dtype=object),
        np.array([[0.0, None], [0.0, 0.0], [0.0, 0.0]], dtype=object),
        np.full((3, 2), "a"),
        np.zeros((3, 2), dtype="M8[s]"),
    ):  # dtypes the conversion cannot carry: the host check's message, not the conversion's BufferError
        with pytest.raises(ValueError, match=r"actions must be a number array of shape \(3, 2\)"):
            view.step(bad)


# ---- the constructor --------------------------------------------------------------------------------


def test_unavailable_and_meta_devices_are_one_error_naming_the_available_ones():
    have = D.available_devices()
    missing = [d for d in ("cuda", "cuda:7", "mps", "xla", "xpu") if d not in have and f"{d}:0" not in have]
    assert "xla" in missing or "cuda:7" in missing  # this machine has neither torch_xla nor 8 GPUs
    for name in [*missing, "meta", "nonsense", 3.5, None]:
        with pytest.raises(ValueError, match=r"device must be a torch device this machine has, one of \[.*'cpu'"):
            make(device=name)


def test_device_is_the_one_tensors_report():
    env = make(device=torch.device("cpu"))
    assert env.device == torch.zeros(1).device


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        (
            {"compile_backend": "nope"},
            r"compile_backend must be one of torch.compile's backends \[.*'eager'.*'inductor'",
        ),
        ({"compile_backend": 3}, "compile_backend must be one of"),
        ({"compile_backend": None}, "compile_backend must be one of"),
        ({"compile": "yes"}, "compile must be True or False"),
        ({"compile": 1}, "compile must be True or False"),
        ({"num_envs": 0}, rf"num_envs must be an integer in \[1, {MAX_NUM_ENVS}\]"),
        ({"num_envs": 2**63}, rf"num_envs must be an integer in \[1, {MAX_NUM_ENVS}\]"),
        ({"num_envs": 2.0}, "num_envs must be an integer"),
        ({"num_envs": True}, "num_envs must be an integer"),
        ({"action_check": "never"}, r"action_check must be one of \['auto', 'host', 'device'\]"),
        ({"render_mode": "human"}, "render_mode"),
        ({"autoreset_mode": "same_step"}, "autoreset_mode"),
        ({"autoreset_mode": "bogus"}, "autoreset_mode"),
        ({"autoreset_mode": ["next_step"]}, "autoreset_mode"),
        ({"n_particles": 10**9}, r"n_particles × num_envs = 1000000000 × 3 needs ≈\d.* GiB on cpu"),
        ({"num_envs": MAX_NUM_ENVS}, r"needs ≈.* GiB on cpu .* at most \d+ envs of 50 particles"),
        ({"calibration": {"grid_step_mm": 1e-4}}, "calibration grid of .* choose a coarser calibration grid_step_mm"),
    ],
)
def test_bad_constructor_arguments_are_one_clear_error(kw, match):
    kw = {"num_envs": 3, **kw}
    with pytest.raises(ValueError, match=match):
        TorchElectroLocVectorEnv(n_particles=kw.pop("n_particles", 50), **kw)


def test_a_registered_backend_other_than_inductor_is_accepted():
    make(compile_backend="eager")


@pytest.mark.parametrize(
    "kw",
    [
        {"n_particles": 0},
        {"n_particles": 2**40},
        {"condition": "nope"},
        {"calibration_seed": -1},
        {"max_episode_steps": 0},
        {"observation": "pixels"},
        {"n_particle": 10},
        {"randomize_target": "false"},
        {"calibration": {"grid_step": 2}},
        {"success_spread_mm": NAN},
    ],
)
def test_env_arguments_give_the_numba_engines_message(kw):
    with pytest.raises(ValueError) as a:
        ElectroLocVectorEnv(num_envs=2, **kw)
    with pytest.raises(ValueError) as b:
        TorchElectroLocVectorEnv(num_envs=2, **kw)
    assert str(a.value) == str(b.value)


# ---- the memory estimate -----------------------------------------------------------------------------


@pytest.mark.parametrize("kw", [{}, {"sensor_model": "analytic"}, {"condition": "random", "calibration_seed": 2}])
def test_memory_estimate_is_the_traced_allocation(kw):
    env = make(n=2, **kw)
    c = env.consts
    state_bytes = sum(t.nbytes for t in env.state.values())
    const_bytes = sum(
        v.nbytes for f in dataclasses.fields(c) for v in [getattr(c, f.name)] if isinstance(v, torch.Tensor)
    )
    est = env.memory_estimate_bytes()
    assert est > state_bytes + const_bytes  # the state is part of it, and a step's temporaries come on top
    assert D.estimate_bytes(c, 7) == const_bytes + 7 * D.env_step_bytes(c)
    peak7 = D.traced_peak_bytes(c, 7)  # the step of 7 envs traced itself
    assert peak7 <= D.estimate_bytes(c, 7) <= peak7 * 1.01  # one env's share × N: the traced N-env step


def test_memory_estimate_follows_the_state_layout():
    """A larger state (more particles) is a larger estimate, by at least the state's own growth."""
    small, big = make(n=2, n_particles=100), make(n=2, n_particles=1100)
    grow = sum(t.nbytes for t in big.state.values()) - sum(t.nbytes for t in small.state.values())
    assert grow == 2 * 1000 * 2 * 4  # particles: 2 coordinates float32
    assert big.memory_estimate_bytes() - small.memory_estimate_bytes() >= grow


# ---- reset's seeds and options ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "seed", [-1, "7", 1.5, True, [1, 2], [1, 2, -3], np.zeros((3, 1), dtype=np.int64), {"a": 1}, b"xyz"]
)
def test_bad_seeds_give_the_numba_engines_message(seed):
    numba, torch_env = ElectroLocVectorEnv(num_envs=3, n_particles=50), make()
    with pytest.raises(ValueError) as a:
        numba.reset(seed=seed)
    with pytest.raises(ValueError) as b:
        torch_env.reset(seed=seed)
    assert str(a.value) == str(b.value)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ("notadict", r"options must be None or a dict with keys among \['reset_mask'\], got 'notadict'"),
        ([("reset_mask", None)], "options must be None or a dict"),
        ({"seed": 3}, r"options has unknown key\(s\) \['seed'\]; allowed: \['reset_mask'\]"),
        ({"reset_mask": None}, r"options\['reset_mask'\] must be a bool array of shape \(3,\) with a True entry"),
        ({"reset_mask": [True, False, True]}, r"options\['reset_mask'\] must be a bool array"),
        ({"reset_mask": np.zeros(3, dtype=bool)}, "with a True entry"),
        ({"reset_mask": torch.zeros(3, dtype=torch.bool)}, "with a True entry"),
        ({"reset_mask": np.ones(4, dtype=bool)}, r"shape \(3,\)"),
        ({"reset_mask": torch.ones(3)}, "bool array"),
        ({"reset_mask": torch.ones(3, dtype=torch.bool, device="meta")}, "with a True entry, got a meta tensor"),
        ({"reset_mask": torch.ones(3, dtype=torch.bool).to_sparse()}, "with a True entry, got a sparse_coo tensor"),
        ({"reset_mask": "abc"}, "bool array"),
    ],
)
def test_bad_reset_options_are_one_error_before_anything_changes(options, match):
    env = make()
    env.reset(seed=0)
    env.step(torch.zeros(3, 2))
    before = snapshot(env)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=1, options=options)
    assert_same_state(before, snapshot(env))


def test_reset_mask_as_array_or_tensor_resets_those_envs():
    env = make()
    env.reset(seed=0)
    env.step(torch.ones(3, 2))
    for mask in (np.array([True, False, False]), torch.tensor([False, True, False])):
        before = env.state["n_observations"].clone()
        env.reset(options={"reset_mask": mask})
        m = torch.as_tensor(mask)
        assert torch.all(env.state["n_observations"][m] == 1) and torch.equal(
            env.state["n_observations"][~m], before[~m]
        )
    env.reset(options={})  # no options: every env


# ---- a closed env ---------------------------------------------------------------------------------------------


def test_a_closed_env_refuses_every_use():
    env = make()
    env.reset(seed=0)
    view = env.sub_env(1)
    env.close()
    for call in (
        lambda: env.step(torch.zeros(3, 2)),
        lambda: env.reset(seed=0),
        lambda: env.sub_env(0),
        lambda: env.state,
        lambda: view.position_mm,
        lambda: view.belief.particles,
        lambda: view.predicted_reading_model(np.zeros((4, 2)), np.zeros(2)),
    ):
        with pytest.raises(RuntimeError, match="closed env"):
            call()
    env.close()  # closing twice is nothing


@pytest.mark.parametrize("seed", [-1, "x", 2.5, True, [1, 2], b"1"])
def test_the_sb3_adapter_checks_a_seed_when_it_is_given(seed):
    pytest.importorskip("stable_baselines3")
    from electroloc_gym.envs.torch_sb3 import TorchSB3VecEnv

    match = r"seed must be None, an integer ≥ 0 or a sequence of 3 seeds"
    with pytest.raises(ValueError, match=match):
        TorchSB3VecEnv(make(), seed=seed)
    venv = TorchSB3VecEnv(make(), seed=0)
    with pytest.raises(ValueError, match=match):
        venv.seed(seed)
    assert venv.seed(5) == [5, 5, 5] and venv.reset().shape == (3, 81)


# ---- the sub-env's prediction accessors ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("particles", "moves", "match"),
    [
        (np.array([[NAN, 0.0], [0.0, 0.0]]), np.zeros(2), "particles_mm must be finite"),
        (np.array([[INF, 0.0], [0.0, 0.0]]), np.zeros(2), "particles_mm must be finite"),
        ("x", np.zeros(2), r"particles_mm must be a real number array of shape \(M, 2\), got dtype <U1: 'x'"),
        (np.zeros((2, 2), dtype=complex), np.zeros(2), "particles_mm must be a real number array .* complex128"),
        (np.zeros((2, 2), dtype=bool), np.zeros(2), "particles_mm must be a real number array .* bool"),
        ([[0.0, 1.0], [2.0]], np.zeros(2), "particles_mm must be a real number array .* got no array"),
        (np.zeros((2, 2)), "x", r"moves_mm must be a real number array of shape \(2,\) or \(C, 2\)"),
        (np.zeros((2, 2)), np.zeros(2, dtype=complex), "moves_mm must be a real number array .* complex128"),
    ],
)
def test_prediction_accessors_refuse_what_is_not_finite_real_numbers_on_both_engines(particles, moves, match):
    numba = gym.make("ElectroLoc-v0", n_particles=50).unwrapped
    numba.reset(seed=0)
    torch_env = make()
    torch_env.reset(seed=0)
    for env in (numba, torch_env.sub_env(0)):
        for accessor in (env.predicted_reading_model, env.predicted_particles_mm):
            with pytest.raises(ValueError, match=match):
                accessor(particles, moves)
