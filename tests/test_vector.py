"""The native vector env: exact per-env equivalence with ElectroLoc-v0, API, bad inputs."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from reference_filter import ParticleBelief, egocentric_histogram

import electroloc_gym  # noqa: F401
from electroloc_gym.contract.observation import HIST_BINS, INFO_KEYS
from electroloc_gym.envs import ElectroLocVectorEnv
from electroloc_gym.envs.vector import sub_env_seeds
from electroloc_gym.kernels import loglik_assimilate
from electroloc_gym.kernels.streams import normal_table
from electroloc_gym.sensor_models import CalibratedSensorModel


def _native(n: int, **kw: Any) -> ElectroLocVectorEnv:
    env = gym.make_vec("ElectroLoc-v0", num_envs=n, vectorization_mode="vector_entry_point", **kw)
    return env


def _reference(n: int, mode: AutoresetMode, **kw: Any) -> gym.vector.SyncVectorEnv:
    return gym.vector.SyncVectorEnv([lambda: gym.make("ElectroLoc-v0", **kw) for _ in range(n)], autoreset_mode=mode)


def _info_equal(a: dict[str, Any], b: dict[str, Any], where: str) -> None:
    """Native info vs SyncVectorEnv info: the same numeric arrays (no object arrays in either)."""
    for key in INFO_KEYS:
        x, y = a[key], b[key]
        assert x.dtype != object and y.dtype == x.dtype, f"{where}: info[{key!r}] dtypes {x.dtype}, {y.dtype}"
        assert np.array_equal(x, y), f"{where}: info[{key!r}] differs"


def _actions(space: gym.Space, n_steps: int, seed: int) -> list[Any]:
    space.seed(seed)
    return [space.sample() for _ in range(n_steps)]


CASES = [
    pytest.param({"n_particles": 400}, AutoresetMode.NEXT_STEP, 120, id="calibrated-next"),
    pytest.param(
        {"n_particles": 300, "sensor_model": "analytic", "condition": "random", "randomize_target": True},
        AutoresetMode.NEXT_STEP,
        120,
        id="analytic-random-target",
    ),
    pytest.param({"n_particles": 300, "condition": "random"}, AutoresetMode.SAME_STEP, 120, id="random-same-step"),
    pytest.param(
        {"n_particles": 200, "observation": "raw", "action_type": "discrete", "max_observations": 6},
        AutoresetMode.NEXT_STEP,
        80,
        id="raw-discrete",
    ),
    pytest.param(
        {
            "n_particles": 250,
            "calibration_seed": 7,
            "signal": "paper",
            "condition": "salt-delrin-38.1",
            "success_spread_mm": 14.0,
        },
        AutoresetMode.SAME_STEP,
        80,
        id="fixed-calibration-paper",
    ),
]


@pytest.mark.parametrize(("kwargs", "mode", "n_steps"), CASES)
def test_native_equals_sync_of_single_envs_bit_for_bit(
    kwargs: dict[str, Any], mode: AutoresetMode, n_steps: int
) -> None:
    n = 5
    native = _native(n, autoreset_mode=mode, **kwargs)
    ref = _reference(n, mode, **kwargs)
    assert native.metadata["autoreset_mode"] is mode
    assert native.single_observation_space == ref.single_observation_space
    assert native.action_space == ref.action_space
    o1, i1 = native.reset(seed=11)
    o2, i2 = ref.reset(seed=sub_env_seeds(11, n))
    assert np.array_equal(o1, o2)
    _info_equal(i1, i2, "reset")
    ended = 0
    for t, a in enumerate(_actions(ref.action_space, n_steps, seed=3)):
        o1, r1, te1, tr1, i1 = native.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        assert o1.dtype == np.float32 and o1.shape == o2.shape
        assert np.array_equal(o1, o2), f"step {t}: observations differ"
        assert np.array_equal(r1, r2) and np.array_equal(te1, te2) and np.array_equal(tr1, tr2), f"step {t}"
        _info_equal(i1, i2, f"step {t}")
        if mode is AutoresetMode.SAME_STEP and (te1 | tr1).any():
            done = te1 | tr1
            assert np.array_equal(i1["_final_obs"], done) and np.array_equal(i1["_final_obs"], i2["_final_obs"])
            for j in np.flatnonzero(done):
                assert np.array_equal(i1["final_obs"][j], i2["final_obs"][j])
                for key in ("spread_mm", "error_mm", "n_observations", "success"):
                    assert i1["final_info"][key][j] == i2["final_info"][key][j]
        ended += int((te1 | tr1).sum())
    assert ended >= 3, "the rollout should cross several autoresets"


def test_default_kwargs_match_single_env_at_2500_particles() -> None:
    native = _native(3)
    ref = _reference(3, AutoresetMode.NEXT_STEP)
    assert np.array_equal(native.reset(seed=5)[0], ref.reset(seed=sub_env_seeds(5, 3))[0])
    for a in _actions(ref.action_space, 40, seed=0):
        r1, r2 = native.step(a), ref.step(a)
        assert np.array_equal(r1[0], r2[0]) and np.array_equal(r1[2], r2[2]) and np.array_equal(r1[3], r2[3])
    # The per-episode calibrated models (built on demand) are the single envs' models.
    for mine, theirs in zip(native.unwrapped.sensor_models, ref.get_attr("sensor_model"), strict=True):
        assert mine.seed == theirs.seed and np.array_equal(mine.std_table_V, theirs.std_table_V)


def test_make_vec_entry_point_and_spaces() -> None:
    env = gym.make_vec("ElectroLoc-v0", num_envs=4, vectorization_mode="vector_entry_point", n_particles=100)
    assert isinstance(env.unwrapped, ElectroLocVectorEnv)
    assert env.num_envs == 4
    assert env.observation_space.shape == (4, 81) and env.action_space.shape == (4, 2)
    assert isinstance(env.metadata["autoreset_mode"], AutoresetMode)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert info["position_mm"].shape == (4, 2) and info["_spread_mm"].all()
    u = env.unwrapped
    p = u.particles_mm
    p[:] = 1e6  # a copy: writing to it does not touch the env
    assert p.shape == (4, 100, 2) and np.all(u.particles_mm < 1e3)
    assert len(u.sensor_models) == 4 and all(isinstance(m, CalibratedSensorModel) for m in u.sensor_models)
    assert np.array_equal(u.n_observations, np.ones(4))
    env.close()


def test_same_seed_same_rollout_and_seed_list() -> None:
    a, b = _native(3, n_particles=150), _native(3, n_particles=150)
    oa, _ = a.reset(seed=sub_env_seeds(4, 3))
    ob, _ = b.reset(seed=4)
    assert np.array_equal(oa, ob)
    for act in _actions(a.action_space, 30, seed=1):
        ra, rb = a.step(act), b.step(act)
        assert np.array_equal(ra[0], rb[0]) and np.array_equal(ra[2], rb[2])


def test_reset_mask_resets_only_selected_envs() -> None:
    env = _native(3, n_particles=150)
    env.reset(seed=0)
    for act in _actions(env.action_space, 3, seed=2):
        env.step(act)
    before = env.unwrapped.n_observations
    mask = np.array([False, True, False])
    obs, _ = env.reset(seed=[None, 42, None], options={"reset_mask": mask})
    single = gym.make("ElectroLoc-v0", n_particles=150)
    assert np.array_equal(obs[1], single.reset(seed=42)[0])
    after = env.unwrapped.n_observations
    assert after[1] == 1 and after[0] == before[0] and after[2] == before[2]


def test_max_episode_steps_truncates_like_time_limit() -> None:
    native = _native(2, n_particles=120, max_episode_steps=3, success_spread_mm=1e-6)
    ref = gym.vector.SyncVectorEnv(
        [
            lambda: gym.make("ElectroLoc-v0", n_particles=120, max_episode_steps=3, success_spread_mm=1e-6)
            for _ in range(2)
        ]
    )
    native.reset(seed=1)
    ref.reset(seed=sub_env_seeds(1, 2))
    for act in _actions(ref.action_space, 8, seed=0):
        r1, r2 = native.step(act), ref.step(act)
        assert np.array_equal(r1[0], r2[0]) and np.array_equal(r1[3], r2[3]) and np.array_equal(r1[1], r2[1])


def test_resample_kernel_equals_belief_resample_and_jitter() -> None:
    """The compiled update (weights, systematic resampling, jitter, clip, statistics) equals the numpy reference."""
    rng = np.random.default_rng(0)

    class _Fixed:
        """A generator whose resampling offset is ``u`` and whose raw bits are ``raw``."""

        def __init__(self, u: float, raw: np.ndarray) -> None:
            self.u, self.bit_generator = u, self

            def random_raw(n: int) -> np.ndarray:
                return raw[:n]

            self.random_raw = random_raw

        def random(self, shape: tuple[int, ...]) -> np.ndarray:
            return np.full(shape, self.u)

    for trial in range(300):
        n, m = int(rng.integers(1, 4)), int(rng.integers(1, 400))
        kind = trial % 4
        if kind == 0:
            e = rng.random((n, m))
        elif kind == 1:  # very peaked
            e = np.exp(rng.normal(size=(n, m)) * rng.uniform(0, 40))
        elif kind == 2:  # mostly zeros
            e = (rng.random((n, m)) < 0.1) * 1.0
            e[:, 0] += 1e-300
        else:  # uniform: pointers land on the cumulative sums (ties)
            e = np.ones((n, m))
        with np.errstate(divide="ignore"):
            ll = np.log(e)
        ll = ll.astype(np.float32)  # the sensor models' log-likelihoods are float32
        u = np.zeros(n) if trial % 5 == 0 else rng.random(n)
        half = np.float32(rng.uniform(5, 60))
        aos = rng.uniform(-half, half, (n, m, 2)).astype(np.float32)
        raw = rng.integers(0, 2**64, size=(n, (2 * m + 3) // 4), dtype=np.uint64)
        jitter_idx = np.ascontiguousarray(raw.view(np.uint16)[:, : 2 * m])
        out = np.ascontiguousarray(aos.transpose(0, 2, 1))  # updated in place
        mean, cov, counts = np.empty((n, 2)), np.empty((n, 2, 2)), np.empty((n, HIST_BINS * HIST_BINS))
        origin = rng.uniform(-half, half, (n, 2))
        assert (
            loglik_assimilate(
                ll,
                out,
                origin.astype(np.float32),
                u,
                jitter_idx,
                normal_table(),
                np.full(n, half, dtype=np.float32),
                out,
                mean,
                cov,
                np.full(n, 2 * half, dtype=np.float32),
                HIST_BINS,
                counts,
            )
            == -1
        )
        for i in range(n):
            b = ParticleBelief(m, (-half, -half), (half, half), dtype=np.float32)
            b.set_state(aos[i])
            b.update(ll[i])
            fixed = _Fixed(u[i], raw[i])
            b.resample(fixed)
            b.jitter(fixed)
            assert np.array_equal(out[i].T, b.particles), f"trial {trial}, cloud {i}"
            assert np.array_equal(mean[i], b.mean()) and np.array_equal(cov[i], b.covariance())
            hist = egocentric_histogram(b.particles, None, origin[i].astype(np.float32), np.asarray(float(half)))
            assert np.array_equal(counts[i] / m, hist)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num_envs": 0}, "num_envs"),
        ({"num_envs": 2, "autoreset_mode": "sometimes"}, "autoreset_mode"),
        ({"num_envs": 2, "autoreset_mode": AutoresetMode.DISABLED}, "autoreset_mode"),
        ({"num_envs": 2, "render_mode": "rgb_array"}, "render_mode"),
        ({"num_envs": 2, "max_episode_steps": 0}, "max_episode_steps"),
        ({"num_envs": 2, "n_particles": 0}, "n_particles"),
        ({"num_envs": 2, "observation": "pixels"}, "observation"),
        ({"num_envs": 2, "condition": "mud-steel-12.7"}, "mud"),
    ],
)
def test_bad_constructor_arguments(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises((ValueError, KeyError), match=match):
        ElectroLocVectorEnv(**kwargs)


def test_bad_actions_and_step_before_reset() -> None:
    env = ElectroLocVectorEnv(num_envs=2, n_particles=50)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((2, 2), dtype=np.float32))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((3, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([[np.nan, 0.0], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=[1, 2, 3])
    denv = ElectroLocVectorEnv(num_envs=2, n_particles=50, action_type="discrete")
    denv.reset(seed=0)
    with pytest.raises(ValueError, match="integers"):
        denv.step(np.array([0, 9]))


# ---- SB3 adapter (electroloc_gym/train/native_vec.py) --------------------------------------------------------
def test_sb3_adapter_equals_dummy_vec_env() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from electroloc_gym.train.native_vec import make_native_vec_env

    kw = {"n_particles": 200, "condition": "random"}
    native = make_native_vec_env("ElectroLoc-v0", 4, seed=9, env_kwargs=kw)
    dummy = DummyVecEnv([lambda: Monitor(gym.make("ElectroLoc-v0", **kw)) for _ in range(4)])
    dummy.seed(9)
    assert native.observation_space == dummy.observation_space and native.action_space == dummy.action_space
    assert np.array_equal(native.reset(), dummy.reset())
    rng = np.random.default_rng(0)
    n_done = 0
    for _ in range(60):
        a = rng.uniform(-1, 1, size=(4, 2)).astype(np.float32)
        o1, r1, d1, i1 = native.step(a)
        o2, r2, d2, i2 = dummy.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        for x, y in zip(i1, i2, strict=True):
            assert x["TimeLimit.truncated"] == y["TimeLimit.truncated"]
            assert x["spread_mm"] == y["spread_mm"] and np.array_equal(x["position_mm"], y["position_mm"])
            assert x["condition_index"] == y["condition_index"] and "condition" not in x
            if "terminal_observation" in y:
                assert np.array_equal(x["terminal_observation"], y["terminal_observation"])
                assert x["episode"]["r"] == y["episode"]["r"] and x["episode"]["l"] == y["episode"]["l"]
                assert x["is_success"] == y["success"]
        n_done += int(d1.sum())
    assert n_done >= 3


def test_sb3_ppo_learns_on_native_adapter_smoke() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from electroloc_gym.train.native_vec import NativeVecEnv, make_native_vec_env

    venv = make_native_vec_env("ElectroLoc-v0", 2, seed=0, env_kwargs={"n_particles": 100})
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(64)
    assert model.num_timesteps >= 64
    with pytest.raises(ValueError, match="SAME_STEP"):
        NativeVecEnv(ElectroLocVectorEnv(num_envs=2, n_particles=10))
    with pytest.raises(ValueError, match="vector_entry_point"):
        make_native_vec_env("Pendulum-v1", 2, seed=0)


def test_sb3_adapter_shaping_equals_potential_shaping_wrapper() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from electroloc_gym.train.native_vec import make_native_vec_env
    from electroloc_gym.train.wrappers import PotentialShaping

    kw = {"n_particles": 200, "max_observations": 8}
    native = make_native_vec_env("ElectroLoc-v0", 3, seed=2, env_kwargs=kw, shaping_coef=1.0, gamma=0.9)
    dummy = DummyVecEnv(
        [lambda: PotentialShaping(Monitor(gym.make("ElectroLoc-v0", **kw)), 1.0, 0.9) for _ in range(3)]
    )
    dummy.seed(2)
    assert np.array_equal(native.reset(), dummy.reset())
    rng = np.random.default_rng(1)
    n_done = 0
    for _ in range(40):
        a = rng.uniform(-1, 1, size=(3, 2)).astype(np.float32)
        o1, r1, d1, i1 = native.step(a)
        o2, r2, d2, i2 = dummy.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(d1, d2)
        np.testing.assert_allclose(r1, r2, rtol=1e-6, atol=1e-6)
        for x, y in zip(i1, i2, strict=True):
            if "episode" in y:  # the logged return is the unshaped one in both stacks
                assert x["episode"]["r"] == y["episode"]["r"]
        n_done += int(d1.sum())
    assert n_done >= 3


# ---- ElectroLocGlobal-v0 (fixed map) ------------------------------------------------------------
GLOBAL_CASES = [
    pytest.param({"n_particles": 300}, AutoresetMode.NEXT_STEP, id="global-calibrated-next"),
    pytest.param(
        {"n_particles": 300, "sensor_model": "analytic", "observation": "raw"},
        AutoresetMode.SAME_STEP,
        id="global-analytic-raw-same-step",
    ),
    pytest.param({"n_particles": 200, "layout": "random"}, AutoresetMode.SAME_STEP, id="global-random-layout"),
]


@pytest.mark.parametrize(("kwargs", "mode"), GLOBAL_CASES)
def test_global_native_equals_sync_of_single_envs(kwargs: dict[str, Any], mode: AutoresetMode) -> None:
    n = 3
    native = gym.make_vec(
        "ElectroLocGlobal-v0", num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs
    )
    ref = gym.vector.SyncVectorEnv(
        [lambda: gym.make("ElectroLocGlobal-v0", **kwargs) for _ in range(n)], autoreset_mode=mode
    )
    o1, _ = native.reset(seed=21)
    o2, _ = ref.reset(seed=sub_env_seeds(21, n))
    assert np.array_equal(o1, o2)
    ended = 0
    for t, a in enumerate(_actions(ref.action_space, 70, seed=4)):
        o1, r1, te1, tr1, i1 = native.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        assert np.array_equal(o1, o2), f"step {t}: observations differ"
        assert np.array_equal(r1, r2) and np.array_equal(te1, te2) and np.array_equal(tr1, tr2), f"step {t}"
        _info_equal(i1, i2, f"step {t}")
        ended += int((te1 | tr1).sum())
    assert ended >= 2


@pytest.mark.parametrize(
    "kwargs", [{"n_particles": 257}, {"n_particles": 257, "sensor_model": "analytic", "condition": "random"}]
)
def test_sub_env_values_do_not_depend_on_the_batch_size(kwargs: dict[str, Any]) -> None:
    """Sub-env i of N = 1, 3 and 17 native envs seeded alike: the same bits (SIMD body vs tail of every array)."""
    envs = {n: _native(n, **kwargs) for n in (1, 3, 17)}
    obs = {n: e.reset(seed=40)[0] for n, e in envs.items()}
    assert np.array_equal(obs[3][0], obs[1][0]) and np.array_equal(obs[17][:3], obs[3])
    rng = np.random.default_rng(2)
    for _ in range(25):
        a = rng.uniform(-1, 1, (17, 2)).astype(np.float32)
        out = {n: e.step(a[:n]) for n, e in envs.items()}
        for n_small, n_big in ((1, 3), (3, 17)):
            small, big = out[n_small], out[n_big]
            assert np.array_equal(big[0][:n_small], small[0])
            assert np.array_equal(big[4]["reading_V"][:n_small], small[4]["reading_V"])
            assert np.array_equal(big[4]["estimate_mm"][:n_small], small[4]["estimate_mm"])
