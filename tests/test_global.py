"""The multi-object scene, the map's sensor models and ElectroLocGlobal-v0 (paper §6.5)."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import electroloc_gym
from electroloc_gym import physics
from electroloc_gym.conditions import Amplifier, Condition, Target, Water
from electroloc_gym.envs.self_localize import GlobalLocalizationEnv
from electroloc_gym.scene import (
    BENCHMARK_LAYOUT_SEED,
    BENCHMARK_SCENE,
    STOCK_DIAMETERS_MM,
    Scene,
    SceneObject,
    cylinder_differential_perturbation,
    map_eev,
    random_cylinder_layout,
)
from electroloc_gym.sensor import expected_reading
from electroloc_gym.sensor_models.map import make_map_sensor_model

GLOBAL_ID = "ElectroLocGlobal-v0"


def _mixed_scene() -> Scene:
    objs = (
        SceneObject.of_material("cylinder", (30.0, -20.0), 19.05, "steel"),
        SceneObject.of_material("cylinder", (-45.0, 10.0), 25.4, "delrin"),
        SceneObject("sphere", (5.0, 40.0), 6.35, 1.4e10, "steel"),
        SceneObject("sphere", (-20.0, -50.0), 19.05, 1e-9, "delrin"),
        SceneObject.of_material("cylinder", (60.0, 60.0), 12.7, "agar"),
    )
    return BENCHMARK_SCENE.replace(name="mixed", objects=objs)


def _carriages(n: int = 500, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-80.0, 80.0, size=(n, 2))


# ---------------------------------------------------------------------------------------------
# Physics of the scene
# ---------------------------------------------------------------------------------------------
def test_superposition_equals_sum_of_single_object_perturbations() -> None:
    scene = _mixed_scene()
    p = _carriages()
    singles = [scene.replace(objects=(o,)).perturbation(p) for o in scene.objects]
    np.testing.assert_allclose(scene.perturbation(p), np.sum(singles, axis=0), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(scene.object_perturbations(p).sum(axis=-1), scene.perturbation(p), rtol=1e-12)
    # The reading is the amplified, scaled sum (docs/design.md, "Physics"), saturated at ±10 V.
    g = scene.amplifier.gain * scene.signal_scale
    np.testing.assert_allclose(scene.expected_reading(p, saturate=False), g * np.sum(singles, axis=0), rtol=1e-12)
    loud = scene.replace(signal_scale=500.0)
    assert np.abs(loud.expected_reading(p)).max() == pytest.approx(10.0)


def test_single_sphere_scene_equals_the_single_target_sensor() -> None:
    """A one-sphere scene reads exactly what ElectroLoc-v0's sensor reads for that sphere."""
    cond = Condition(name="s", target=Target(radius_mm=6.35, conductivity_uScm=1.4e10), water=Water(160.0),
                     amplifier=Amplifier(gain=191.0, noise_rms_mV=0.25), start_half_width_mm=40.0,
                     allowed_half_width_mm=50.0, target_xy_mm=(12.0, -7.0), signal_scale=0.9)
    scene = Scene(name="one", objects=(SceneObject("sphere", (12.0, -7.0), 6.35, 1.4e10),), water=Water(160.0),
                  amplifier=Amplifier(gain=191.0, noise_rms_mV=0.25), allowed_half_width_mm=50.0,
                  start_half_width_mm=40.0, signal_scale=0.9)
    p = _carriages(300) * 0.6
    np.testing.assert_allclose(scene.expected_reading(p), expected_reading(cond, np.array([12.0, -7.0]) - p),
                               rtol=1e-12, atol=1e-15)


def test_cylinder_at_depth_zero_is_the_physics_2d_formula() -> None:
    """With the dipole point in the electrode plane the fast path equals physics.cylinder_perturbation."""
    rng = np.random.default_rng(1)
    off = rng.uniform(-60, 60, size=(400, 2))
    h = 25.0
    c = np.concatenate([off, np.zeros((400, 1))], axis=-1)
    e = physics.emitter_field(c, np.array([h, 0.0, 0.0]), np.array([-h, 0.0, 0.0]))
    s1, s2 = np.array([0.0, h, 0.0]), np.array([0.0, -h, 0.0])
    ref = (physics.cylinder_perturbation(s1, c, 9.0, 0.7, e) - physics.cylinder_perturbation(s2, c, 9.0, 0.7, e))
    np.testing.assert_allclose(cylinder_differential_perturbation(off, 9.0, 0.7, 0.0), ref, rtol=1e-9, atol=1e-14)


