"""A pre-mapped tank of several objects: the world of the global self-localisation task (paper §6.5).

The paper's §6.5: "six cylinders of different diameters and conductivities were randomly dispersed
with x and y coordinates within ±80 mm"; the robot localises itself relative to the map origin using
the measured EEV of that layout (Fig. 14) as prior knowledge.

Physics (paper Eq. 4; docs/design.md, "Physics"). Every object becomes an induced dipole in the
emitters' field evaluated at one point ``c`` of the object, and the perturbations of all objects
**superpose** (no mutual polarisation, no tank walls — the paper's uniform-field assumption):

* sphere of radius a (paper Eq. 4): ``δV(s) = χ a³ E_f(c)·(s − c)/|s − c|³``, ``χ = (σ_t − σ_w)/(σ_t + 2σ_w)``,
  centre ``c`` at depth ``a + E + O`` below the electrode plane (as the single-target presets).
* vertical cylinder of radius a (the 2-D analogue of Eq. 4): ``δV(s) = χ₂ a² E_f(c)·(s − c)/|s − c|²``,
  ``χ₂ = (σ_t − σ_w)/(σ_t + σ_w)``, with ``c`` the point of the cylinder's axis closest to the sensor.
  Modelling choice: the cylinders stand on the tank floor and end, like the spheres, 2 mm (O) below
  the electrodes (radius E) with a rounded (hemispherical) top, so the top of the axis — the point
  ``c`` — lies at the depth of an equal sphere's centre, ``a + E + O`` (the carriage can pass over
  them). Why not a flat top at ``E + O = 3 mm``: the point-dipole formula is only valid at distances
  ≳ a from the axis; with ``c`` 3 mm under the electrodes the map becomes nearly singular (99th
  percentile of |∇Φ| ≈ 5.5 V/mm ≈ 115 σ per mm on the benchmark map, against 0.43 V/mm with the
  rounded tops), far steeper than the paper's measured map (Fig. 14's 1 V contours are millimetres
  apart), and a 2500-particle filter then converges on wrong places in about half of the trials.
  An infinite cylinder through the electrode plane would be singular wherever an electrode crosses
  an axis. With the dipole depth → 0 the formula reduces exactly to
  :func:`electroloc_gym.world.physics.cylinder_perturbation` (tested).

The reading is ``Φ = clip(s·G·Σ_k (δV_k(S1) − δV_k(S2)) + ε, ±V_sat)``, ε ~ N(0, (G·σ_s)²), exactly as
for one sphere (:mod:`electroloc_gym.world.sensor`), with one ``signal_scale`` for the whole scene.

The agent's sensor models of the map (analytic and calibrated, with a position blur) are in
:mod:`electroloc_gym.sensor_models.map`; the map's EEV plot in :mod:`electroloc_gym.views.eev_maps`, its episode
frames in :mod:`electroloc_gym.views.render`.

The benchmark layout (:data:`BENCHMARK_SCENE`, ``layout="benchmark"``) is fixed in code: six cylinders
drawn once by :func:`random_cylinder_layout` with seed :data:`BENCHMARK_LAYOUT_SEED` (a test checks the
generator still reproduces it). Condition: fresh water (160 µS/cm) with the fresh-water 12.7 mm
amplifier (G = 191, σ_s = 0.25 mV RMS, Table 3) and signal scale 1 (the paper's equations): the
paper gives no measured detection distance for cylinders, so there is nothing to fit a scale to.
The noise-free map spans −4.0 V to +3.2 V (71 % of the box above the 2σ level), below the ±10 V
card limit, so unlike Fig. 14 it never saturates.
The carriage's allowed box is ±80 mm (the region the cylinders were dispersed in), the start box
±70 mm (the 10 mm margin of the 12.7 mm presets).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.utils.checks import check_float
from electroloc_gym.world import physics
from electroloc_gym.world.conditions import (
    Amplifier,
    Condition,
    FRESH_WATER_uScm,
    Geometry,
    Target,
    Water,
)
from electroloc_gym.world.sensor import saturated_reading

__all__ = [
    "SHAPES",
    "SCENE_MATERIAL_CONDUCTIVITY_uScm",
    "STOCK_DIAMETERS_MM",
    "SceneObject",
    "Scene",
    "cylinder_differential_perturbation",
    "random_cylinder_layout",
    "BENCHMARK_LAYOUT_SEED",
    "BENCHMARK_SCENE",
    "map_eev",
]

SHAPES = ("sphere", "cylinder")

#: Conductivities (µS/cm) of the materials the layout generator draws from. Metals and plastics are
#: perfect conductors / insulators for the contrast (χ₂ = ±1 to many digits); "agar" is a weakly
#: conducting gel (1000 µS/cm, χ₂ = 0.72 in fresh water) so that contrasts really differ.
SCENE_MATERIAL_CONDUCTIVITY_uScm: dict[str, float] = {
    "steel": 1.4e10,
    "brass": 1.5e11,
    "aluminium": 3.5e11,
    "delrin": 1e-9,
    "pvc": 1e-10,
    "agar": 1000.0,
}

#: Stock rod diameters (mm): 1/4" to 1 1/2" in 1/4" steps.
STOCK_DIAMETERS_MM: tuple[float, ...] = (6.35, 12.7, 19.05, 25.4, 31.75, 38.1)

_DEFAULT_GEOMETRY = Geometry()


@dataclass(frozen=True)
class SceneObject:
    """One object of the map.

    Attributes:
        shape: "sphere" or "cylinder" (vertical, standing on the floor).
        xy_mm: horizontal centre (sphere) / axis position (cylinder) in the map frame, mm.
        radius_mm: radius, mm (> 0).
        conductivity_uScm: conductivity σ_t, µS/cm (≥ 0).
        material: a label.
    """

    shape: str
    xy_mm: tuple[float, float]
    radius_mm: float
    conductivity_uScm: float
    material: str = "custom"

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"shape must be one of {list(SHAPES)}, got {self.shape!r}")
        if len(self.xy_mm) != 2:
            raise ValueError(f"xy_mm must be (x, y) in mm, got {self.xy_mm!r}")
        object.__setattr__(self, "xy_mm", (check_float("xy_mm", self.xy_mm[0]), check_float("xy_mm", self.xy_mm[1])))
        check_float("radius_mm", self.radius_mm, 0.0)
        check_float("conductivity_uScm", self.conductivity_uScm, 0.0, inclusive=True)

    @classmethod
    def of_material(cls, shape: str, xy_mm: tuple[float, float], diameter_mm: float, material: str) -> SceneObject:
        """An object of a named material (:data:`SCENE_MATERIAL_CONDUCTIVITY_uScm`)."""
        key = material.lower()
        if key not in SCENE_MATERIAL_CONDUCTIVITY_uScm:
            raise ValueError(f"material must be one of {sorted(SCENE_MATERIAL_CONDUCTIVITY_uScm)}, got {material!r}")
        return cls(
            shape,
            cast("tuple[float, float]", tuple(xy_mm)),  # the pair as a tuple (SceneObject checks its length)
            check_float("diameter_mm", diameter_mm, 0.0) / 2.0,
            SCENE_MATERIAL_CONDUCTIVITY_uScm[key],
            key,
        )

    @property
    def diameter_mm(self) -> float:
        """Diameter, mm."""
        return 2.0 * self.radius_mm

    def contrast(self, water_conductivity_uScm: float) -> float:
        """χ (sphere, Eq. 4) or χ₂ (cylinder, 2-D analogue) in water of the given conductivity."""
        f = physics.contrast_factor_sphere if self.shape == "sphere" else physics.contrast_factor_cylinder
        return float(f(self.conductivity_uScm, water_conductivity_uScm))


#: δV(S1) − δV(S2) of a vertical cylinder (the 2-D analogue of Eq. 4); the column-wise fast path lives in
#: physics, shared with the sphere's; ``depth_mm`` is the top of the axis (``a + E + O`` in a :class:`Scene`).
cylinder_differential_perturbation = physics.differential_line_perturbation


@dataclass(frozen=True)
class Scene:
    """A map: objects in fresh or salt water, the amplifier and the carriage's workspace.

    Attributes:
        name: a label.
        objects: the objects (any mix of spheres and cylinders, conductors and insulators).
        water: the water.
        amplifier: gain G and input noise σ_s (paper Table 3).
        allowed_half_width_mm: the carriage (and the belief over it) stays within ±this box, mm.
        start_half_width_mm: the carriage starts uniformly within ±this box, mm.
        signal_scale: dimensionless factor on the noise-free amplified signal (:mod:`electroloc_gym.world.sensor`).
        geometry: carriage geometry and emitter drive; ``clearance_mm`` is the gap between the
            electrodes and the top of every object.
    """

    name: str
    objects: tuple[SceneObject, ...]
    water: Water
    amplifier: Amplifier
    allowed_half_width_mm: float = 80.0
    start_half_width_mm: float = 70.0
    signal_scale: float = 1.0
    geometry: Geometry = field(default_factory=Geometry)

    def __post_init__(self) -> None:
        object.__setattr__(self, "objects", tuple(self.objects))
        if not self.objects:
            raise ValueError("objects must hold at least one SceneObject")
        for o in self.objects:
            if not isinstance(o, SceneObject):
                raise TypeError(f"objects must be SceneObject instances, got {type(o).__name__}")
        for fname, typ in (("water", Water), ("amplifier", Amplifier), ("geometry", Geometry)):
            if not isinstance(getattr(self, fname), typ):
                raise TypeError(f"{fname} must be a {typ.__name__}, got {type(getattr(self, fname)).__name__}")
        check_float("allowed_half_width_mm", self.allowed_half_width_mm, 0.0)
        check_float("start_half_width_mm", self.start_half_width_mm, 0.0)
        if self.start_half_width_mm > self.allowed_half_width_mm:
            raise ValueError(
                f"start_half_width_mm must be ≤ allowed_half_width_mm ({self.allowed_half_width_mm}),"
                f" got {self.start_half_width_mm}"
            )
        check_float("signal_scale", self.signal_scale, 0.0)

    # ---- derived values ---------------------------------------------------------------------
    @property
    def noise_std_V(self) -> float:
        """Standard deviation of the amplified reading, V (G·σ_s)."""
        return self.amplifier.noise_std_V

    @property
    def saturation_V(self) -> float:
        """Clip level of the reading, V."""
        return self.amplifier.saturation_V

    def object_depth_mm(self, obj: SceneObject) -> float:
        """Depth of an object's dipole point below the electrode plane, mm: a + E + O (§6.7).

        The sphere's centre, or the top of a cylinder's axis (rounded top, module docstring).
        """
        return obj.radius_mm + self.geometry.electrode_radius_mm + self.geometry.clearance_mm

    def replace(self, **changes: Any) -> Scene:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def as_condition(self) -> Condition:
        """This scene's amplifier, water, geometry, boxes and signal scale as a :class:`Condition`.

        The sensor models and the observation's condition descriptor take a Condition. Its ``target``
        is a nominal stand-in (a sphere of the objects' mean radius and of the first object's
        conductivity); it is never used to compute a reading of the scene.
        """
        r = float(np.mean([o.radius_mm for o in self.objects]))
        return Condition(
            name=self.name,
            target=Target(
                radius_mm=r, conductivity_uScm=self.objects[0].conductivity_uScm, material=self.objects[0].material
            ),
            water=self.water,
            amplifier=self.amplifier,
            start_half_width_mm=self.start_half_width_mm,
            allowed_half_width_mm=self.allowed_half_width_mm,
            signal_scale=self.signal_scale,
            geometry=self.geometry,
        )

    # ---- the reading ------------------------------------------------------------------------
    def object_perturbations(self, carriage_mm: ArrayLike) -> NDArray:
        """δV_k(S1) − δV_k(S2) (V, unamplified) of each object alone, shape (..., K).

        ``carriage_mm`` (..., 2) is the carriage centre in the map frame; float32 stays float32.
        """
        p = np.asarray(carriage_mm)
        if p.dtype not in (np.float32, np.float64):
            p = p.astype(np.float64)
        return np.stack([self._one(o, p) for o in self.objects], axis=-1)

    def perturbation(self, carriage_mm: ArrayLike) -> NDArray:
        """Σ_k (δV_k(S1) − δV_k(S2)) (V, unamplified): the superposition of the objects' dipoles, shape (...)."""
        p = np.asarray(carriage_mm)
        if p.dtype not in (np.float32, np.float64):
            p = p.astype(np.float64)
        total = self._one(self.objects[0], p)
        for o in self.objects[1:]:
            total += self._one(o, p)
        return total

    def _one(self, obj: SceneObject, p: NDArray) -> NDArray:
        g = self.geometry
        off = np.asarray(obj.xy_mm, dtype=p.dtype) - p  # object − carriage (the sensor's convention)
        chi = obj.contrast(self.water.conductivity_uScm)
        if obj.shape == "sphere":
            return physics.differential_perturbation(
                off,
                obj.radius_mm,
                chi,
                self.object_depth_mm(obj),
                spacing_mm=g.spacing_mm,
                emitter_voltage_V=g.emitter_voltage_V,
                electrode_radius_mm=g.electrode_radius_mm,
            )
        return cylinder_differential_perturbation(
            off,
            obj.radius_mm,
            chi,
            self.object_depth_mm(obj),
            spacing_mm=g.spacing_mm,
            emitter_voltage_V=g.emitter_voltage_V,
            electrode_radius_mm=g.electrode_radius_mm,
        )

    def expected_reading(self, carriage_mm: ArrayLike, *, saturate: bool = True) -> NDArray:
        """Noise-free reading Φ (V) with the carriage at ``carriage_mm`` (..., 2) in the map frame."""
        delta = self.perturbation(carriage_mm)
        phi = np.asarray(delta * delta.dtype.type(self.signal_scale * self.amplifier.gain))
        if saturate:
            sat = delta.dtype.type(self.saturation_V)
            phi = np.clip(phi, -sat, sat, out=phi if phi.ndim else None)
        return phi

    def noisy_reading(self, carriage_mm: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
        """A noisy, saturated reading Φ (V) at ``carriage_mm`` (..., 2); one normal draw per reading.

        Same draw as :func:`electroloc_gym.world.sensor.noisy_reading` (``rng.normal`` of the output shape).
        """
        mean = self.expected_reading(np.asarray(carriage_mm, dtype=np.float64), saturate=False)
        return saturated_reading(mean, rng.normal(0.0, self.noise_std_V, size=mean.shape), self.saturation_V)

    # Sensor-model convention: offsets = map origin − carriage = −carriage.
    def expected_reading_at_offsets(self, offsets_mm: ArrayLike) -> NDArray:
        """:meth:`expected_reading` for ``offsets_mm`` = −carriage (the sensor models' convention)."""
        return self.expected_reading(-np.asarray(offsets_mm))

    def noisy_reading_at_offsets(self, offsets_mm: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
        """:meth:`noisy_reading` for ``offsets_mm`` = −carriage (the sensor models' convention)."""
        return self.noisy_reading(-np.asarray(offsets_mm, dtype=np.float64), rng)


# ------------------------------------------------------------------------------------------
# Layouts
# ------------------------------------------------------------------------------------------
def random_cylinder_layout(
    rng: np.random.Generator | int,
    n_objects: int = 6,
    half_width_mm: float = 80.0,
    diameters_mm: Sequence[float] = STOCK_DIAMETERS_MM,
    materials: Sequence[str] = tuple(SCENE_MATERIAL_CONDUCTIVITY_uScm),
    min_gap_mm: float = 5.0,
    max_tries: int = 10_000,
) -> tuple[SceneObject, ...]:
    """Six (``n_objects``) vertical cylinders of different diameters and materials within ±80 mm (§6.5).

    Diameters and materials are drawn without replacement (so all differ when there are enough of
    them, with replacement otherwise); axes are uniform in ±``half_width_mm`` and rejected until the
    cylinders are at least ``min_gap_mm`` apart surface to surface.

    Args:
        rng: a Generator or an integer seed.
        n_objects: number of cylinders (≥ 1).
        half_width_mm: axes lie within ±this, mm (> 0).
        diameters_mm: diameters to draw from, mm.
        materials: material names (:data:`SCENE_MATERIAL_CONDUCTIVITY_uScm`) to draw from.
        min_gap_mm: least surface-to-surface distance, mm (≥ 0).
        max_tries: give up after this many rejected placements.

    Raises:
        ValueError: bad arguments, or the cylinders do not fit.
    """
    if isinstance(n_objects, bool) or not isinstance(n_objects, (int, np.integer)) or n_objects < 1:
        raise ValueError(f"n_objects must be an integer ≥ 1, got {n_objects!r}")
    check_float("half_width_mm", half_width_mm, 0.0)
    check_float("min_gap_mm", min_gap_mm, 0.0, inclusive=True)
    if not diameters_mm or not materials:
        raise ValueError("diameters_mm and materials must not be empty")
    for m in materials:
        if m not in SCENE_MATERIAL_CONDUCTIVITY_uScm:
            raise ValueError(f"materials must be among {sorted(SCENE_MATERIAL_CONDUCTIVITY_uScm)}, got {m!r}")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    diams = gen.choice(np.asarray(diameters_mm, float), size=n_objects, replace=n_objects > len(diameters_mm))
    mats = gen.choice(np.asarray(materials), size=n_objects, replace=n_objects > len(materials))
    placed: list[tuple[float, float, float]] = []
    for d in diams:
        for _ in range(max_tries):
            xy = gen.uniform(-half_width_mm, half_width_mm, size=2)
            if all(math.hypot(xy[0] - x, xy[1] - y) >= (d / 2 + r + min_gap_mm) for x, y, r in placed):
                placed.append((float(xy[0]), float(xy[1]), float(d) / 2))
                break
        else:
            raise ValueError(
                f"could not place {n_objects} cylinders within ±{half_width_mm} mm with a gap of {min_gap_mm} mm"
            )
    return tuple(
        SceneObject.of_material("cylinder", (round(x, 1), round(y, 1)), 2 * r, str(m))
        for (x, y, r), m in zip(placed, mats)
    )


#: Seed of the benchmark layout (the paper's year); :data:`BENCHMARK_SCENE` is its output, frozen here.
BENCHMARK_LAYOUT_SEED = 2008

#: The fixed six-cylinder layout of ``ElectroLocGlobal-v0`` (map frame, mm; diameter mm; material).
#: Produced by ``random_cylinder_layout(2008)`` and written out so the benchmark cannot drift.
_BENCHMARK_OBJECTS: tuple[tuple[tuple[float, float], float, str], ...] = (
    ((61.3, -73.1), 12.7, "delrin"),
    ((-31.3, 59.3), 19.05, "pvc"),
    ((41.4, 67.5), 25.4, "aluminium"),
    ((6.2, -14.4), 31.75, "steel"),
    ((-71.6, 52.4), 6.35, "brass"),
    ((-7.3, -72.1), 38.1, "agar"),
)


def _fresh_scene(name: str, objects: tuple[SceneObject, ...]) -> Scene:
    # Fresh water and the fresh-water 12.7 mm amplifier (paper Table 3): G = 191, σ_s = 0.25 mV.
    return Scene(
        name=name,
        objects=objects,
        water=Water(FRESH_WATER_uScm),
        amplifier=Amplifier(gain=191.0, noise_rms_mV=0.25),
        allowed_half_width_mm=80.0,
        start_half_width_mm=70.0,
        signal_scale=1.0,
        geometry=_DEFAULT_GEOMETRY,
    )


def _benchmark() -> Scene:
    objs = tuple(SceneObject.of_material("cylinder", xy, d, m) for xy, d, m in _BENCHMARK_OBJECTS)
    return _fresh_scene("six-cylinders", objs)


BENCHMARK_SCENE: Scene = _benchmark()


# ------------------------------------------------------------------------------------------
# The map's EEV (Fig. 14)
# ------------------------------------------------------------------------------------------
def map_eev(
    scene: Scene, step_mm: float = 1.0, half_span_mm: float | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The map's EEV (Fig. 14): (grid_mm, Φ[ix, iy]) noise-free reading with the carriage at (grid[ix], grid[iy])."""
    h = scene.allowed_half_width_mm if half_span_mm is None else float(half_span_mm)
    grid = np.arange(-h, h + 1e-9, check_float("step_mm", step_mm, 0.0))
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    return grid, scene.expected_reading(np.stack([gx, gy], axis=-1))
