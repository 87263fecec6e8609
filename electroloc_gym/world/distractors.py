"""Distractors: objects in the tank that are not the target, and what they add to the reading.

Physics level (no Gymnasium, no simulation core). A distractor is a :class:`~electroloc_gym.world.scene.SceneObject`
— a sphere, or a vertical cylinder standing on the floor with a rounded top — of any size and material.
Like every object of :mod:`electroloc_gym.world.scene` its top lies the clearance O (2 mm) below the electrodes,
so its dipole point is ``a + E + O`` deep, the depth of the target's centre when a = A. Each object
becomes an induced dipole in the emitters' field, and the perturbations **superpose** with the
target's (paper Eq. 4; the uniform-field assumption: no mutual polarisation, no walls):

    Φ = clip(s·G·(δV_target(S1) − δV_target(S2) + Σ_k (δV_k(S1) − δV_k(S2))) + ε, ±V_sat)

with the condition's signal scale s, gain G, noise and clip. The target's term is
:func:`electroloc_gym.world.sensor.expected_reading`'s; the distractors' terms are
:meth:`electroloc_gym.world.scene.Scene.perturbation` of a scene of the distractors in the condition's water,
amplifier and geometry — the same physics module the maps use, nothing re-derived here. An empty set
adds nothing: :func:`superposed_reading_V` then returns the target's reading itself, bit for bit.

An agent's sensor model knows only the target: the distractors are the model mismatch a real tank
imposes (Miller et al., IEEE T-RO 32(1), 2016, localise targets among such distractors).

**Placement.** A set is drawn per episode (:class:`DistractorDraw`, from the episode's generator) with
every centre in the condition's allowed box (the part of the tank the carriage can pass over, so every
distractor is within the sensor's reach) and every footprint — the disc of the object's radius around
its centre; all tops are at the same depth, so disjoint footprints are disjoint bodies — at least
``gap_mm`` from the target's and from the other distractors'. Explicit layouts
(:class:`DistractorSet`) are validated by the same rule (:meth:`DistractorSet.validate`).

**A draw that always finishes.** Centres are drawn by rejection, object after object; a set placed
early can leave no room for a later object, so when ``max_attempts`` centres in a row fail, the draw
falls back to a construction that cannot fail where it is admitted: *columns*
(:func:`~electroloc_gym.world.distractor_layout.column_layout`).
With S = 2·r_max + gap (two of the largest objects side by side) and T = r_target + r_max + gap,
columns at least S apart never conflict, and in one column the most centres spaced ≥ S in [−h, h] that
avoid the interval the target's disc of radius T cuts out of it is what the greedy bottom-up sweep
places (the 1-D interval argument). Over a family of column positions (and the same with rows) the
best one is taken; the episode's objects take a random subset of its centres. Whether every target
position the env can draw admits ``count`` objects is checked once at construction
(:meth:`DistractorDraw.check_fits`): at the fixed target itself, or — for a random target in a box —
at a grid of targets with the disc grown by the grid's half-diagonal m, since a layout valid for the
grid point's disc of radius T + m is valid for every target within m of it, and the count is monotone
in the blocked set. No packing library solves this per-episode, per-target bound, so it is written
here. A draw that succeeds by rejection is untouched: the fallback is reached only where the draw
used to fail.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.distractor_layout import EDGE_MM, column_layout, least_capacity
from electroloc_gym.world.scene import SHAPES, STOCK_DIAMETERS_MM, Scene, SCENE_MATERIAL_CONDUCTIVITY_uScm, SceneObject
from electroloc_gym.world.sensor import expected_reading

__all__ = [
    "MAX_DISTRACTORS",
    "DistractorDraw",
    "DistractorSet",
    "superposed_reading_V",
    "resolve_distractors",
]

#: Most distractors a draw may place (the 100 mm box holds a handful of stock-size objects).
MAX_DISTRACTORS = 8


def _tuple_of(name: str, values: Any, allowed: Sequence[str]) -> tuple[str, ...]:
    if isinstance(values, str) or not isinstance(values, Sequence) or len(values) == 0:
        raise ValueError(f"{name} must be a non-empty sequence drawn from {list(allowed)}, got {values!r}")
    bad = [v for v in values if v not in allowed]
    if bad:
        raise ValueError(f"{name} must be drawn from {list(allowed)}, got {bad!r}")
    return tuple(values)


def _checked_count(v: object, count: object) -> int:
    """One distractor count ``v`` (of the ``count`` given) as an int, or a ValueError naming ``count``."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= MAX_DISTRACTORS:
        raise ValueError(
            f"count (distractors) must be an integer in [0, {MAX_DISTRACTORS}] or a non-empty "
            f"tuple of such integers, got {count!r}"
        )
    return int(v)