def test_cylinder_fast_path_equals_direct_3d_evaluation() -> None:
    rng = np.random.default_rng(2)
    off = rng.uniform(-60, 60, size=(400, 2))
    depth, a, chi2, h = 15.0, 12.0, -0.9, 25.0
    c = np.concatenate([off, np.full((400, 1), -depth)], axis=-1)
    e = physics.emitter_field(c, np.array([h, 0.0, 0.0]), np.array([-h, 0.0, 0.0]))

    def dv(s):
        d = s - c
        return chi2 * a**2 * np.sum(e * d, axis=-1) / np.sum(d * d, axis=-1)

    ref = dv(np.array([0.0, h, 0.0])) - dv(np.array([0.0, -h, 0.0]))
    np.testing.assert_allclose(cylinder_differential_perturbation(off, a, chi2, depth), ref, rtol=1e-9, atol=1e-14)
    # float32 in, float32 out (the belief's fast path), close to float64
    f32 = cylinder_differential_perturbation(off.astype(np.float32), a, chi2, depth)
    assert f32.dtype == np.float32
    np.testing.assert_allclose(f32, ref, rtol=1e-3, atol=1e-6)


def test_conductor_and_insulator_cylinders_have_opposite_signs() -> None:
    p = _carriages(200)
    steel = BENCHMARK_SCENE.replace(objects=(SceneObject.of_material("cylinder", (10.0, 5.0), 19.05, "steel"),))
    pvc = BENCHMARK_SCENE.replace(objects=(SceneObject.of_material("cylinder", (10.0, 5.0), 19.05, "pvc"),))
    np.testing.assert_allclose(steel.perturbation(p), -pvc.perturbation(p), rtol=1e-6)


def test_map_is_finite_everywhere_including_over_the_objects() -> None:
    scene = _mixed_scene()
    pts = np.array([o.xy_mm for o in scene.objects] + [[o.xy_mm[0] + 25.0, o.xy_mm[1]] for o in scene.objects])
    assert np.all(np.isfinite(scene.expected_reading(pts)))
    grid, phi = map_eev(scene, step_mm=2.0)
    assert phi.shape == (grid.size, grid.size) and np.all(np.isfinite(phi))


def test_noisy_reading_statistics() -> None:
    rng = np.random.default_rng(3)
    p = np.tile(np.array([[12.0, -30.0]]), (20000, 1))
    r = BENCHMARK_SCENE.noisy_reading(p, rng)
    mu = float(BENCHMARK_SCENE.expected_reading(p[0]))
    assert abs(r.mean() - mu) < 5 * BENCHMARK_SCENE.noise_std_V / np.sqrt(p.shape[0])
    assert r.std() == pytest.approx(BENCHMARK_SCENE.noise_std_V, rel=0.03)
    assert isinstance(float(BENCHMARK_SCENE.noisy_reading(p[0], rng)), float)  # scalar path


# ---------------------------------------------------------------------------------------------
# Layouts
# ---------------------------------------------------------------------------------------------
def test_layout_generator_is_seeded_and_paper_like() -> None:
    for seed in range(20):
        objs = random_cylinder_layout(seed)
        assert objs == random_cylinder_layout(np.random.default_rng(seed))
        assert len(objs) == 6 and all(o.shape == "cylinder" for o in objs)
        assert len({o.diameter_mm for o in objs}) == 6 and len({o.material for o in objs}) == 6
        assert all(abs(c) <= 80.0 for o in objs for c in o.xy_mm)
        for i, a in enumerate(objs):
            for b in objs[i + 1:]:
                gap = np.hypot(a.xy_mm[0] - b.xy_mm[0], a.xy_mm[1] - b.xy_mm[1]) - a.radius_mm - b.radius_mm
                assert gap >= 5.0 - 0.2  # 5 mm apart, less the rounding of the centres to 0.1 mm
    assert random_cylinder_layout(0) != random_cylinder_layout(1)


