"""``reset``'s options and the first reset, on every env of the table and both engines
(electroloc_gym/contract/reset.py): one check of the options with the same message on both engines, no partial
reset before a full one, and no step before any reset.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import electroloc_gym  # noqa: F401 - registers the ids
from electroloc_gym.registry import ENV_IDS, env_entry

N = 3
KW = {"n_particles": 50}
PARTIAL = np.array([True, False, False])


def _vector(env_id: str, engine: str) -> Any:
    if engine == "torch":
        pytest.importorskip("torch")
    return gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", backend=engine, **KW).unwrapped


def _kinds() -> list[Any]:
    """(env id, "single" / "numba" / "torch"): every id's single env and native vector env, and its torch vector env
    where the entry has one."""
    out = []
    for env_id in ENV_IDS:
        out += [pytest.param(env_id, kind, id=f"{env_id}-{kind}") for kind in ("single", "numba")]
        if "torch" in env_entry(env_id).backends:
            out.append(pytest.param(env_id, "torch", id=f"{env_id}-torch"))
    return out


def _vector_kinds() -> list[Any]:
    return [p for p in _kinds() if p.values[1] != "single"]


def _zero_actions(env: Any) -> Any:
    a = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    if getattr(env, "device", None) is not None:
        import torch

        return torch.as_tensor(a)
    return a


def _n_observations(env: Any) -> np.ndarray:
    if getattr(env, "device", None) is not None:
        return env.state["n_observations"].cpu().numpy().copy()
    return np.atleast_1d(np.asarray(env.n_observations)).copy()


# ---- no step before a reset -----------------------------------------------------------------------------------
@pytest.mark.parametrize(("env_id", "kind"), _kinds())
def test_a_step_before_any_reset_is_refused(env_id: str, kind: str) -> None:
    if kind == "single":
        env = gym.make(env_id, **KW)
        with pytest.raises(gym.error.ResetNeeded):  # Gymnasium's order check, then the env's own
            env.step(env.action_space.sample())
        core = env.unwrapped
        with pytest.raises(RuntimeError, match=r"^call reset\(\) before step\(\)$"):
            core.step(core.action_space.sample())
        return
    env = _vector(env_id, kind)
    with pytest.raises(RuntimeError, match=r"^call reset\(\) before step\(\)$"):
        env.step(_zero_actions(env))


@pytest.mark.parametrize(("env_id", "kind"), _vector_kinds())
def test_a_partial_reset_before_a_full_one_is_one_error_and_changes_nothing(env_id: str, kind: str) -> None:
    env = _vector(env_id, kind)
    with pytest.raises(
        ValueError, match=r"^options\['reset_mask'\] .* before the first full reset: call reset\(\) without"
    ):
        env.reset(seed=0, options={"reset_mask": PARTIAL})
    with pytest.raises(RuntimeError, match=r"^call reset\(\) before step\(\)$"):  # still never reset
        env.step(_zero_actions(env))
    env.reset(seed=0, options={"reset_mask": np.ones(N, dtype=bool)})  # every sub-env: a full reset
    env.step(_zero_actions(env))
    env.reset(seed=1, options={"reset_mask": PARTIAL})  # after a full reset, a partial one is allowed
    assert _n_observations(env).tolist() == [1, 2, 2]


# ---- one check of the options, the same message on both engines -------------------------------------------------
BAD_VECTOR_OPTIONS = [
    ("notadict", r"^options must be None or a dict with keys among \['reset_mask'\], got 'notadict'$"),
    ("reset_mask", r"^options must be None or a dict with keys among \['reset_mask'\], got 'reset_mask'$"),
    ([("reset_mask", PARTIAL)], r"^options must be None or a dict with keys among \['reset_mask'\]"),
    ({"resetmask": PARTIAL}, r"^options has unknown key\(s\) \['resetmask'\]; allowed: \['reset_mask'\]$"),
    ({"seed": 3, "reset_mask": PARTIAL}, r"^options has unknown key\(s\) \['seed'\]; allowed: \['reset_mask'\]$"),
    ({"reset_mask": None}, r"^options\['reset_mask'\] must be a bool array of shape \(3,\) with a True entry$"),
    ({"reset_mask": [True, False, True]}, r"^options\['reset_mask'\] must be a bool array"),
    ({"reset_mask": "abc"}, r"^options\['reset_mask'\] must be a bool array"),
    ({"reset_mask": np.zeros(N, dtype=bool)}, r"^options\['reset_mask'\] must be .* with a True entry$"),
    ({"reset_mask": np.ones(N + 1, dtype=bool)}, r"^options\['reset_mask'\] must be a bool array of shape \(3,\)"),
]


@pytest.mark.parametrize(("env_id", "kind"), _vector_kinds())
def test_bad_reset_options_are_one_error_before_anything_changes(env_id: str, kind: str) -> None:
    env = _vector(env_id, kind)
    env.reset(seed=0)
    env.step(_zero_actions(env))
    before = _n_observations(env)
    for options, match in BAD_VECTOR_OPTIONS:
        with pytest.raises(ValueError, match=match):
            env.reset(seed=1, options=options)
        assert np.array_equal(_n_observations(env), before), f"{options!r} changed the env"
    env.reset(seed=1, options={})  # no options: every sub-env
    assert _n_observations(env).tolist() == [1] * N


def test_the_engines_give_the_same_message_for_each_bad_option() -> None:
    pytest.importorskip("torch")
    numba, torch_env = _vector("ElectroLoc-v0", "numba"), _vector("ElectroLoc-v0", "torch")
    cases = [options for options, _ in BAD_VECTOR_OPTIONS] + [{"reset_mask": PARTIAL}]  # the last before a reset
    for options in cases:
        with pytest.raises(ValueError) as a:
            numba.reset(seed=0, options=options)
        with pytest.raises(ValueError) as b:
            torch_env.reset(seed=0, options=options)
        assert str(a.value) == str(b.value), options


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_single_env_takes_no_reset_options(env_id: str) -> None:
    """``None`` or ``{}`` (what Gymnasium's vector envs hand their sub-envs); any key is refused, the allowed
    keys (none) listed — a ``reset_mask`` is the vector env's."""
    env = gym.make(env_id, **KW)
    env.reset(seed=0, options=None)
    env.reset(seed=0, options={})
    for options, match in [
        ({"reset_mask": PARTIAL}, r"^options has unknown key\(s\) \['reset_mask'\]; allowed: none \(.*\)$"),
        ({"resetmask": 1}, r"^options has unknown key\(s\) \['resetmask'\]; allowed: none"),
        ("reset_mask", r"^options must be None or an empty dict \(.*\), got 'reset_mask'$"),
    ]:
        with pytest.raises(ValueError, match=match):
            env.reset(seed=1, options=options)
    assert env.unwrapped.n_observations == 1


def test_a_sync_vector_env_of_single_envs_still_resets_by_mask() -> None:
    """Gymnasium's SyncVectorEnv takes ``reset_mask`` itself and hands its sub-envs the rest (``{}``)."""
    env = gym.vector.SyncVectorEnv([lambda: gym.make("ElectroLoc-v0", **KW) for _ in range(N)])
    env.reset(seed=0)
    env.step(np.zeros((N, 2), dtype=np.float32))
    env.reset(options={"reset_mask": PARTIAL})
    assert [e.unwrapped.n_observations for e in env.envs] == [1, 2, 2]