@dataclass(frozen=True)
class DistractorDraw:
    """How a distractor set is drawn per episode (all draws from the episode's generator).

    Attributes:
        count: D, the number of distractors, 0–:data:`MAX_DISTRACTORS`; or a tuple of such counts, one of
            which is drawn uniformly per episode (a mix of tanks, e.g. ``(0, 1, 2)`` for training).
        shapes: shapes drawn uniformly per object (``"sphere"``, ``"cylinder"``).
        diameters_mm: diameters drawn uniformly per object, mm (> 0; default the stock sizes 6.35–38.1 mm).
        materials: materials drawn uniformly per object
        (:data:`~electroloc_gym.world.scene.SCENE_MATERIAL_CONDUCTIVITY_uScm`:
            conductors, insulators and the weakly conducting agar).
        gap_mm: least horizontal clearance between footprints (target and distractors), mm (≥ 0).
        max_attempts: rejection-sampling attempts per object before the draw falls back to the column
            construction (1–100000; module docstring).
    """

    count: int | tuple[int, ...]
    shapes: tuple[str, ...] = SHAPES
    diameters_mm: tuple[float, ...] = STOCK_DIAMETERS_MM
    materials: tuple[str, ...] = ("steel", "brass", "aluminium", "delrin", "pvc", "agar")
    gap_mm: float = 5.0
    max_attempts: int = 1000

    def __post_init__(self) -> None:
        c = self.count
        if isinstance(c, (tuple, list)) and len(c) > 0:
            counts = [_checked_count(v, c) for v in c]  # every entry checked before any is stored
            object.__setattr__(self, "count", tuple(counts))
        else:
            object.__setattr__(self, "count", _checked_count(c, c))
        object.__setattr__(self, "shapes", _tuple_of("shapes", self.shapes, SHAPES))
        object.__setattr__(
            self, "materials", _tuple_of("materials", self.materials, tuple(SCENE_MATERIAL_CONDUCTIVITY_uScm))
        )
        d = self.diameters_mm
        if (
            isinstance(d, str)
            or not isinstance(d, Sequence)
            or len(d) == 0
            or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0 for v in d
            )
        ):
            raise ValueError(f"diameters_mm must be a non-empty sequence of diameters > 0 mm, got {d!r}")
        object.__setattr__(self, "diameters_mm", tuple(float(v) for v in d))
        g = self.gap_mm
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g) or g < 0:
            raise ValueError(f"gap_mm must be a number of mm ≥ 0, got {g!r}")
        object.__setattr__(self, "gap_mm", float(g))
        a = self.max_attempts
        if isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 1 <= a <= 100_000:
            raise ValueError(f"max_attempts must be an integer in [1, 100000], got {a!r}")

    @property
    def max_count(self) -> int:
        """The most distractors an episode can have."""
        return max(self.count) if isinstance(self.count, tuple) else self.count

    def draw(self, condition: Condition, target_xy_mm: ArrayLike, rng: np.random.Generator) -> DistractorSet:
        """One episode's set in ``condition``'s tank, none overlapping the target at ``target_xy_mm``.

        With a tuple of counts, first the episode's count (one uniform index). Per object, in order: shape,
        diameter, material (one uniform index each), then centres uniform in the allowed box until one clears
        the target and the objects placed so far by ``gap_mm``.

        Where ``max_attempts`` centres in a row fail, the column construction places the set instead
        (module docstring); it always succeeds where :meth:`check_fits` admits the draw.

        Raises:
            ValueError: not even the column construction fits ``count`` objects beside this target.
        """
        h = condition.allowed_half_width_mm
        placed: list[SceneObject] = []
        discs = [(np.asarray(target_xy_mm, dtype=np.float64), condition.target.radius_mm)]
        count = self.count[int(rng.integers(len(self.count)))] if isinstance(self.count, tuple) else self.count
        for _ in range(count):
            shape = self.shapes[int(rng.integers(len(self.shapes)))]
            diameter = self.diameters_mm[int(rng.integers(len(self.diameters_mm)))]
            material = self.materials[int(rng.integers(len(self.materials)))]
            radius = diameter / 2.0
            for _ in range(self.max_attempts):
                xy = rng.uniform(-h, h, size=2)
                if all(np.hypot(*(xy - c)) >= radius + r + self.gap_mm for c, r in discs):
                    break
            else:
                return self._fallback(condition, target_xy_mm, rng, count, placed, (shape, diameter, material))
            placed.append(SceneObject.of_material(shape, (float(xy[0]), float(xy[1])), diameter, material))
            discs.append((xy, radius))
        return DistractorSet(tuple(placed))

    def _clearances_mm(self, condition: Condition) -> tuple[float, float]:
        """(S, T): the centre distance two of the largest objects need, and one of them and the target, mm
        (each a hair more, :data:`~electroloc_gym.world.distractor_layout.EDGE_MM`, so that rounding in the sums
        never brings two centres closer).
        """
        r_max = max(self.diameters_mm) / 2.0
        return 2.0 * r_max + self.gap_mm + EDGE_MM, condition.target.radius_mm + r_max + self.gap_mm + EDGE_MM

    def _fallback(
        self,
        condition: Condition,
        target_xy_mm: ArrayLike,
        rng: np.random.Generator,
        count: int,
        placed: list[SceneObject],
        current: tuple[str, float, str],
    ) -> DistractorSet:
        """The column construction, reached when rejection fails: the objects keep their drawn shape,
        diameter and material (the rest are drawn now, as in the loop), and take ``count`` of the best
        column layout's centres, a random subset.
        """
        kinds = [(o.shape, o.diameter_mm, o.material) for o in placed] + [current]
        while len(kinds) < count:
            kinds.append(
                (
                    self.shapes[int(rng.integers(len(self.shapes)))],
                    self.diameters_mm[int(rng.integers(len(self.diameters_mm)))],
                    self.materials[int(rng.integers(len(self.materials)))],
                )
            )
        t = np.asarray(target_xy_mm, dtype=np.float64).reshape(2)
        spacing, clearance = self._clearances_mm(condition)
        nodes = column_layout(condition.allowed_half_width_mm, spacing, clearance, float(t[0]), float(t[1]))
        if len(nodes) < count:
            raise ValueError(
                f"could not place {count} distractors of up to {max(self.diameters_mm):g} mm clear of "
                f"the target at ({t[0]:.4g}, {t[1]:.4g}) mm by gap_mm={self.gap_mm:g} in the "
                f"±{condition.allowed_half_width_mm:g} mm box: at most {len(nodes)} fit there"
            )
        pick = rng.choice(len(nodes), size=count, replace=False)
        return DistractorSet(
            tuple(
                SceneObject.of_material(shape, nodes[int(j)], diameter, material)
                for (shape, diameter, material), j in zip(kinds, pick)
            )
        )

    def check_fits(self, condition: Condition, target_half_width_mm: float | None = None) -> None:
        """Refuse a draw that could fail: ``max_count`` objects must fit beside every target the env can
        draw — the condition's fixed target (``target_half_width_mm=None``) or any target uniform in
        ±``target_half_width_mm`` (module docstring: a grid with a grown disc).

        Raises:
            ValueError: one line naming the count, the sizes, the condition and the most that always fit.
        """
        if self.max_count == 0:
            return
        spacing, clearance = self._clearances_mm(condition)
        h = condition.allowed_half_width_mm
        if target_half_width_mm is None:
            fits = len(column_layout(h, spacing, clearance, *condition.target_xy_mm))
            where = f"the target at {condition.target_xy_mm} mm"
        else:
            fits = least_capacity(h, spacing, clearance, float(target_half_width_mm))
            where = f"a random target in ±{float(target_half_width_mm):g} mm"
        if fits < self.max_count:
            raise ValueError(
                f"count (distractors) {self.max_count} of up to {max(self.diameters_mm):g} mm with "
                f"gap_mm={self.gap_mm:g} cannot always be placed in condition {condition.name!r} "
                f"beside {where}: at most {fits} always fit; ask for fewer or smaller distractors"
            )