def test_benchmark_layout_is_the_documented_generator_output() -> None:
    assert BENCHMARK_SCENE.objects == random_cylinder_layout(BENCHMARK_LAYOUT_SEED)
    assert sorted(o.diameter_mm for o in BENCHMARK_SCENE.objects) == sorted(STOCK_DIAMETERS_MM)
    assert BENCHMARK_SCENE.water.conductivity_uScm == 160.0 and BENCHMARK_SCENE.amplifier.gain == 191.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(n_objects=0), "n_objects"),
    (dict(half_width_mm=-1.0), "half_width_mm"),
    (dict(materials=("gold",)), "materials"),
    (dict(n_objects=40, min_gap_mm=10.0, max_tries=50), "could not place"),
])
def test_layout_generator_bad_arguments(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        random_cylinder_layout(0, **kwargs)


@pytest.mark.parametrize("make, match", [
    (lambda: SceneObject("cube", (0.0, 0.0), 5.0, 1.0), "shape"),
    (lambda: SceneObject("sphere", (0.0, 0.0), -5.0, 1.0), "radius_mm"),
    (lambda: SceneObject("sphere", (0.0, np.nan), 5.0, 1.0), "xy_mm"),
    (lambda: SceneObject.of_material("cylinder", (0.0, 0.0), 5.0, "wood"), "material"),
    (lambda: BENCHMARK_SCENE.replace(objects=()), "objects"),
    (lambda: BENCHMARK_SCENE.replace(start_half_width_mm=90.0), "start_half_width_mm"),
])
def test_scene_validation(make, match) -> None:
    with pytest.raises(ValueError, match=match):
        make()


# ---------------------------------------------------------------------------------------------
# The map's sensor models
# ---------------------------------------------------------------------------------------------
def test_map_sensor_models_follow_the_offset_convention() -> None:
    """offsets = map origin − carriage; blur 0 gives the bare amplifier noise."""
    p = _carriages(300) * 0.95
    truth = BENCHMARK_SCENE.expected_reading(p)
    bare = make_map_sensor_model("analytic", BENCHMARK_SCENE, position_blur_mm=0.0)
    mean, std = bare.mean_std(-p)
    np.testing.assert_allclose(mean, truth, rtol=1e-12)
    np.testing.assert_allclose(std, BENCHMARK_SCENE.noise_std_V)
    blurred = make_map_sensor_model("analytic", BENCHMARK_SCENE, position_blur_mm=2.0)
    m2, s2 = blurred.mean_std(-p)
    np.testing.assert_allclose(m2, truth, rtol=1e-12)
    assert np.all(s2 >= BENCHMARK_SCENE.noise_std_V - 1e-12) and np.median(s2) > 2 * BENCHMARK_SCENE.noise_std_V
    # std ⊕ |∇Φ|·b with the gradient by finite differences
    eps = 1e-3
    gx = (BENCHMARK_SCENE.expected_reading(p + [eps, 0]) - BENCHMARK_SCENE.expected_reading(p - [eps, 0])) / (2 * eps)
    gy = (BENCHMARK_SCENE.expected_reading(p + [0, eps]) - BENCHMARK_SCENE.expected_reading(p - [0, eps])) / (2 * eps)
    # (the model's ±0.25 mm central difference differs from the tangent by the curvature: 0.5 %)
    np.testing.assert_allclose(s2, np.hypot(BENCHMARK_SCENE.noise_std_V, 2.0 * np.hypot(gx, gy)), rtol=5e-3)


def test_calibrated_map_model_approximates_the_map() -> None:
    cal = make_map_sensor_model("calibrated", BENCHMARK_SCENE, seed=5)
    assert cal is make_map_sensor_model("calibrated", BENCHMARK_SCENE, seed=5)  # cached
    assert cal.grid_shape == (41, 41)
    p = _carriages(4000, seed=9) * 0.99
    err = np.abs(cal.mean_std(-p)[0] - BENCHMARK_SCENE.expected_reading(p))
    assert np.median(err) < 0.5 * BENCHMARK_SCENE.noise_std_V
    assert np.percentile(err, 90) < 2.0 * BENCHMARK_SCENE.noise_std_V
    bare = make_map_sensor_model("calibrated", BENCHMARK_SCENE, seed=5, position_blur_mm=0.0)
    np.testing.assert_array_equal(bare.mean_table_V, cal.mean_table_V)
    assert np.all(cal.std_table_V >= bare.std_table_V) and np.any(cal.std_table_V > 2 * bare.std_table_V)
    with pytest.raises(ValueError, match="sensor_model"):
        make_map_sensor_model("magic", BENCHMARK_SCENE)
    with pytest.raises(ValueError, match="position_blur_mm"):
        make_map_sensor_model("analytic", BENCHMARK_SCENE, position_blur_mm=-1.0)


# ---------------------------------------------------------------------------------------------
# The environment
# ---------------------------------------------------------------------------------------------
def test_registered_and_idempotent() -> None:
    assert GLOBAL_ID in electroloc_gym.ENV_IDS
    electroloc_gym._register()
    assert GLOBAL_ID in gym.registry
    env = gym.make(f"electroloc_gym:{GLOBAL_ID}", n_particles=100)
    assert isinstance(env.unwrapped, GlobalLocalizationEnv)


@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_gymnasium_check_env(observation: str, sensor_model: str) -> None:
    env = gym.make(GLOBAL_ID, observation=observation, sensor_model=sensor_model, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        gym_check_env(env.unwrapped, skip_render_check=True)
    assert not [str(w.message) for w in record]


@pytest.mark.parametrize("observation", ["belief", "raw"])
@pytest.mark.parametrize("action_type", ["continuous", "discrete"])
def test_sb3_check_env(observation: str, action_type: str) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(GLOBAL_ID, observation=observation, action_type=action_type, n_particles=300)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        sb3_checker.check_env(env.unwrapped, warn=True)
    assert not [str(w.message) for w in record]


def _rollout(seed: int, n: int = 40, **kwargs):
    env = gym.make(GLOBAL_ID, **kwargs)
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), 0.0, False, False, info, env.unwrapped.belief.particles.copy())]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append((obs.copy(), r, term, trunc, info, env.unwrapped.belief.particles.copy()))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs.copy(), 0.0, False, False, info, env.unwrapped.belief.particles.copy()))
    return out


