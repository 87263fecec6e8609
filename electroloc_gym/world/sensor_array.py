"""The sensor array (paper §7): where K differential sensing pairs sit on the carriage, and what each reads.

**Layouts.** The paper's one pair reads ≈ 0 V without a target because both electrodes lie on the emitters'
zero-potential plane x = 0 (carriage frame): the emitter potential ``φ = V_e E (1/|x − x₊| − 1/|x − x₋|)``
(App. A, Eq. 7) is odd in x and even in y. A pair anywhere else sees the emitters' own potential difference
``Δφ_nt`` — tens of mV at the electrodes (88 mV for a pair at (±25, 25) mm), which the gain G = 103–1977 turns
into 9–175 V, far beyond the ±10 V the acquisition passes — unless one of these holds (each named layout says
which):

* **symmetry plane**: both electrodes on x = 0 (φ = 0 there): ``"single"``, ``"line-4"``;
* **mirrored about the emitter axis**: electrodes at (x, y) and (x, −y) (φ is even in y, so Δφ_nt = 0 for
  every x): ``"ring-8"``. (Mirroring about the symmetry plane, (x, y) and (−x, y), is the worst choice:
  φ is odd in x, so Δφ_nt = 2φ(x, y).)
* **extra emitter pairs**: each pair is a full copy of the paper's unit with its own two emitters at the
  pair's centre ± (L/2, 0), the units driven one at a time (time-multiplexed, so no unit sees another's
  field; the idle units' electrode spheres are neglected as the paper neglects its own): ``"grid-2x2"``.
  Unit k reads exactly what the paper's robot reads with its carriage at the unit's centre — the
  "four stationary sensor pairs positioned at the four asterisks" of §7.
* **baseline-subtracting front end** (``subtract_baseline=True``, explicit layouts): the pair's no-target
  difference is removed before the gain, as an instrumentation amplifier's offset trim or the paper's
  no-target mean μ_nt (§6.1) would, but before the ±10 V clip. Modelled as exact (a perfect trim).

A :class:`SensorLayout` holds the pairs' electrode offsets (and, with extra emitter pairs, each pair's own
emitters), checked once when it is built: the shape, 1 ≤ K ≤ :data:`MAX_PAIRS`, finite offsets, no two
electrode or emitter spheres overlapping, every point within the carriage's reach, and every pair on an
equipotential unless a front end subtracts its baseline; every failure is one ``ValueError`` naming
``sensor_layout``. :func:`named_layout` builds the named layouts (:data:`LAYOUT_NAMES`) for a geometry and
:func:`make_sensor_layout` turns any ``sensor_layout`` argument into a layout.

**Readings.** The true reading of pair k is the paper's amplifier applied to that pair:
``Φ_k = clip(s·G·(δV(e_k1) − δV(e_k2)) + G·Δφ_nt,k + ε_k, ±V_sat)``, ``ε_k ~ N(0, (G·σ_s)²)`` independent per
pair, ``δV`` the target's induced dipole (Eq. 4) in the field of the pair's emitters, all from
:mod:`electroloc_gym.world.physics` (``Δφ_nt,k`` is 0, or below :data:`BASELINE_TOLERANCE_V`, or subtracted). A pair
that is the paper's unit translated by c (electrodes c ± (0, L/2), emitters c ± (L/2, 0)) is computed by
:func:`electroloc_gym.world.sensor.sphere_reading` at ``offsets − c``, the compiled fast path: the ``"single"``
layout's numbers are the one-pair sensor's bit for bit. Other pairs are one compiled pass of the same
equations for electrodes and emitters anywhere (:func:`electroloc_gym.kernels.fusion.general_pair_difference`),
tested equal to the physics module's :func:`~electroloc_gym.world.physics.emitter_field` +
:func:`~electroloc_gym.world.physics.sphere_perturbation` (:func:`_general_pair`), which is also tested equal to the
fast path on the paper's pair.
:func:`array_noisy_reading` adds each pair's own noise; :func:`detection_coverage` is the share of the
start box from which at least one pair detects the target.

Offsets are from the carriage centre, (x, y) mm in the carriage frame (for the readings: ``target − carriage
centre``, (..., 2) mm); readings come out with the pairs first, (K, ...), V.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.kernels.fusion import general_pair_difference
from electroloc_gym.utils.checks import check_float
from electroloc_gym.world import physics
from electroloc_gym.world.apparatus import Geometry
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import saturated_reading, sphere_reading

__all__ = [
    "LAYOUT_NAMES",
    "LAYOUT_DESIGNS",
    "CARRIAGE_REACH_MM",
    "BASELINE_TOLERANCE_V",
    "MAX_PAIRS",
    "SensorLayout",
    "named_layout",
    "make_sensor_layout",
    "array_reading",
    "array_noisy_reading",
    "pair_baseline_V",
    "detection_coverage",
]

#: The named layouts (:func:`named_layout`).
LAYOUT_NAMES = ("single", "line-4", "grid-2x2", "ring-8")

#: The design each named layout uses to read ≈ 0 V without a target (module docstring).
LAYOUT_DESIGNS = {
    "single": "symmetry plane",
    "line-4": "symmetry plane",
    "grid-2x2": "extra emitter pairs",
    "ring-8": "mirrored about the emitter axis",
}

#: Every electrode and emitter sits on the carriage's breadboard, a disc of this radius (mm) about the carriage
#: centre: twice the paper's emitter spacing, the width of the 12.7 mm spheres' workspace.
CARRIAGE_REACH_MM = 100.0

#: Largest no-target difference |Δφ_nt| (V, at the electrodes) a pair without a front end may have: 1 µV,
#: 0.4 % of the smallest σ_s of the paper's conditions (0.23 mV), so the baseline is far inside the noise.
BASELINE_TOLERANCE_V = 1e-6

#: Most pairs a layout may have (each pair is a reading per step and a likelihood per particle).
MAX_PAIRS = 64


def _error(message: str) -> ValueError:
    return ValueError(f"sensor_layout: {message}")


def _points3(xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 2) plane points → (..., 3) points on the electrode plane z = 0."""
    return np.concatenate([xy, np.zeros(xy.shape[:-1] + (1,))], axis=-1)


