"""zero-crossing: the paper's deterministic controller #3 (§4.2), with no belief and no calibration.

The EEV of any isolated sphere has two straight 0 V lines through the target (paper §4.2, Fig. 2): by
symmetry the reading vanishes whenever the carriage centre has the target's x (the field at the
target is then parallel to x and the sensors lie on the y axis) or the target's y (the two sensors
are mirror images). Across either line the reading changes sign with a steep gradient. The
controller finds both lines:

1. **Binary search in x** (§4.2): the workspace (160 × 160 mm centred on the start position, paper
   §6.4, Table 1) is searched column by column in bisection order — centre, then the midpoints of
   the halves, quarters, … down to ``column_spacing_mm`` — each column scanned along y in 10 mm
   steps for a robust polarity change. A strong one (``strong_sigmas``) ends the search; otherwise
   every column is scanned and the strongest robust change is taken: y*.
2. **The x crossing**: the carriage scans in x along the row ``y* ± row_offset_mm`` for the second
   robust polarity change: x*.
3. **Confirmation of y** (our addition): a short y scan on the column ``x* ± row_offset_mm``, where
   the lobes are strongest, re-measures y* (a far search column can only see the weak outer lobes).
4. **Sub-step refinement** of each crossing: a line is fitted by least squares to averaged readings
   on a small symmetric pattern (``±refine_offsets_mm``) around the crossing interpolated between the
   two bracketing scan readings; its zero is the estimate. The reading is an odd function of the
   offset across each 0 V line, so the symmetric pattern cancels the even curvature terms.

**Robustness to noise.** The controller knows the amplifier noise ``G·σ_s`` (a property of the
sensor, ``condition.noise_std_V``) but nothing about the target (no sensor model, no χ, no size, no
particle filter):

* every scan point averages ``n_average`` readings (the carriage stays put; each reading is an
  observation): noise σ/√n;
* a reading is *significant* when |mean| > ``k_sigma`` · σ/√n (3σ: a false alarm has probability
  0.27 %); consecutive significant readings of one sign form a *lobe*;
* a polarity change counts only between two consecutive lobes at most ``max_gap_mm`` apart, whose
  peaks agree within ``lobe_ratio_max`` and dominate every other lobe of the scan
  (``lobe_dominance``). The straight 0 V line is flanked by the two strongest lobes, equal in size
  (the reading is odd across it); a crossing of the EEV's circular 0 V contour always has a weak
  outer lobe on one side (the paper's "small gradient" there, §4.2) and is rejected, which matters
  for the 38.1 mm spheres whose outer lobes exceed the noise.

The controller ends the trial itself (``done``) and reports ``estimate_mm`` (or ``None`` when no
crossing was found in the whole workspace or the observation budget runs out: a failure).
"""

from __future__ import annotations

import math
from collections.abc import Generator, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.base import MAX_STEP_MM, BaselineAgent, require_target_belief

__all__ = ["ZeroCrossingAgent", "TABLE1_WORKSPACE_HALF_MM", "TABLE1_CENTRE_HALF_MM"]

#: Half-width of the scanned workspace, mm (paper §6.4: 160 mm × 160 mm).
TABLE1_WORKSPACE_HALF_MM = 80.0
#: The workspace centre is drawn uniformly within ± this, mm (paper §6.4: ±75 mm).
TABLE1_CENTRE_HALF_MM = 75.0

# A waypoint request from the search programme, and what it receives back: (position mm, reading V).
_Obs = tuple[NDArray[np.float64], float]


class _GiveUp(Exception):
    """No robust crossing found where one was needed."""


def _line_zero(ts: Sequence[float], vs: Sequence[float]) -> float | None:
    """Where the least-squares line through the points (``ts`` mm, ``vs`` V) crosses 0 V, mm; None where fewer
    than two points, or no slope, define one.

    Python floats and exactly rounded sums (``math.fsum``), not ``np.polyfit``: its LAPACK solve runs the
    kernels OpenBLAS picks for the CPU, whose last bits differ between CPUs, and the estimate must not.
    """
    ts, vs = [float(t) for t in ts], [float(v) for v in vs]
    n = len(ts)
    if n < 2 or len(vs) != n:
        return None
    t_mean, v_mean = math.fsum(ts) / n, math.fsum(vs) / n
    sxx = math.fsum((t - t_mean) * (t - t_mean) for t in ts)
    sxy = math.fsum((t - t_mean) * (v - v_mean) for t, v in zip(ts, vs))
    slope = sxy / sxx if sxx > 0 else 0.0
    if slope == 0 or not math.isfinite(slope):
        return None
    return t_mean - v_mean / slope