@pytest.mark.parametrize("kwargs", [dict(n_particles=500), dict(n_particles=500, sensor_model="analytic"),
                                    dict(n_particles=300, layout="random", observation="raw")])
def test_seeded_rollouts_are_identical(kwargs) -> None:
    a = _rollout(11, **kwargs)
    b = _rollout(11, **kwargs)
    assert len(a) == len(b)
    for (oa, ra, ta, tra, ia, pa), (ob, rb, tb, trb, ib, pb) in zip(a, b):
        np.testing.assert_array_equal(oa, ob)
        np.testing.assert_array_equal(pa, pb)
        assert (ra, ta, tra) == (rb, tb, trb)
        assert ia == ib
    c = _rollout(12, n=3, **kwargs)
    assert any(not np.array_equal(x[0], y[0]) for x, y in zip(a, c))


def test_random_layout_changes_with_the_seed_only() -> None:
    env = GlobalLocalizationEnv(layout="random", n_particles=100, sensor_model="analytic")
    env.reset(seed=1)
    s1 = env.scene
    env.reset(seed=1)
    assert env.scene == s1
    env.reset(seed=2)
    assert env.scene != s1 and len(env.scene.objects) == 6


def test_info_contract_truth_and_odometry() -> None:
    env = GlobalLocalizationEnv(n_particles=500, observation="raw")
    obs, info = env.reset(seed=3)
    assert set(info) == {"position_mm", "estimate_mm", "error_mm", "spread_mm", "reading_V", "n_observations",
                         "success", "condition"}
    assert info["n_observations"] == 1 and info["condition"] == BENCHMARK_SCENE.name
    np.testing.assert_array_equal(obs[:2], 0.0)  # raw: odometry, not the (unknown) true position
    assert np.all(np.abs(env.position_mm) <= BENCHMARK_SCENE.start_half_width_mm)
    obs, _, _, _, info = env.step(np.array([0.5, -1.0], np.float32))
    np.testing.assert_allclose(env.odometry_mm, [5.0, -10.0])
    np.testing.assert_allclose(obs[:2], np.array([5.0, -10.0]) / 80.0, rtol=1e-6)
    assert info["position_mm"] == tuple(map(float, env.position_mm))
    assert info["error_mm"] == pytest.approx(float(np.hypot(*(np.array(info["estimate_mm"]) - env.position_mm))))
    lo, hi = env.move_bounds_mm
    np.testing.assert_array_equal(lo, [-10.0, -10.0])
    np.testing.assert_array_equal(hi, [10.0, 10.0])


def test_motion_shifts_particles_and_keeps_carriage_in_the_box() -> None:
    env = GlobalLocalizationEnv(n_particles=400, sensor_model="analytic")
    env.reset(seed=4)
    before = env.belief.particles.copy()
    pos = env.position_mm
    core = env._sim  # the motion half of a step (no reading)
    core.task.move(core.state, slice(None), np.array([[10.0, -10.0]]))
    np.testing.assert_allclose(env.belief.particles, np.clip(before + [10.0, -10.0], -80, 80), atol=1e-5)
    np.testing.assert_allclose(env.position_mm, np.clip(pos + [10.0, -10.0], -80, 80))
    for _ in range(30):  # drive into the corner: truth and particles stay inside the box
        _, _, term, trunc, _ = env.step(np.array([1.0, 1.0], np.float32))
        if term or trunc:
            break
    assert np.all(env.position_mm <= 80.0) and np.all(env.belief.particles <= 80.0)


