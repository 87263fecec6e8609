"""ElectroLoc-v0's ``distractors=``: D = 0 is the plain env bit for bit, superposition in the true reading only,
explicit layouts, count mixes, check_env, the native vector env and one clear error per bad value."""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from hypothesis import given, settings
from hypothesis import strategies as st

import electroloc_gym  # noqa: F401
from electroloc_gym.engines.numba_core.localize_task import LocalizeTask
from electroloc_gym.world.distractors import DistractorDraw, DistractorSet, superposed_reading_V
from electroloc_gym.world.scene import SceneObject

_DIGEST = Path(__file__).resolve().parents[1] / ".ci" / "trajectory_digest.py"


def _digest_module():
    spec = importlib.util.spec_from_file_location("trajectory_digest", _DIGEST)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_particles": 500},
        {"n_particles": 300, "sensor_model": "analytic", "condition": "random", "randomize_target": True},
    ],
)
def test_zero_distractors_is_the_plain_env_digest(kwargs) -> None:
    mod = _digest_module()
    plain = mod.digest("ElectroLoc-v0", kwargs, n_steps=30)
    assert mod.digest("ElectroLoc-v0", {**kwargs, "distractors": 0}, n_steps=30) == plain
    assert mod.digest("ElectroLoc-v0", {**kwargs, "distractors": DistractorDraw(count=0)}, n_steps=30) == plain


def test_zero_distractors_is_the_plain_env_step_by_step() -> None:
    kw = {"n_particles": 300, "condition": "random", "randomize_target": True}
    a, b = gym.make("ElectroLoc-v0", **kw), gym.make("ElectroLoc-v0", distractors=0, **kw)
    rng = np.random.default_rng(5)
    for seed in (1, 2):
        (oa, ia), (ob, ib) = a.reset(seed=seed), b.reset(seed=seed)
        assert np.array_equal(oa, ob)
        np.testing.assert_equal(ia, ib)
        done = False
        while not done:
            act = rng.uniform(-1, 1, 2).astype(np.float32)
            oa, ra, ta, tra, ia = a.step(act)
            ob, rb, tb, trb, ib = b.step(act)
            assert np.array_equal(oa, ob) and (ra, ta, tra) == (rb, tb, trb)
            np.testing.assert_equal(ia, ib)
            assert "distractors_mm" not in ib
            done = ta or tra
        assert np.array_equal(a.unwrapped.np_random.random(3), b.unwrapped.np_random.random(3))  # same stream


def test_true_reading_is_target_plus_distractors_and_the_model_knows_only_the_target() -> None:
    env = gym.make("ElectroLoc-v0", n_particles=300, distractors=3, condition="random", randomize_target=True)
    plain = gym.make("ElectroLoc-v0", n_particles=300, condition="random", randomize_target=True)
    for seed in range(4):
        _, info = env.reset(seed=seed)
        core = env.unwrapped
        state, task = core._state, core._task
        xy = info["distractors_mm"]
        assert xy.shape == (3, 2)
        scene = task.distractor_scene(state, 0)
        layout = DistractorSet(scene.objects)
        c = state.world[0]
        layout.validate(c, state.target_mm[0], gap_mm=DistractorDraw(count=1).gap_mm)  # clear of target, in box
        np.testing.assert_array_equal(xy, [o.xy_mm for o in scene.objects])
        ids = np.array([0])
        want = superposed_reading_V(c, state.target_mm[0], layout, state.position_mm[0], saturate=False)
        got = task.true_mean_V(state, ids)
        assert got[0] == pytest.approx(float(want), rel=1e-12, abs=1e-15)
        assert got[0] != LocalizeTask.true_mean_V(task, state, ids)[0]
        # the agent's model: the same object as the plain env's for this world (the target only)
        plain.reset(seed=seed)
        off = np.array([[[5.0, -3.0]]])
        np.testing.assert_array_equal(core.sensor_model.mean_std(off)[0], plain.unwrapped.sensor_model.mean_std(off)[0])