@dataclass(frozen=True)
class DistractorSet:
    """The distractors of one episode (or an explicit layout): objects of :mod:`electroloc_gym.world.scene`.

    Attributes:
        objects: the distractors (any number, possibly none); centres in the tank frame, mm.
    """

    objects: tuple[SceneObject, ...] = ()

    def __post_init__(self) -> None:
        if isinstance(self.objects, SceneObject) or not isinstance(self.objects, Sequence):
            raise ValueError(f"objects must be a sequence of SceneObject, got {type(self.objects).__name__}")
        object.__setattr__(self, "objects", tuple(self.objects))
        for o in self.objects:
            if not isinstance(o, SceneObject):
                raise ValueError(f"objects must be SceneObject instances, got {type(o).__name__}")

    def __len__(self) -> int:
        return len(self.objects)

    def validate(self, condition: Condition, target_xy_mm: ArrayLike, gap_mm: float = 0.0) -> DistractorSet:
        """Check the layout against a tank and target: every centre in the allowed box, every footprint
        at least ``gap_mm`` from the target's and the others'. Returns self.

        Raises:
            ValueError: the first violation, naming the object.
        """
        h = condition.allowed_half_width_mm
        discs = [(np.asarray(target_xy_mm, dtype=np.float64), condition.target.radius_mm, "the target")]
        for i, o in enumerate(self.objects):
            xy = np.asarray(o.xy_mm)
            name = f"distractor {i} ({o.shape}, {o.diameter_mm:g} mm at {o.xy_mm})"
            if np.any(np.abs(xy) > h):
                raise ValueError(f"{name} lies outside the allowed box ±{h} mm")
            for c, r, other in discs:
                if np.hypot(*(xy - c)) < o.radius_mm + r + gap_mm:
                    raise ValueError(f"{name} overlaps {other} (centres must be ≥ radii + {gap_mm} mm apart)")
            discs.append((xy, o.radius_mm, f"distractor {i}"))
        return self

    def scene(self, condition: Condition) -> Scene | None:
        """The distractors as a :class:`~electroloc_gym.world.scene.Scene` in ``condition``'s water, amplifier,
        geometry and signal scale (None when there are none).
        """
        if not self.objects:
            return None
        return Scene(
            name=f"{condition.name}+{len(self.objects)} distractors",
            objects=self.objects,
            water=condition.water,
            amplifier=condition.amplifier,
            allowed_half_width_mm=condition.allowed_half_width_mm,
            start_half_width_mm=condition.start_half_width_mm,
            signal_scale=condition.signal_scale,
            geometry=condition.geometry,
        )

    def reading_V(self, condition: Condition, carriage_mm: ArrayLike) -> NDArray:
        """The distractors' part of the noise-free, unsaturated reading, s·G·Σ_k (δV_k(S1) − δV_k(S2)) (V),
        with the carriage at ``carriage_mm`` (..., 2); exactly 0 without distractors. float32 stays float32.
        """
        p = np.asarray(carriage_mm)
        if p.dtype not in (np.float32, np.float64):
            p = p.astype(np.float64)
        scene = self.scene(condition)
        if scene is None:
            return np.zeros(p.shape[:-1], dtype=p.dtype)
        return scene.expected_reading(p, saturate=False)