def _pairs_array(value: Any, what: str) -> NDArray[np.float64]:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _error(f"{what} must be a (K, 2, 2) array of electrode (x, y) offsets in mm, got {value!r}") from None
    if arr.ndim == 3 and arr.shape[0] == 0:
        raise _error(f"{what} needs at least one pair (K ≥ 1), got K = 0")
    if arr.ndim != 3 or arr.shape[1:] != (2, 2):
        raise _error(f"{what} must have shape (K, 2, 2) — K pairs of two (x, y) points in mm — got shape {arr.shape}")
    if arr.shape[0] > MAX_PAIRS:
        raise _error(f"{what} must have 1 ≤ K ≤ {MAX_PAIRS} pairs, got K = {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise _error(
            f"{what} must be finite numbers (mm), got non-finite values in pairs "
            f"{sorted(set(np.nonzero(~np.isfinite(arr))[0].tolist()))}"
        )
    return arr


@dataclass(frozen=True)
class SensorLayout:
    """K differential sensing pairs on the carriage (frozen, validated; module docstring for the designs).

    Attributes:
        electrodes_mm: (K, 2, 2) electrode offsets from the carriage centre, mm: pair k reads
            ``δV(electrodes_mm[k, 0]) − δV(electrodes_mm[k, 1])`` (the paper's S1, S2 order). Stored as nested
            tuples (hashable); :attr:`electrodes` is the array.
        emitters_mm: None: every pair is in the field of the carriage's two emitters at (±L/2, 0); or (K, 2, 2):
            pair k's own emitters (+V_e first, then −V_e), the units driven one at a time.
        subtract_baseline: True: every pair has a front end that removes its no-target difference before the
            gain; False: every pair must lie on one equipotential (|Δφ_nt| ≤ :data:`BASELINE_TOLERANCE_V`).
        name: a label (the named layouts' names, or ``"custom"``).
        geometry: the carriage geometry (emitter spacing and drive, electrode radius) the layout is built for.
        reach_mm: every electrode and emitter lies within this distance of the carriage centre, mm (> 0).

    Raises:
        ValueError: one clear error naming ``sensor_layout``: wrong shape, K = 0 or K > :data:`MAX_PAIRS`,
            non-finite offsets, overlapping electrodes (two spheres of radius E closer than 2E, emitters
            included), a point outside the carriage's reach, or a pair off every equipotential without a front end.
    """

    electrodes_mm: Any
    emitters_mm: Any = None
    subtract_baseline: bool = False
    name: str = "custom"
    geometry: Geometry = field(default_factory=Geometry)
    reach_mm: float = CARRIAGE_REACH_MM
    _unit_centres: tuple[tuple[float, float] | None, ...] = field(init=False, repr=False, compare=False)
    _baselines_V: tuple[float, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.geometry, Geometry):
            raise _error(f"geometry must be a Geometry, got {type(self.geometry).__name__}")
        if not isinstance(self.name, str) or not self.name:
            raise _error(f"name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.subtract_baseline, (bool, np.bool_)):
            raise _error(f"subtract_baseline must be True or False, got {self.subtract_baseline!r}")
        try:
            check_float("reach_mm", self.reach_mm, low=0.0)
        except ValueError as exc:
            raise _error(str(exc)) from None
        elec = _pairs_array(self.electrodes_mm, "electrodes_mm")
        k = elec.shape[0]
        h = self.geometry.spacing_mm / 2.0
        if self.emitters_mm is None:
            emit = np.broadcast_to(np.array([[h, 0.0], [-h, 0.0]]), (k, 2, 2))
            points = np.concatenate([elec.reshape(-1, 2), emit[0]])
        else:
            emit = _pairs_array(self.emitters_mm, "emitters_mm")
            if emit.shape[0] != k:
                raise _error(f"emitters_mm must have one emitter pair per sensing pair: K = {k}, got {emit.shape[0]}")
            points = np.concatenate([elec.reshape(-1, 2), emit.reshape(-1, 2)])
            object.__setattr__(self, "emitters_mm", _as_tuples(emit))
        self._check_points(points, 2 * k)
        object.__setattr__(self, "electrodes_mm", _as_tuples(elec))
        object.__setattr__(self, "subtract_baseline", bool(self.subtract_baseline))
        object.__setattr__(self, "reach_mm", float(self.reach_mm))
        g = self.geometry
        phi = physics.emitter_potential(
            _points3(elec),
            _points3(emit[:, None, 0]),
            _points3(emit[:, None, 1]),
            g.emitter_voltage_V,
            g.electrode_radius_mm,
        )
        baseline = phi[:, 0] - phi[:, 1]
        object.__setattr__(self, "_baselines_V", tuple(float(b) for b in baseline))
        if not self.subtract_baseline:
            bad = np.nonzero(np.abs(baseline) > BASELINE_TOLERANCE_V)[0]
            if bad.size:
                i = int(bad[0])
                raise _error(
                    f"pair {i} lies off every equipotential of the emitters: its no-target difference is "
                    f"{baseline[i] * 1e3:.4g} mV at the electrodes (× the gain G = 103–1977 is far beyond ±10 V); "
                    f"place both electrodes on x = 0, or at (x, y) and (x, −y), or give it its own emitters, "
                    f"or set subtract_baseline=True (|Δφ_nt| ≤ {BASELINE_TOLERANCE_V:g} V allowed)"
                )
        centres: list[tuple[float, float] | None] = []
        for e, m in zip(elec, emit, strict=True):
            c = (e[0] + e[1]) / 2.0
            paper_unit = np.array_equal(e, c + np.array([[0.0, h], [0.0, -h]])) and np.array_equal(
                m, c + np.array([[h, 0.0], [-h, 0.0]])
            )
            centres.append((float(c[0]), float(c[1])) if paper_unit else None)
        object.__setattr__(self, "_unit_centres", tuple(centres))

    def _check_points(self, points: NDArray[np.float64], n_electrodes: int) -> None:
        """Reach and overlap of every electrode (first ``n_electrodes`` rows) and emitter."""
        r = np.hypot(points[:, 0], points[:, 1])
        far = np.nonzero(r > self.reach_mm)[0]
        if far.size:
            i = int(far[0])
            what = f"electrode {i % 2} of pair {i // 2}" if i < n_electrodes else "an emitter"
            x, y = (float(v) for v in points[i])
            raise _error(
                f"{what} at ({x:.4g}, {y:.4g}) mm is {float(r[i]):.4g} mm from the carriage centre, "
                f"outside the carriage's reach (≤ {self.reach_mm:g} mm)"
            )
        d = np.hypot(*(points[:, None, :] - points[None, :, :]).transpose(2, 0, 1))
        d[np.diag_indices_from(d)] = np.inf
        min_sep = 2.0 * self.geometry.electrode_radius_mm
        i, j = (int(v) for v in np.unravel_index(int(np.argmin(d)), d.shape))
        if d[i, j] < min_sep:
            i, j = min(i, j), max(i, j)

            def label(n: int) -> str:
                return f"electrode {n % 2} of pair {n // 2}" if n < n_electrodes else "an emitter"

            raise _error(
                f"{label(i)} and {label(j)} overlap: centres {d[i, j]:.3g} mm apart at "
                f"{tuple(points[i].round(3))} mm, less than two electrode radii ({min_sep:g} mm)"
            )

    def pair(self, k: int) -> SensorLayout:
        """Pair ``k`` alone, as a one-pair layout (same emitters, front end, geometry and reach)."""
        if not 0 <= k < self.n_pairs:
            raise IndexError(f"pair index must be in [0, {self.n_pairs}), got {k}")
        emit = None if self.emitters_mm is None else self.emitters_mm[k : k + 1]
        return SensorLayout(
            self.electrodes_mm[k : k + 1],
            emit,
            self.subtract_baseline,
            name=f"{self.name}[{k}]",
            geometry=self.geometry,
            reach_mm=self.reach_mm,
        )

    @property
    def n_pairs(self) -> int:
        """K, the number of sensing pairs."""
        return len(self.electrodes_mm)

    @property
    def electrodes(self) -> NDArray[np.float64]:
        """(K, 2, 2) electrode offsets from the carriage centre, mm."""
        return np.array(self.electrodes_mm, dtype=np.float64)

    @property
    def emitters(self) -> NDArray[np.float64]:
        """(K, 2, 2) the emitters (+, −) whose field each pair reads, mm (the carriage's, repeated, by default)."""
        if self.emitters_mm is None:
            h = self.geometry.spacing_mm / 2.0
            return np.broadcast_to(np.array([[h, 0.0], [-h, 0.0]]), (self.n_pairs, 2, 2)).copy()
        return np.array(self.emitters_mm, dtype=np.float64)

    @property
    def centres_mm(self) -> NDArray[np.float64]:
        """(K, 2) each pair's centre (the midpoint of its electrodes), mm."""
        return self.electrodes.mean(axis=1)

    @property
    def paper_unit_centres(self) -> tuple[tuple[float, float] | None, ...]:
        """Per pair: the centre c (mm) if the pair is the paper's unit translated by c, else None."""
        return self._unit_centres

    @property
    def baselines_V(self) -> NDArray[np.float64]:
        """(K,) each pair's no-target difference Δφ_nt at the electrodes, V, before any front end."""
        return np.array(self._baselines_V)

    @property
    def design(self) -> str:
        """Which design keeps the no-target reading ≈ 0 V (module docstring)."""
        if self.name in LAYOUT_DESIGNS:
            return LAYOUT_DESIGNS[self.name]
        if self.subtract_baseline:
            return "baseline-subtracting front end"
        return "extra emitter pairs" if self.emitters_mm is not None else "pairs on one equipotential"


def _as_tuples(arr: NDArray[np.float64]) -> tuple:
    return tuple(tuple((float(p[0]), float(p[1])) for p in pair) for pair in arr)


def named_layout(name: str, geometry: Geometry | None = None) -> SensorLayout:
    """A named layout for ``geometry`` (default the paper's), lengths in units of h = L/2 (25 mm by default).

    * ``"single"``: the paper's pair, S1 = (0, h), S2 = (0, −h).
    * ``"line-4"``: four pairs on the symmetry plane x = 0, centred at y = ±0.6h, ±1.8h, 0.8h long.
    * ``"grid-2x2"``: four copies of the paper's unit (own emitters, driven in turn) centred at (±1.2h, ±1.2h).
    * ``"ring-8"``: sixteen electrodes on a circle of radius 1.6h at the angles ±(11.25° + 22.5°·j),
      paired (x, y) with (x, −y), in the carriage's field.
    """
    g = Geometry() if geometry is None else geometry
    h = g.spacing_mm / 2.0
    if name == "single":
        return SensorLayout([[[0.0, h], [0.0, -h]]], name=name, geometry=g)
    if name == "line-4":
        ys = (1.8 * h, 0.6 * h, -0.6 * h, -1.8 * h)
        return SensorLayout([[[0.0, y + 0.4 * h], [0.0, y - 0.4 * h]] for y in ys], name=name, geometry=g)
    if name == "grid-2x2":
        d = 1.2 * h
        centres = [(-d, d), (d, d), (-d, -d), (d, -d)]
        return SensorLayout(
            [[[cx, cy + h], [cx, cy - h]] for cx, cy in centres],
            emitters_mm=[[[cx + h, cy], [cx - h, cy]] for cx, cy in centres],
            name=name,
            geometry=g,
        )
    if name == "ring-8":
        r = 1.6 * h
        angles = np.deg2rad(11.25 + 22.5 * np.arange(8))
        return SensorLayout(
            [[[r * math.cos(a), r * math.sin(a)], [r * math.cos(a), -r * math.sin(a)]] for a in angles],
            name=name,
            geometry=g,
        )
    raise _error(
        f"must be one of {list(LAYOUT_NAMES)}, a (K, 2, 2) array of electrode offsets in mm, "
        f"or a SensorLayout; got {name!r}"
    )


def make_sensor_layout(spec: str | SensorLayout | ArrayLike, geometry: Geometry | None = None) -> SensorLayout:
    """The layout of a ``sensor_layout`` argument: a name, a :class:`SensorLayout`, or (K, 2, 2) offsets in mm
    (pairs on one equipotential of the carriage's emitters; :class:`SensorLayout` for the other designs).
    """
    g = Geometry() if geometry is None else geometry
    if isinstance(spec, SensorLayout):
        if spec.geometry != g:
            raise _error(f"was built for {spec.geometry}, the condition has {g}")
        return spec
    if isinstance(spec, str):
        return named_layout(spec, g)
    if spec is None or isinstance(spec, (bool, int, float, dict, set)):
        raise _error(
            f"must be one of {list(LAYOUT_NAMES)}, a (K, 2, 2) array of electrode offsets in mm, "
            f"or a SensorLayout; got {spec!r}"
        )
    return SensorLayout(spec, geometry=g)


def pair_baseline_V(layout: SensorLayout) -> NDArray[np.float64]:
    """(K,) the no-target difference each pair's amplifier input sees, V: 0 with the front end, else Δφ_nt."""
    return np.zeros(layout.n_pairs) if layout.subtract_baseline else layout.baselines_V


def _general_pair(
    condition: Condition,
    electrodes: NDArray[np.float64],
    emitters: NDArray[np.float64],
    off: NDArray[np.float64],
    a: NDArray[np.float64],
    chi: NDArray[np.float64],
) -> NDArray[np.float64]:
    """s·(δV(e1) − δV(e2)) (V, before the gain) of one pair for spheres at ``off`` (..., 2) through the physics
    module's general functions (Eq. 4, 7), float64: the reference the compiled pass is tested against.
    """
    g = condition.geometry
    depth = (a + g.electrode_radius_mm) + g.clearance_mm
    x, y = np.broadcast_arrays(off[..., 0], off[..., 1], depth)[:2]
    centre = np.stack([x, y, -np.broadcast_to(depth, x.shape)], axis=-1)
    emit = _points3(emitters)
    field_V_per_mm = physics.emitter_field(centre, emit[0], emit[1], g.emitter_voltage_V, g.electrode_radius_mm)
    elec = _points3(electrodes)
    dv = physics.sphere_perturbation(elec[0], centre, a, chi, field_V_per_mm) - physics.sphere_perturbation(
        elec[1], centre, a, chi, field_V_per_mm
    )
    return dv * condition.signal_scale


def array_reading(
    condition: Condition,
    layout: SensorLayout,
    offsets_mm: ArrayLike,
    *,
    radius_mm: ArrayLike | None = None,
    chi: ArrayLike | None = None,
    saturate: bool = True,
) -> NDArray[np.floating]:
    """Noise-free readings Φ (K, ...) (V) of every pair for spheres at ``offsets_mm`` (..., 2) = target − carriage.

    Args:
        condition: the tank, sphere and amplifier (every pair has the same amplifier: G, σ_s, ±V_sat).
        layout: the pairs (its geometry must be the condition's).
        offsets_mm: (..., 2) target − carriage centre, mm; float32 stays float32 (as
            :func:`~electroloc_gym.world.sensor.expected_reading`), anything else float64.
        radius_mm: sphere radius, mm (default the condition's; or an array broadcasting against offsets[..., 0]).
        chi: contrast χ (default the condition's; χ = 0 is no target).
        saturate: clip at ±V_sat.
    """
    if layout.geometry != condition.geometry:
        raise _error(f"was built for {layout.geometry}, the condition has {condition.geometry}")
    off = np.asarray(offsets_mm)
    dtype = off.dtype if off.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    off = off.astype(dtype, copy=False)
    a = np.asarray(condition.target.radius_mm if radius_mm is None else radius_mm, dtype=np.float64)
    x = np.asarray(condition.chi if chi is None else chi, dtype=np.float64)
    gain = condition.amplifier.gain
    base = pair_baseline_V(layout)
    out = np.empty((layout.n_pairs,) + np.broadcast_shapes(off.shape[:-1], a.shape, x.shape), dtype=dtype)
    elec, emit = layout.electrodes, layout.emitters
    g = condition.geometry
    strength = x * (a * a * a)
    depth = (a + g.electrode_radius_mm) + g.clearance_mm
    drive = g.emitter_voltage_V * g.electrode_radius_mm
    for k, centre in enumerate(layout.paper_unit_centres):
        if centre is not None:
            shifted = off if centre == (0.0, 0.0) else off - np.asarray(centre, dtype=dtype)
            phi = sphere_reading(condition, shifted, a, x, saturate=False)
        else:  # Eq. 4 + 7 for this pair: the compiled pass, equal to _general_pair's (tested)
            (px, py), (nx, ny) = emit[k]
            (ax, ay), (bx, by) = elec[k]
            phi = general_pair_difference(
                off[..., 0].astype(np.float64),
                off[..., 1].astype(np.float64),
                depth,
                strength,
                drive,
                px,
                py,
                nx,
                ny,
                ax,
                ay,
                bx,
                by,
            )
            phi = phi * (condition.signal_scale * gain)
        if base[k] != 0.0:
            phi = phi + base[k] * gain
        out[k] = phi
    if saturate:
        sat = dtype.type(condition.saturation_V)
        np.clip(out, -sat, sat, out=out)
    return out


def array_noisy_reading(
    condition: Condition, layout: SensorLayout, offsets_mm: ArrayLike, rng: np.random.Generator, **sphere: Any
) -> NDArray[np.float64]:
    """Noisy, saturated readings Φ (K, ...) (V): each pair's own N(0, (G·σ_s)²) noise from ``rng`` (the pairs'
    draws in pair order), then the ±V_sat clip, as :func:`electroloc_gym.world.sensor.noisy_reading` (bit for bit
    for the ``"single"`` layout). ``sphere``: ``radius_mm``, ``chi`` as :func:`array_reading`.
    """
    mean = array_reading(condition, layout, np.asarray(offsets_mm, dtype=np.float64), saturate=False, **sphere)
    return saturated_reading(mean, rng.normal(0.0, condition.noise_std_V, size=mean.shape), condition.saturation_V)


def detection_coverage(
    condition: Condition, layout: SensorLayout, threshold_sigmas: float = 2.0, n_grid: int = 121
) -> float:
    """Fraction of carriage positions (uniform in the start box) from which at least one pair's noise-free reading
    exceeds ``threshold_sigmas``·G·σ_s: the array's analogue of
    :func:`electroloc_gym.world.conditions.start_box_coverage` (equal to it for ``"single"``).
    """
    s = condition.start_half_width_mm
    g = np.linspace(-s, s, n_grid)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    off = np.asarray(condition.target_xy_mm) - np.stack([gx, gy], axis=-1)
    signal = np.abs(array_reading(condition, layout, off))
    return float(np.mean(np.any(signal > threshold_sigmas * condition.noise_std_V, axis=0)))
