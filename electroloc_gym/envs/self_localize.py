"""ElectroLocGlobal-v0: the robot localises itself in a pre-mapped tank of six cylinders (paper §6.5)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.envs.base import MAX_STEP_MM, ParticleFilterEnv
from electroloc_gym.envs.observation import belief_observation, condition_descriptor, raw_observation
from electroloc_gym.render import FrameRenderer
from electroloc_gym.scene import BENCHMARK_SCENE, Scene, map_eev, random_cylinder_layout
from electroloc_gym.sensor_models.map import DEFAULT_POSITION_BLUR_MM, make_map_sensor_model
from electroloc_gym.sensor import electrode_positions_mm

__all__ = ["GlobalLocalizationEnv", "LAYOUTS"]

#: Named layouts: the fixed benchmark map, or a fresh seeded six-cylinder map every episode.
LAYOUTS = ("benchmark", "random")


class GlobalLocalizationEnv(ParticleFilterEnv):
    """
    ## Description

    Global self-localisation of the electrolocation robot of Solberg, Lynch & MacIver (IJRR 2008,
    §6.5, Fig. 13–14, Table 2). The tank holds six vertical cylinders of different diameters and
    conductivities within ±80 mm; their EEV map (Fig. 14) is known to the robot. The robot does
    *not* know where it is: the particle belief (2500 particles, uniform over the tank box at start)
    is over the carriage's own position in the map frame. Every commanded move shifts all particles
    by the move (deterministic motion, ``ParticleBelief.predict``: clipped at the walls exactly as the
    true carriage is); every reading reweights them with the map's sensor model. The agent moves the
    carriage until the belief is tight: √trace Σ ≤ 10 mm. The filter, sensor-model machinery, action
    space, success rule, observation cap and observation layout are those of ``ElectroLoc-v0``
    (shared code in :mod:`electroloc_gym.envs.base`): the hidden state differs, the machinery does not.

    The map (``layout="benchmark"``): :data:`electroloc_gym.scene.BENCHMARK_SCENE`, six cylinders
    (Ø 6.35–38.1 mm; steel, brass, aluminium, Delrin, PVC and a 1000 µS/cm gel) in fresh water
    (160 µS/cm) with the fresh-water amplifier (G = 191, σ_s = 0.25 mV RMS) and signal scale 1;
    carriage box ±80 mm, start box ±70 mm. See :mod:`electroloc_gym.scene` for the physics.

    ## Action Space

    As ``ElectroLoc-v0``: ``Box(-1, 1, (2,), float32)`` scaled to a move of at most 10 mm per axis
    (``action_type="discrete"``: ``Discrete(9)``). The true carriage is kept inside the box (truncated
    at the walls); the robot is not told when that happens.

    ## Observation Space

    ``observation="belief"`` (default): ``Box(-1, 1, (81,), float32)``, the layout of ``ElectroLoc-v0``
    built by the same function (:func:`electroloc_gym.envs.observation.belief_observation`) with the
    *map origin* as the reference point instead of the (here unknown) carriage:

    | index | feature (ElectroLocGlobal-v0) | unit / normalisation |
    |-------|---------|----------------------|
    | 0–1   | odometry: sum of the commanded moves since reset (start = 0) | mm / H (clipped) |
    | 2     | last reading Φ | V / 10 V |
    | 3     | last reading in noise units | tanh(Φ / 3·G·σ_s) |
    | 4–5   | belief mean = estimated carriage position in the map frame | mm / 2H |
    | 6–7   | belief std x, y | mm / H |
    | 8     | belief correlation | — |
    | 9     | spread √trace Σ | mm / H |
    | 10    | log₁₀(spread / 10 mm) | clipped to [−1, 1] |
    | 11    | observations used / cap | — |
    | 12–75 | 8×8 histogram of the particles over the map box ±H (allocentric, map frame) | mass fraction |
    | 76–80 | descriptor of ``condition``: mean radius/25 mm, χ*, log₁₀ G / 4, G·σ_s (V), scale / 8 | — |

    χ* is the sphere contrast of the first object's conductivity (``condition``'s stand-in target).
    H = 80 mm for the benchmark map. ``observation="raw"``: ``[odometry_x/H, odometry_y/H, Φ/10 V]``
    (no belief; the true position is never observed).

    ## Rewards

    −1 per step (every new reading), as ``ElectroLoc-v0``.

    ## Starting State

    The carriage starts uniformly in the start box (±70 mm); the particles are uniform over the
    allowed box (±80 mm). reset() takes and fuses the first reading (observation count 1).

    ## Episode End

    * Termination: the belief's spread √trace Σ ≤ ``success_spread_mm`` (10 mm): success.
    * Truncation: ``max_observations`` readings (35) fused without success: failure.

    ## Info

    As ``ElectroLoc-v0``: ``position_mm`` (the TRUE carriage position in the map frame, for
    evaluation), ``estimate_mm`` (belief mean), ``error_mm`` (|estimate − true position|),
    ``spread_mm``, ``reading_V``, ``n_observations``, ``success``, ``condition`` (the scene's name).
    ``position_mm`` and ``error_mm`` use the ground truth: agents must not act on them.

    ## Accessors (read-only, on ``env.unwrapped``)

    ``belief`` (over the carriage position, map frame), ``sensor_model`` (the map model: ``mean_std`` /
    ``log_likelihood`` of offsets = map origin − carriage = −position), ``scene`` (the map),
    ``condition`` (amplifier, water, boxes as a Condition; its target is a nominal stand-in),
    ``allowed_box_mm``, ``move_bounds_mm`` (±10 mm: the robot cannot know where the walls are),
    ``odometry_mm``, ``n_observations``, ``last_reading_V``, ``path_mm`` (true path, for plots),
    ``position_mm`` (ground truth, evaluation only), and the shared
    ``predicted_reading_model(particles_mm, moves_mm)`` → (mean_V, std_V) of the reading each
    position hypothesis predicts after a commanded move (carriage_i = clip(particle_i + move)) and
    ``predicted_particles_mm`` (the hypotheses after the move).

    ## Arguments

    ```python
    gym.make("ElectroLocGlobal-v0", layout="benchmark", observation="belief",
             sensor_model="calibrated", n_particles=2500, max_observations=35,
             success_spread_mm=10.0, action_type="continuous", calibration_seed=None,
             position_blur_mm=2.0, render_mode=None)
    ```

    * ``layout``: ``"benchmark"`` (the fixed map), ``"random"`` (a new six-cylinder map per episode,
      drawn from the env's seeded generator by :func:`electroloc_gym.scene.random_cylinder_layout`),
      or a :class:`~electroloc_gym.scene.Scene`.
    * ``sensor_model``: ``"analytic"`` or ``"calibrated"`` (the paper's 4 mm grid of 10 readings over
      the carriage box, drawn per episode from ``calibration_seed`` or the env's generator).
    * ``position_blur_mm``: the map sensor model's position blur b (std ⊕ |∇Φ|·b), 2 mm by default;
      0 gives the bare model, with which 2500 particles often converge on a wrong place (see
      :mod:`electroloc_gym.scene`).

    ## Version History

    * v0: initial version.
    """

    def __init__(
        self,
        layout: str | Scene = "benchmark",
        observation: str = "belief",
        sensor_model: str = "calibrated",
        n_particles: int = 2500,
        max_observations: int = 35,
        success_spread_mm: float = 10.0,
        action_type: str = "continuous",
        calibration_seed: int | None = None,
        position_blur_mm: float = DEFAULT_POSITION_BLUR_MM,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(layout, Scene):
            self._fixed_scene: Scene | None = layout
        elif isinstance(layout, str) and layout in LAYOUTS:
            self._fixed_scene = BENCHMARK_SCENE if layout == "benchmark" else None
        else:
            raise ValueError(f"layout must be one of {list(LAYOUTS)} or a Scene, got {layout!r}")
        self.layout = layout if isinstance(layout, str) else "custom"
        self._init_common(observation, sensor_model, n_particles, max_observations, success_spread_mm, action_type,
                          calibration_seed, render_mode)
        self._scene = self._fixed_scene if self._fixed_scene is not None else BENCHMARK_SCENE
        self._condition = self._scene.as_condition()
        self.position_blur_mm = float(position_blur_mm)
        self._sensor_model = make_map_sensor_model("analytic", self._scene, position_blur_mm=self.position_blur_mm)
        self._descriptor = condition_descriptor(self._condition)
        self._odometry = np.zeros(2)

    # ---- accessors -----------------------------------------------------------------------------
    @property
    def scene(self) -> Scene:
        """The current episode's map."""
        return self._scene

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """TRUE carriage position in the map frame, mm (a copy) — ground truth for evaluation only."""
        return self._position.copy()

    @property
    def odometry_mm(self) -> NDArray[np.float64]:
        """Sum of the commanded moves since reset, mm (what the robot knows of its own motion)."""
        return self._odometry.copy()

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(−10, −10), (10, 10) mm: the robot does not know where it is, hence not where the walls are."""
        return np.full(2, -MAX_STEP_MM), np.full(2, MAX_STEP_MM)

    # ---- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        rng = self.np_random
        # Draw order: layout (if random), calibration seed, start position, particles, first reading.
        if self._fixed_scene is None:
            self._scene = BENCHMARK_SCENE.replace(name="random-six-cylinders", objects=random_cylinder_layout(rng))
        else:
            self._scene = self._fixed_scene
        self._condition = self._scene.as_condition()
        cal_seed = self.calibration_seed if self.calibration_seed is not None else int(rng.integers(2**31 - 1))
        self._sensor_model = make_map_sensor_model(self.sensor_model_name, self._scene, cal_seed,
                                                   position_blur_mm=self.position_blur_mm)
        self._descriptor = condition_descriptor(self._condition)
        s = self._scene.start_half_width_mm
        self._position = rng.uniform(-s, s, size=2)
        self._odometry = np.zeros(2)
        return self._begin_episode(rng)

    # ---- hooks of ParticleFilterEnv --------------------------------------------------------------
    def _execute_move(self, move_mm: NDArray[np.float64]) -> None:
        low, high = self.allowed_box_mm
        self._position = np.clip(self._position + move_mm, low, high)
        self._odometry = self._odometry + move_mm
        # Deterministic motion model: every position hypothesis moves by the commanded move and is
        # kept in the box, as the true carriage is (paper §4.1, "motion is deterministic").
        self.belief.predict(move_mm)

    def _true_reading(self, rng: np.random.Generator) -> float:
        return float(self._scene.noisy_reading(self._position, rng))

    def _particle_offsets(self, particles: NDArray) -> NDArray:
        # The map model's convention: offsets = map origin − carriage hypothesis.
        return -particles

    def _particles_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        low, high = self.allowed_box_mm
        moved = particles + moves.astype(particles.dtype)[..., None, :]
        return np.clip(moved, low.astype(particles.dtype), high.astype(particles.dtype))

    def _offsets_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        return -self._particles_after_move(particles, moves)

    def _true_state_mm(self) -> NDArray[np.float64]:
        return self._position

    def _make_renderer(self) -> Any:
        return _GlobalRenderer(self.render_mode)

    def _get_obs(self) -> NDArray[np.float32]:
        c = self._condition
        h = c.allowed_half_width_mm
        if self.observation_mode == "raw":
            return raw_observation(self._odometry, np.asarray(self._reading), h, c.saturation_V)
        b = self.belief
        # Reference point = the map origin: entries 4–5 are the estimated position, the histogram
        # covers the whole map box. Entries 0–1 (the carriage in ElectroLoc-v0) become the odometry.
        obs = belief_observation(
            np.zeros(2), np.asarray(self._reading), b.particles, None if b.uniform_weights else b.weights,
            self._n_obs, self.max_observations, h, c.noise_std_V, c.saturation_V, self.success_spread_mm,
            self._descriptor, mean_cov=(b.mean(), b.covariance()))
        obs[0:2] = np.clip(self._odometry / h, -1.0, 1.0)
        return obs


@functools.lru_cache(maxsize=8)
def _cached_map_eev(scene: Scene) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return map_eev(scene, step_mm=1.5)


class _GlobalRenderer(FrameRenderer):
    """A Fig. 13-style frame: the map's EEV, the particles, the true path (asterisks), the estimate."""

    def draw(self, env: GlobalLocalizationEnv) -> NDArray[np.uint8] | None:
        from matplotlib.patches import Circle

        ax = self.ax
        ax.clear()
        scene = env.scene
        grid, phi = _cached_map_eev(scene)
        sat = scene.saturation_V
        ax.pcolormesh(grid, grid, phi.T, cmap="gray_r", vmin=-sat, vmax=sat, shading="auto", alpha=0.6)
        h = scene.allowed_half_width_mm
        ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], color="0.3", lw=0.8)
        for o in scene.objects:
            ax.add_patch(Circle(o.xy_mm, o.radius_mm, fill=False, color="tab:orange", lw=1.0))
        p = env.belief.particles
        ax.scatter(p[:, 0], p[:, 1], s=1.5, c="tab:blue", alpha=0.4, linewidths=0)
        est = env.belief.mean()
        spread = env.belief.spread()
        ax.add_patch(Circle(tuple(est), spread, fill=False, color="tab:green", lw=1.2, ls="--"))
        ax.plot(*est, "+", color="tab:green", ms=10, mew=2, label="estimate")
        path = env.path_mm
        ax.plot(path[:, 0], path[:, 1], "*-", color="tab:red", lw=1.0, ms=5, label="true path")
        el = electrode_positions_mm(env.condition, env.position_mm)  # ground truth, for the picture only
        for key, style in (("emitter+", "rs"), ("emitter-", "bs"), ("S1", "kD"), ("S2", "kD")):
            ax.plot(*el[key], style, ms=5)
        ax.plot(0.0, 0.0, "o", mfc="none", mec="tab:purple", ms=8, mew=1.5)
        ax.set_xlim(-h - 10, h + 10)
        ax.set_ylim(-h - 10, h + 10)
        ax.set_aspect("equal")
        ax.set_title(f"{scene.name}: obs {env.n_observations}, spread {spread:.1f} mm", fontsize=9)
        ax.legend(loc="upper right", fontsize=7)
        return self.finish()