def superposed_reading_V(
    condition: Condition,
    target_xy_mm: ArrayLike,
    distractors: DistractorSet,
    carriage_mm: ArrayLike,
    *,
    saturate: bool = True,
) -> NDArray:
    """The noise-free reading Φ (V) of the target and the distractors together, carriage at ``carriage_mm``
    (..., 2): the target's term plus the distractors', then the clip. Without distractors it is
    :func:`~electroloc_gym.world.sensor.expected_reading` of the target, bit for bit.
    """
    p = np.asarray(carriage_mm)
    if p.dtype not in (np.float32, np.float64):
        p = p.astype(np.float64)
    target = expected_reading(condition, np.asarray(target_xy_mm, dtype=p.dtype) - p, saturate=False)
    if len(distractors) == 0:
        phi = target
    else:
        phi = target + distractors.reading_V(condition, p)
    if saturate:
        sat = phi.dtype.type(condition.saturation_V)
        phi = np.clip(phi, -sat, sat)
    return phi


def resolve_distractors(value: Any) -> DistractorDraw | DistractorSet:
    """What a ``distractors=`` argument means: an int D (a :class:`DistractorDraw` of D per episode), a
    sequence of ints (one of these counts drawn per episode), a :class:`DistractorDraw` or
    :class:`DistractorSet`, a mapping of :class:`DistractorDraw`'s fields, or a sequence of
    :class:`~electroloc_gym.world.scene.SceneObject` / their field mappings (an explicit layout).

    Raises:
        ValueError: anything else (naming the argument and the accepted forms).
    """
    try:
        return _resolve(value)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(
            msg if msg.startswith("distractors") or "(distractors)" in msg else f"distractors: {msg}"
        ) from None


def _resolve(value: Any) -> DistractorDraw | DistractorSet:
    if isinstance(value, (DistractorDraw, DistractorSet)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return DistractorDraw(count=int(value))
    if isinstance(value, Mapping):
        try:
            return DistractorDraw(**dict(value))
        except TypeError as exc:
            raise ValueError(f"distractors: {exc}") from exc
    if (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value)
        and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value)
    ):
        return DistractorDraw(count=tuple(value))
    if isinstance(value, Sequence) and not isinstance(value, str):
        objects = []
        for item in value:
            if isinstance(item, Mapping):
                try:
                    item = SceneObject(**dict(item))
                except TypeError as exc:
                    raise ValueError(f"distractors: {exc}") from exc
            objects.append(item)
        return DistractorSet(tuple(objects))
    raise ValueError(
        f"distractors must be a count 0–{MAX_DISTRACTORS} (or a list of counts), a DistractorDraw, "
        f"a DistractorSet, a dict of DistractorDraw's fields or a sequence of SceneObject, got {value!r}"
    )