def test_predicted_reading_model_matches_the_map_and_the_v0_convention() -> None:
    env = GlobalLocalizationEnv(n_particles=200, sensor_model="analytic")
    env.reset(seed=5)
    parts = np.array([[0.0, 0.0], [75.0, -78.0], [-30.0, 44.0]], dtype=np.float32)
    moves = np.array([[0.0, 0.0], [10.0, -10.0], [-3.0, 7.0]])
    mean, std = env.predicted_reading_model(parts, moves)
    assert mean.shape == std.shape == (3, 3) and mean.dtype == np.float32
    after = env.predicted_particles_mm(parts, moves)
    np.testing.assert_allclose(after[1, 1], [80.0, -80.0])  # clipped at the walls like the carriage
    np.testing.assert_allclose(mean, BENCHMARK_SCENE.expected_reading(after.astype(np.float64)), rtol=1e-4, atol=1e-4)
    m1, _ = env.predicted_reading_model(parts, moves[2])
    np.testing.assert_allclose(m1, mean[2])
    # ElectroLoc-v0 offers the same call with offsets = particle − clip(carriage + move).
    v0 = gym.make("ElectroLoc-v0", n_particles=100, sensor_model="analytic").unwrapped
    v0.reset(seed=0)
    low, high = v0.allowed_box_mm
    mv, _ = v0.predicted_reading_model(parts / 2, moves)
    carriages = np.clip(v0.position_mm + moves, low, high)[:, None].astype(np.float32)
    ref = v0.sensor_model.mean_std(parts[None] / 2 - carriages)[0]
    np.testing.assert_array_equal(mv, ref)
    np.testing.assert_array_equal(v0.predicted_particles_mm(parts, moves), np.broadcast_to(parts, (3, 3, 2)))
    with pytest.raises(ValueError, match="moves_mm"):
        env.predicted_reading_model(parts, np.zeros(3))
    with pytest.raises(ValueError, match="particles_mm"):
        env.predicted_reading_model(np.zeros(4), moves)


def _square_spiral(n: int) -> list[np.ndarray]:
    """A fixed, informative path: an outward square spiral of 10 mm moves."""
    dirs = [np.array(d, np.float32) for d in ((1, 0), (0, 1), (-1, 0), (0, -1))]
    out, leg, k = [], 1, 0
    while len(out) < n:
        for _ in range(2):
            out += [dirs[k % 4]] * leg
            k += 1
        leg += 1
    return out[:n]


@pytest.mark.parametrize("sensor_model", ["analytic", "calibrated"])
def test_belief_converges_on_a_fixed_informative_path(sensor_model: str) -> None:
    """Along a fixed spiral the belief tightens on the true position in (nearly) every trial."""
    good = 0
    seeds = range(8)
    for seed in seeds:
        env = GlobalLocalizationEnv(sensor_model=sensor_model)
        _, info = env.reset(seed=seed)
        spreads = [info["spread_mm"]]
        for a in _square_spiral(34):
            _, _, term, trunc, info = env.step(a)
            spreads.append(info["spread_mm"])
            if term or trunc:
                break
        assert spreads[-1] < spreads[0]
        good += bool(info["success"] and info["error_mm"] < 5.0)
    assert good >= 7


