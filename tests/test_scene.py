"""The multi-object scene of the global self-localisation task and the map's sensor models (paper §6.5)."""

from __future__ import annotations

import numpy as np
import pytest

from electroloc_gym.sensor_models.map import make_map_sensor_model
from electroloc_gym.world import physics
from electroloc_gym.world.conditions import Amplifier, Condition, Target, Water
from electroloc_gym.world.scene import (
    BENCHMARK_LAYOUT_SEED,
    BENCHMARK_SCENE,
    STOCK_DIAMETERS_MM,
    Scene,
    SceneObject,
    cylinder_differential_perturbation,
    map_eev,
    random_cylinder_layout,
)
from electroloc_gym.world.sensor import expected_reading


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
    cond = Condition(
        name="s",
        target=Target(radius_mm=6.35, conductivity_uScm=1.4e10),
        water=Water(160.0),
        amplifier=Amplifier(gain=191.0, noise_rms_mV=0.25),
        start_half_width_mm=40.0,
        allowed_half_width_mm=50.0,
        target_xy_mm=(12.0, -7.0),
        signal_scale=0.9,
    )
    scene = Scene(
        name="one",
        objects=(SceneObject("sphere", (12.0, -7.0), 6.35, 1.4e10),),
        water=Water(160.0),
        amplifier=Amplifier(gain=191.0, noise_rms_mV=0.25),
        allowed_half_width_mm=50.0,
        start_half_width_mm=40.0,
        signal_scale=0.9,
    )
    p = _carriages(300) * 0.6
    np.testing.assert_allclose(
        scene.expected_reading(p), expected_reading(cond, np.array([12.0, -7.0]) - p), rtol=1e-12, atol=1e-15
    )


def test_cylinder_at_depth_zero_is_the_physics_2d_formula() -> None:
    """With the dipole point in the electrode plane the fast path equals physics.cylinder_perturbation."""
    rng = np.random.default_rng(1)
    off = rng.uniform(-60, 60, size=(400, 2))
    h = 25.0
    c = np.concatenate([off, np.zeros((400, 1))], axis=-1)
    e = physics.emitter_field(c, np.array([h, 0.0, 0.0]), np.array([-h, 0.0, 0.0]))
    s1, s2 = np.array([0.0, h, 0.0]), np.array([0.0, -h, 0.0])
    ref = physics.cylinder_perturbation(s1, c, 9.0, 0.7, e) - physics.cylinder_perturbation(s2, c, 9.0, 0.7, e)
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
            for b in objs[i + 1 :]:
                gap = np.hypot(a.xy_mm[0] - b.xy_mm[0], a.xy_mm[1] - b.xy_mm[1]) - a.radius_mm - b.radius_mm
                assert gap >= 5.0 - 0.2  # 5 mm apart, less the rounding of the centres to 0.1 mm
    assert random_cylinder_layout(0) != random_cylinder_layout(1)


def test_benchmark_layout_is_the_documented_generator_output() -> None:
    assert BENCHMARK_SCENE.objects == random_cylinder_layout(BENCHMARK_LAYOUT_SEED)
    assert sorted(o.diameter_mm for o in BENCHMARK_SCENE.objects) == sorted(STOCK_DIAMETERS_MM)
    assert BENCHMARK_SCENE.water.conductivity_uScm == 160.0 and BENCHMARK_SCENE.amplifier.gain == 191.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n_objects=0), "n_objects"),
        (dict(half_width_mm=-1.0), "half_width_mm"),
        (dict(materials=("gold",)), "materials"),
        (dict(n_objects=40, min_gap_mm=10.0, max_tries=50), "could not place"),
    ],
)
def test_layout_generator_bad_arguments(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        random_cylinder_layout(0, **kwargs)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: SceneObject("cube", (0.0, 0.0), 5.0, 1.0), "shape"),
        (lambda: SceneObject("sphere", (0.0, 0.0), -5.0, 1.0), "radius_mm"),
        (lambda: SceneObject("sphere", (0.0, np.nan), 5.0, 1.0), "xy_mm"),
        (lambda: SceneObject.of_material("cylinder", (0.0, 0.0), 5.0, "wood"), "material"),
        (lambda: BENCHMARK_SCENE.replace(objects=()), "objects"),
        (lambda: BENCHMARK_SCENE.replace(start_half_width_mm=90.0), "start_half_width_mm"),
    ],
)
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