def test_explicit_layout_and_its_errors() -> None:
    objs = (
        SceneObject.of_material("cylinder", (30.0, -25.0), 12.7, "pvc"),
        SceneObject.of_material("sphere", (-30.0, 20.0), 19.05, "brass"),
    )
    env = gym.make("ElectroLoc-v0", n_particles=200, distractors=list(objs))
    for seed in (0, 1):
        _, info = env.reset(seed=seed)
        np.testing.assert_array_equal(info["distractors_mm"], [(30.0, -25.0), (-30.0, 20.0)])
    with pytest.raises(ValueError, match="distractors: an explicit layout needs randomize_target=False"):
        gym.make("ElectroLoc-v0", distractors=list(objs), randomize_target=True)
    on_target = SceneObject.of_material("sphere", (5.0, 0.0), 12.7, "steel")
    with pytest.raises(ValueError, match="distractors in condition 'fresh-steel-12.7'.*overlaps the target"):
        gym.make("ElectroLoc-v0", distractors=[on_target])


def test_count_mix_draws_each_count_and_pads_the_info() -> None:
    env = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=8,
        vectorization_mode="vector_entry_point",
        n_particles=100,
        distractors=[0, 1, 2],
        condition="random",
        randomize_target=True,
    )
    _, info = env.reset(seed=3)
    xy, counts = info["distractors_mm"], info["distractors_count"]
    assert xy.shape == (8, 2, 2) and xy.dtype == np.float64 and counts.shape == (8,)
    assert set(counts.tolist()) <= {0, 1, 2} and len(set(counts.tolist())) >= 2
    for row, n in zip(xy, counts, strict=True):
        assert np.isfinite(row[:n]).all() and not row[n:].any()


def test_a_count_mix_keeps_gymnasiums_sync_vector_env_working() -> None:
    kw = {"n_particles": 60, "sensor_model": "analytic", "distractors": [0, 1]}
    sync = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="sync", **kw)
    native = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    _, a = sync.reset(seed=[0, 1, 2])
    _, b = native.reset(seed=[0, 1, 2])
    np.testing.assert_array_equal(a["distractors_mm"], b["distractors_mm"])
    np.testing.assert_array_equal(a["distractors_count"], b["distractors_count"])


_VARIANTS = [
    ("ElectroLoc-v0", {"distractors": [0, 1, 2]}),
    ("ElectroLoc-v0", {"distractors": [0, 8]}),
    ("ElectroLoc-v0", {"distractors": 3, "condition": "random", "randomize_target": True}),
    ("ElectroLoc-v0", {"sensor_layout": "ring-8"}),
    ("ElectroLoc-v0", {"gain_levels": (0.1, 1.0, 10.0)}),
    ("ElectroLoc-v0", {"distractors": [0, 2], "gain_levels": (0.1, 1.0, 10.0)}),
    ("ElectroLocUnknownTarget-v0", {"n_particles": 300}),
]


def _shapes(info: dict) -> dict:
    return {k: np.shape(v) for k, v in info.items() if not k.startswith("_")}


@settings(max_examples=12, deadline=None, derandomize=True)
@given(variant=st.sampled_from(_VARIANTS), seed=st.integers(0, 2**31 - 1))
def test_info_keys_and_shapes_are_fixed_and_sync_equals_native(variant, seed) -> None:
    env_id, extra = variant
    kw = {"n_particles": 60, "sensor_model": "analytic", **extra}
    sync = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **kw)
    native = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kw)
    seeds = [seed, seed + 1]
    _, a = sync.reset(seed=seeds)
    _, b = native.reset(seed=seeds)
    sync_shapes, native_shapes = _shapes(a), _shapes(b)
    assert sync_shapes.keys() == native_shapes.keys()  # the same numeric info in both modes
    rng = np.random.default_rng(seed)
    for _ in range(3):  # new episodes, other seeds: the same keys and shapes
        act = rng.uniform(-1, 1, (2,) + native.single_action_space.shape).astype(np.float32)
        sync.step(act)
        native.step(act)
        seeds = [int(x) for x in rng.integers(0, 2**31 - 1, 2)]
        _, a = sync.reset(seed=seeds)
        _, b = native.reset(seed=seeds)
        assert _shapes(a) == sync_shapes and _shapes(b) == native_shapes
        for k, shape in native_shapes.items():  # tuples in single envs' infos stack otherwise
            if sync_shapes[k] == shape and np.asarray(b[k]).dtype.kind in "fiub":
                np.testing.assert_array_equal(a[k], b[k])