def test_multimodal_belief_spread_and_no_crash() -> None:
    """Two far-apart clusters: the spread is the mixture's √trace Σ, not a cluster's, and steps work."""
    env = GlobalLocalizationEnv(n_particles=1000, sensor_model="calibrated")
    env.reset(seed=6)
    rng = np.random.default_rng(0)
    a = rng.normal([-50.0, -50.0], 1.0, size=(500, 2))
    b = rng.normal([50.0, 50.0], 1.0, size=(500, 2))
    env._sim.set_particles(0, np.concatenate([a, b]))
    # Equal clusters at ±50 mm per axis: var per axis = 50² + 1 → √trace Σ ≈ √(2·2501) ≈ 70.7 mm.
    assert env.belief.spread() == pytest.approx(np.sqrt(2 * 2501.0), rel=0.01)
    obs = env._sim.observation()[0]
    assert env.observation_space.contains(obs)
    hist = obs[12:76].reshape(8, 8)  # allocentric 20 mm cells over ±80 mm
    assert hist[1, 1] == pytest.approx(0.5, abs=0.02) and hist[6, 6] == pytest.approx(0.5, abs=0.02)
    assert not env._sim.info()["success"][0]
    for _ in range(5):
        obs, _, term, trunc, info = env.step(np.array([0.3, -0.2], np.float32))
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        assert np.all(np.isfinite(env.belief.particles)) and np.isfinite(info["spread_mm"])
        if term or trunc:
            break
    mean, std = env.predicted_reading_model(env.belief.particles, np.zeros((16, 2)))
    assert np.all(np.isfinite(mean)) and np.all(std > 0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(layout="moon"), "layout"),
    (dict(observation="pixels"), "observation"),
    (dict(sensor_model="magic"), "sensor_model"),
    (dict(n_particles=0), "n_particles"),
    (dict(max_observations=0), "max_observations"),
    (dict(success_spread_mm=-1.0), "success_spread_mm"),
    (dict(action_type="joystick"), "action_type"),
    (dict(position_blur_mm=-2.0), "position_blur_mm"),
])
def test_bad_kwargs_raise_clear_errors(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        GlobalLocalizationEnv(**kwargs)


def test_rgb_render_returns_frame() -> None:
    env = gym.make(GLOBAL_ID, n_particles=300, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0], np.float32))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8 and frame.std() > 10
    env.close()


def test_cli_eev_global_writes_a_png(tmp_path) -> None:
    import os
    import subprocess
    import sys

    out = tmp_path / "fig14.png"
    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    res = subprocess.run([sys.executable, "-m", "electroloc_gym.cli", "eev", "--env", "global", "--out", str(out)],
                         capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert out.stat().st_size > 10_000 and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_table2_statistics_with_the_paper_controllers() -> None:
    """Table 2 (§6.5) in small: rnd-wlk and min-var, 20 seeded trials each, calibrated map model."""
    agent_mod = pytest.importorskip("electroloc_gym.baselines.agent")
    env = gym.make(GLOBAL_ID)
    for name, min_success, max_median_err, max_median_steps in (("rnd-wlk", 17, 2.5, 20), ("min-var", 18, 3.0, 9)):
        ok, errors, steps = 0, [], []
        for k in range(20):
            agent = agent_mod.make_agent(name)
            obs, info = env.reset(seed=1000 + k)
            agent.seed(k)
            agent.reset(env)
            term = trunc = False
            while not (term or trunc):
                action, _ = agent.predict(obs)
                obs, _, term, trunc, info = env.step(action)
            ok += bool(term and info["success"])
            errors.append(info["error_mm"])
            steps.append(info["n_observations"])
        assert ok >= min_success, (name, ok)
        assert np.median(errors) <= max_median_err, (name, np.median(errors))
        assert np.median(steps) <= max_median_steps, (name, np.median(steps))


def test_bench_runs_table2_layout(tmp_path) -> None:
    """`electroloc bench --env global`: the runner's Table-2 path (serial backend, 2 trials of rnd-wlk)."""
    pytest.importorskip("electroloc_gym.baselines.agent")
    from electroloc_gym.bench.runner import GLOBAL_CONDITION, GLOBAL_ENV_ID, BenchConfig, run_benchmark, trial_seeds

    config = BenchConfig(agents=("rnd-wlk",), conditions=("ignored",), trials=2, env_id=GLOBAL_ENV_ID)
    assert config.conditions == (GLOBAL_CONDITION,)
    assert trial_seeds(0, GLOBAL_CONDITION, 1) != trial_seeds(0, "salt-delrin-38.1", 1)
    summary = run_benchmark(config, tmp_path, workers=1, backend="serial", progress=False, log=None)
    row = next(r for r in summary["rows"] if r["condition"] == GLOBAL_CONDITION and r["agent"] == "rnd-wlk")
    assert row["trials"] == 2
    table = (tmp_path / "table.md").read_text()
    assert "Table 2" in table and "48(2)" in table and "11.8/11" in table
    recs = [line for line in (tmp_path / "trials.jsonl").read_text().splitlines() if line]
    assert len(recs) == 2
    import json

    for rec in map(json.loads, recs):  # error is measured against the true final carriage position
        if rec["estimate"] is not None:
            est, tgt = np.asarray(rec["estimate"]), np.asarray(rec["target"])
            assert rec["error_mm"] == pytest.approx(float(np.hypot(*(est - tgt))))