class ZeroCrossingAgent(BaselineAgent):
    """Binary search for the EEV's polarity changes (paper §4.2, controller #3).

    Args:
        seed: unused (the controller is deterministic); accepted for a uniform interface.
        n_average: readings averaged per scan point.
        n_average_refine: readings averaged per refinement point.
        k_sigma: significance threshold in units of the averaged noise.
        max_gap_mm: largest distance between the two readings bracketing a polarity change.
        column_spacing_mm: finest spacing of the binary search's columns.
        row_offset_mm: offset of the x scan from the found y crossing (and of the y refinement column
            from the found x crossing).
        lobe_ratio_max: largest ratio of the two lobe peaks flanking an accepted crossing.
        lobe_dominance: the weaker flanking lobe must be this many times every other lobe's peak.
        strong_sigmas: a crossing whose weaker flank exceeds this many averaged-noise σ ends the column
            search at once (otherwise every column is scanned and the strongest crossing is used).
        confirm_reach_mm: half-length of the confirming y scan beside the found x.
        refine_offsets_mm: half-offsets of the symmetric refinement pattern.
        workspace_half_mm: half-width of the workspace centred on the start position.
        max_observations: observation budget (also passed to the env as its cap).

    Attributes:
        estimate_mm: the target estimate (x, y) once ``done``; None on failure.
        workspace_mm: (low, high) corners of the scanned workspace.
    """

    name = "zero-crossing"
    table_layout = "table1"
    #: A scan without a belief: quicker trials than the belief planners'.
    cost_rank = 1
    #: It follows one pair's zero crossings (§4.2): the paper's single pair only.
    sensor_layouts = ("single",)

    def __init__(
        self,
        seed: int | np.random.Generator | None = None,
        n_average: int = 4,
        n_average_refine: int = 8,
        k_sigma: float = 3.0,
        max_gap_mm: float = 30.0,
        column_spacing_mm: float = 20.0,
        row_offset_mm: float = 15.0,
        refine_offsets_mm: tuple[float, ...] = (1.5, 3.0),
        workspace_half_mm: float = TABLE1_WORKSPACE_HALF_MM,
        lobe_ratio_max: float = 2.5,
        lobe_dominance: float = 1.5,
        strong_sigmas: float = 6.0,
        confirm_reach_mm: float = 40.0,
        max_observations: int = 1500,
    ) -> None:
        super().__init__(seed)
        for name, val, low in (
            ("n_average", n_average, 1),
            ("n_average_refine", n_average_refine, 1),
            ("max_observations", max_observations, 2),
        ):
            if isinstance(val, bool) or not isinstance(val, int) or val < low:
                raise ValueError(f"{name} must be an integer ≥ {low}, got {val!r}")
        for name, val in (
            ("k_sigma", k_sigma),
            ("max_gap_mm", max_gap_mm),
            ("column_spacing_mm", column_spacing_mm),
            ("row_offset_mm", row_offset_mm),
            ("workspace_half_mm", workspace_half_mm),
            ("lobe_ratio_max", lobe_ratio_max),
            ("lobe_dominance", lobe_dominance),
            ("strong_sigmas", strong_sigmas),
            ("confirm_reach_mm", confirm_reach_mm),
        ):
            if isinstance(val, bool) or not isinstance(val, (int, float)) or not np.isfinite(val) or val <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {val!r}")
        offs = tuple(float(o) for o in refine_offsets_mm)
        if not offs or any(not np.isfinite(o) or o <= 0 for o in offs):
            raise ValueError(f"refine_offsets_mm must be positive offsets in mm, got {refine_offsets_mm!r}")
        self.n_average = n_average
        self.n_average_refine = n_average_refine
        self.k_sigma = float(k_sigma)
        self.max_gap_mm = float(max_gap_mm)
        self.column_spacing_mm = float(column_spacing_mm)
        self.row_offset_mm = float(row_offset_mm)
        self.refine_offsets_mm = offs
        self.workspace_half_mm = float(workspace_half_mm)
        self.max_observations = max_observations
        self.lobe_ratio_max = float(lobe_ratio_max)
        self.lobe_dominance = float(lobe_dominance)
        self.strong_sigmas = float(strong_sigmas)
        self.confirm_reach_mm = float(confirm_reach_mm)
        # The belief is unused: a tiny filter keeps the env cheap, a tiny success spread keeps the env
        # from ending the trial on the filter's account; the trial ends when this controller is done.
        self.env_kwargs = {
            "n_particles": 16,
            "sensor_model": "analytic",
            "success_spread_mm": 1e-6,
            "max_observations": max_observations,
        }
        self.workspace_mm: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._program: Generator[NDArray[np.float64], _Obs, tuple[float, float] | None] | None = None
        self._started = False

    # ---- benchmark hooks ----------------------------------------------------------------------
    @staticmethod
    def adapt_condition(condition: Any) -> Any:
        """The paper's Table-1 layout (§6.4): workspace 160 × 160 mm centred at a random point ±75 mm.

        The carriage starts uniformly in ±75 mm (the workspace centre) and may go anywhere within
        ±(75 + 80) mm, so every workspace fits in the allowed box.
        """
        return condition.replace(
            start_half_width_mm=TABLE1_CENTRE_HALF_MM,
            allowed_half_width_mm=TABLE1_CENTRE_HALF_MM + TABLE1_WORKSPACE_HALF_MM,
        )

    def reset(self, env: Any) -> None:
        """Bind to ``env``'s agent view and set the workspace around the start (the carriage's position).

        Raises:
            ValueError: an env of another sensor layout, or one whose belief is over the robot's own position
                (ElectroLocGlobal-v0: the robot does not know where it is, so it cannot follow a crossing).
        """
        super().reset(env)
        require_target_belief(self.env, self.name)
        core = self.env
        start = core.position_mm
        low, high = core.allowed_box_mm
        self.workspace_mm = (
            np.maximum(start - self.workspace_half_mm, low),
            np.minimum(start + self.workspace_half_mm, high),
        )
        self._sigma = float(core.condition.noise_std_V)
        self._saturation = float(core.condition.saturation_V)
        self._program = self._search()
        self._started = False

    def predict(
        self, observation: NDArray, state: Any = None, episode_start: NDArray | None = None, deterministic: bool = True
    ) -> tuple[NDArray[np.float32], Any]:
        core = self.env
        if self.done or self._program is None:
            return self.action_of(np.zeros(2)), state
        pos = core.position_mm
        try:
            if not self._started:
                self._started = True
                waypoint = next(self._program)
            else:
                waypoint = self._program.send((pos, float(core.last_reading_V)))
        except StopIteration as stop:
            self.done = True
            self.estimate_mm = stop.value
            return self.action_of(np.zeros(2)), state
        move = np.clip(np.asarray(waypoint, dtype=np.float64) - pos, -MAX_STEP_MM, MAX_STEP_MM)
        return self.action_of(move), state

    # ---- the search programme (a generator: yields waypoints ≤ 10 mm away, receives readings) ------
    def _search(self) -> Generator[NDArray[np.float64], _Obs, tuple[float, float] | None]:
        core = self.env
        self._pos = core.position_mm
        self._phi = float(core.last_reading_V)
        self._count = 1
        if self.workspace_mm is None:
            raise RuntimeError(f"{type(self).__name__}.reset(env) must set the workspace before the search")
        lo, hi = self.workspace_mm
        centre = 0.5 * (lo + hi)
        try:
            # 1. binary search over columns, each scanned along y for a robust polarity change. A strong
            #    crossing ends the search at once; otherwise the strongest one found is used.
            best: tuple[float, float, float] | None = None  # (strength in σ units, y*, column x)
            for x in self._bisection_columns(lo[0], hi[0]):
                samples = yield from self._scan_line(axis=1, fixed=x, lo=lo[1], hi=hi[1])
                found = self._best_crossing(samples)
                if found is not None and (best is None or found[1] > best[0]):
                    best = (found[1], found[0], x)
                    if found[1] >= self.strong_sigmas:
                        break
            if best is None:
                return None
            y_star = best[1]
            # 2. the x crossing along the row y* ± row offset, across the whole workspace.
            row = self._offset_inside(y_star, centre[1], lo[1], hi[1])
            samples = yield from self._scan_line(axis=0, fixed=row, lo=lo[0], hi=hi[0])
            found = self._best_crossing(samples)
            if found is None:
                return None
            x_star = found[0]
            # 3. confirm y on a column beside x* (strong lobes there), within ±confirm_reach_mm of y*.
            col = self._offset_inside(x_star, centre[0], lo[0], hi[0])
            samples = yield from self._scan_line(
                axis=1,
                fixed=col,
                lo=max(lo[1], y_star - self.confirm_reach_mm),
                hi=min(hi[1], y_star + self.confirm_reach_mm),
            )
            found = self._best_crossing(samples)
            if found is not None:
                y_star = found[0]
            # 4. sub-step refinement of both crossings on symmetric patterns.
            row = self._offset_inside(y_star, centre[1], lo[1], hi[1])
            x_fine = yield from self._refine(axis=0, fixed=row, guess=x_star, lo=lo[0], hi=hi[0])
            col = self._offset_inside(x_fine, centre[0], lo[0], hi[0])
            y_fine = yield from self._refine(axis=1, fixed=col, guess=y_star, lo=lo[1], hi=hi[1])
            return (float(x_fine), float(y_fine))
        except _GiveUp:
            return None

    def _offset_inside(self, value: float, centre: float, lo: float, hi: float) -> float:
        """``value ± row_offset_mm``, on the side of the workspace centre (and inside it)."""
        off = self.row_offset_mm if centre >= value else -self.row_offset_mm
        return float(np.clip(value + off, lo, hi))

    def _bisection_columns(self, lo: float, hi: float) -> list[float]:
        """Column x positions in binary-search order: centre, then midpoints of halves, quarters, …"""
        cols: list[float] = [0.5 * (lo + hi)]
        intervals = [(lo, 0.5 * (lo + hi)), (0.5 * (lo + hi), hi)]
        while intervals and (intervals[0][1] - intervals[0][0]) >= self.column_spacing_mm:
            nxt = []
            for a, b in intervals:
                cols.append(0.5 * (a + b))
                nxt += [(a, 0.5 * (a + b)), (0.5 * (a + b), b)]
            intervals = nxt
        return cols

    # ---- motion and measurement primitives ------------------------------------------------------
    def _goto(self, target: NDArray[np.float64]) -> Generator[NDArray[np.float64], _Obs, None]:
        """Travel to ``target`` in steps of ≤ 10 mm per axis (each step takes a reading)."""
        target = np.asarray(target, dtype=np.float64)
        while np.max(np.abs(target - self._pos)) > 1e-3:  # float32 actions: ~1e-6 mm round-off
            step = np.clip(target - self._pos, -MAX_STEP_MM, MAX_STEP_MM)
            yield from self._take(self._pos + step)
            if np.max(np.abs(self._pos - self._pos_request)) > 1e-3:  # blocked by a wall: stop there
                break

    def _take(self, waypoint: NDArray[np.float64]) -> Generator[NDArray[np.float64], _Obs, None]:
        """Request one step (a reading) at ``waypoint``."""
        if self._count >= self.max_observations:
            raise _GiveUp
        self._pos_request = np.asarray(waypoint, dtype=np.float64)
        pos, phi = yield self._pos_request
        self._pos, self._phi = np.asarray(pos, dtype=np.float64), float(phi)
        self._count += 1

    def _average(self, n: int, fresh: bool) -> Generator[NDArray[np.float64], _Obs, tuple[float, int]]:
        """Mean of ``n`` readings here: the last one (unless ``fresh``) plus stays."""
        vals = [] if fresh else [self._phi]
        while len(vals) < n:
            yield from self._take(self._pos.copy())
            vals.append(self._phi)
        return float(np.mean(vals)), len(vals)

    def _point(self, axis: int, fixed: float, t: float) -> NDArray[np.float64]:
        p = np.empty(2)
        p[axis], p[1 - axis] = t, fixed
        return p

    def _significant(self, mean: float, n: int) -> int:
        """+1 / −1 if |mean| exceeds k·σ/√n, else 0."""
        thr = self.k_sigma * self._sigma / np.sqrt(n)
        return int(np.sign(mean)) if abs(mean) > thr else 0

    # ---- scans ------------------------------------------------------------------------------------
    def _scan_line(
        self, axis: int, fixed: float, lo: float, hi: float
    ) -> Generator[NDArray[np.float64], _Obs, list[tuple[float, float, int]]]:
        """Averaged readings every ≤ 10 mm along ``axis`` at ``fixed`` over [lo, hi].

        The sweep starts at the end nearer to the carriage (boustrophedon). Returns (t, mean, n)
        samples sorted by t.
        """
        here = self._pos[axis]
        forward = abs(here - lo) <= abs(here - hi)
        start, end = (lo, hi) if forward else (hi, lo)
        n_points = int(np.ceil(abs(end - start) / MAX_STEP_MM - 1e-9)) + 1
        ts = np.linspace(start, end, n_points) if n_points > 1 else np.array([start])
        samples = []
        for t in ts:
            yield from self._goto(self._point(axis, fixed, t))
            mean, n = yield from self._average(self.n_average, fresh=False)
            samples.append((float(self._pos[axis]), mean, n))
        samples.sort()
        return samples

    def _best_crossing(self, samples: list[tuple[float, float, int]]) -> tuple[float, float] | None:
        """The robust polarity change of a scan (the straight 0 V line) and its strength, or None.

        Significant readings (|mean| > k·σ/√n) are grouped into *lobes* of one sign; a polarity
        change lies between two consecutive lobes at most ``max_gap_mm`` apart. The straight 0 V line
        through the target is flanked by the two strongest lobes of the scan, of equal strength (the
        reading is odd across it); a crossing of the EEV's circular 0 V contour has a weak outer
        lobe on one side (paper §4.2: small gradient there). So a crossing is accepted when its two
        flanking lobe peaks agree within ``lobe_ratio_max`` and the weaker of them is at least
        ``lobe_dominance`` × every other lobe's peak; among accepted ones the strongest wins.

        Returns:
            (crossing position along the scan in mm, strength = weaker flank peak in units of the
            averaged noise σ/√n), or None.
        """
        lobes: list[list[float]] = []  # [sign, peak, t_first, v_first, t_last, v_last]
        for t, v, n in samples:
            sign = self._significant(v, n)
            if sign == 0:
                continue
            if lobes and lobes[-1][0] == sign:
                lob = lobes[-1]
                lob[1] = max(lob[1], abs(v))
                lob[4], lob[5] = t, v
            else:
                lobes.append([float(sign), abs(v), t, v, t, v])
        best, best_strength = None, 0.0
        for i in range(len(lobes) - 1):
            left, right = lobes[i], lobes[i + 1]
            if right[2] - left[4] > self.max_gap_mm + 1e-6:
                continue
            weak, strong = sorted((left[1], right[1]))
            others = max((lob[1] for j, lob in enumerate(lobes) if j not in (i, i + 1)), default=0.0)
            if strong > self.lobe_ratio_max * weak or weak < self.lobe_dominance * others:
                continue
            if weak > best_strength:
                best, best_strength = self._interpolate(left[4], left[5], right[2], right[3]), weak
        if best is None:
            return None
        return best, best_strength / (self._sigma / np.sqrt(self.n_average))

    def _interpolate(self, t0: float, v0: float, t1: float, v1: float) -> float:
        """Linear zero crossing between two readings of opposite sign (clamped to the bracket)."""
        if v0 == v1:
            return 0.5 * (t0 + t1)
        t = t0 + v0 * (t1 - t0) / (v0 - v1)
        return float(np.clip(t, min(t0, t1), max(t0, t1)))

    def _refine(
        self, axis: int, fixed: float, guess: float, lo: float, hi: float
    ) -> Generator[NDArray[np.float64], _Obs, float]:
        """Least-squares zero of the reading on a symmetric pattern around ``guess`` (sub-step)."""
        offs = sorted({0.0, *self.refine_offsets_mm, *(-o for o in self.refine_offsets_mm)})
        ts, vs = [], []
        for o in offs:
            t = float(np.clip(guess + o, lo, hi))
            yield from self._goto(self._point(axis, fixed, t))
            mean, _ = yield from self._average(self.n_average_refine, fresh=False)
            if abs(mean) < 0.999 * self._saturation:  # a clipped reading carries no slope information
                ts.append(self._pos[axis])
                vs.append(mean)
        t_zero = _line_zero(ts, vs)
        if t_zero is None:
            return guess
        span = max(self.refine_offsets_mm)
        # Trust the fit within the pattern (a noisy fit can put the zero far away).
        return float(np.clip(t_zero, guess - 2 * span, guess + 2 * span))

    def __repr__(self) -> str:
        return (
            f"ZeroCrossingAgent(n_average={self.n_average}, k_sigma={self.k_sigma}, "
            f"column_spacing_mm={self.column_spacing_mm})"
        )