@settings(max_examples=25, deadline=None, derandomize=True)
@given(count=st.integers(0, 8), seed=st.integers(0, 2**32 - 1))
def test_every_count_and_seed_resets_single_and_vector_with_autoreset(count, seed) -> None:
    kw = {"n_particles": 40, "sensor_model": "analytic", "distractors": count, "max_observations": 2}
    _, info = gym.make("ElectroLoc-v0", **kw).reset(seed=seed)
    assert count == 0 or info["distractors_count"] == count
    vec = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    vec.reset(seed=seed)
    for _ in range(8):  # the cap of 2 readings: several autoresets
        vec.step(np.zeros((3, 2), dtype=np.float32))


def test_vector_env_equals_single_envs() -> None:
    kw = {"n_particles": 200, "distractors": 2, "condition": "random", "randomize_target": True}
    vec = gym.make_vec("ElectroLoc-v0", num_envs=3, vectorization_mode="vector_entry_point", **kw)
    seeds = [11, 12, 13]
    obs, info = vec.reset(seed=seeds)
    singles = [gym.make("ElectroLoc-v0", **kw) for _ in seeds]
    outs = [s.reset(seed=sd) for s, sd in zip(singles, seeds, strict=True)]
    for j, (o, i) in enumerate(outs):
        np.testing.assert_array_equal(obs[j], o)
        np.testing.assert_array_equal(info["distractors_mm"][j], i["distractors_mm"])
    rng = np.random.default_rng(0)
    for _ in range(6):
        act = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        obs, *_ = vec.step(act)
        for j, s in enumerate(singles):
            np.testing.assert_array_equal(obs[j], s.step(act[j])[0])


@pytest.mark.parametrize("distractors", [2, [0, 1, 2]])
def test_check_env_with_distractors(distractors) -> None:
    env = gym.make("ElectroLoc-v0", n_particles=200, distractors=distractors, condition="random", randomize_target=True)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped, skip_render_check=True)
    assert not [str(w.message) for w in record]


@pytest.mark.parametrize("bad", [-1, 9, True, 2.0, "two", [1, 9], {"cnt": 1}, [object()]])
def test_bad_values_are_one_error_naming_the_argument(bad) -> None:
    with pytest.raises(ValueError, match="distractors") as exc:
        gym.make("ElectroLoc-v0", distractors=bad)
    assert "\n" not in str(exc.value)


def test_other_envs_refuse_the_argument() -> None:
    with pytest.raises(ValueError, match=r"unexpected argument\(s\) \['distractors'\]"):
        gym.make("ElectroLocGlobal-v0", distractors=1)


def test_a_draw_that_cannot_fit_is_one_error_at_construction_naming_the_argument() -> None:
    with pytest.raises(ValueError, match=r"^distractors: count \(distractors\) 8 .* at most 4 always fit") as exc:
        gym.make(
            "ElectroLoc-v0",
            n_particles=50,
            sensor_model="analytic",
            distractors={"count": 8, "diameters_mm": (38.1,), "gap_mm": 20.0},
        )
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match=r"^distractors: .*random target in ±40 mm: at most 7 always fit"):
        gym.make("ElectroLoc-v0", distractors=8, randomize_target=True)
    gym.make("ElectroLoc-v0", n_particles=50, distractors=8).reset(seed=4)  # the fixed target: 8 fit


def test_distractors_with_a_sensor_array_are_one_error_and_each_alone_keeps_the_other_off() -> None:
    with pytest.raises(ValueError, match="^distractors: .*sensor_layout"):
        gym.make("ElectroLoc-v0", sensor_layout="ring-8", distractors=1)
    _, info = gym.make("ElectroLoc-v0", sensor_layout="ring-8", n_particles=100).reset(seed=0)
    assert "pair_readings_V" in info and "distractors_mm" not in info
    _, info = gym.make("ElectroLoc-v0", distractors=1, n_particles=100).reset(seed=0)
    assert "distractors_mm" in info and "pair_readings_V" not in info
