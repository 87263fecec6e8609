"""ElectroLoc-v0: move the sensing carriage until the particle belief pins the target down."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition
from electroloc_gym.envs.base import ACTION_TYPES, DISCRETE_MOVES_MM, MAX_STEP_MM, ParticleFilterEnv
from electroloc_gym.envs.base import check_int as _check_int  # noqa: F401  (kept for importers)
from electroloc_gym.envs.observation import belief_observation, condition_descriptor, raw_observation
from electroloc_gym.sensor import noisy_reading
from electroloc_gym.sensor_models import make_sensor_model

__all__ = ["ElectroLocEnv", "MAX_STEP_MM", "DISCRETE_MOVES_MM", "ACTION_TYPES"]


class ElectroLocEnv(ParticleFilterEnv):
    """
    ## Description

    The robot of Solberg, Lynch & MacIver (IJRR 2008, "Active Electrolocation for Underwater Target
    Localization"). A carriage carrying two field emitters and two voltage sensors (50 mm apart)
    moves in a horizontal plane over a water tank. A sphere below distorts the emitted field; the
    robot reads the amplified, noisy, saturating difference of the two sensor voltages. A particle
    filter (2500 particles, paper §4.1) holds the belief of where the target is. The agent moves the
    carriage until the belief is tight: √trace Σ ≤ 10 mm.

    ## Action Space

    ``action_type="continuous"`` (default): ``Box(-1, 1, (2,), float32)``, scaled to a move of at most
    10 mm per axis; finite values outside [−1, 1] are clipped. The carriage is kept inside the allowed
    box (the move is truncated at the walls). ``action_type="discrete"``: ``Discrete(9)``, stay or one of
    the 8 moves of ±10 mm / 0 per axis (index = 3·(dx+1) + (dy+1)).

    ## Observation Space

    ``observation="belief"`` (default): ``Box(-1, 1, (81,), float32)``:

    | index | feature | unit / normalisation |
    |-------|---------|----------------------|
    | 0–1   | carriage position x, y | mm / H (allowed half-width) |
    | 2     | last reading Φ | V / 10 V |
    | 3     | last reading in noise units | tanh(Φ / 3·G·σ_s) |
    | 4–5   | belief mean − carriage | mm / 2H |
    | 6–7   | belief std x, y | mm / H |
    | 8     | belief correlation | — |
    | 9     | spread √trace Σ | mm / H |
    | 10    | log₁₀(spread / 10 mm) | clipped to [−1, 1] |
    | 11    | observations used / cap | — |
    | 12–75 | 8×8 egocentric particle histogram over ±H | mass fraction |
    | 76–80 | condition: radius/25 mm, χ, log₁₀ G / 4, G·σ_s (V), signal scale / 8 | — |

    ``observation="raw"``: ``Box(-1, 1, (3,), float32)`` = [x/H, y/H, Φ/10 V] (no belief).

    ## Rewards

    −1 per step (every new reading). Minimising the return minimises the observations used.

    ## Starting State

    The target sits at the condition's ``target_xy_mm`` (tank centre for the paper's presets; uniform
    in the start box with ``randomize_target=True``). The carriage starts uniformly in the start box
    (±40 mm for 12.7 mm spheres, ±55 mm for 38.1 mm). The particles are uniform over the allowed box
    (±50 / ±60 mm). reset() takes and fuses the first reading (observation count 1).

    ## Episode End

    * Termination: the belief's spread √trace Σ ≤ ``success_spread_mm`` (10 mm): success.
    * Truncation: ``max_observations`` readings (35, paper §5.4) fused without success: failure.

    The observation cap is enforced by the env itself rather than a ``TimeLimit`` wrapper, because it
    counts observations (the first one is taken by reset) and is part of the observation (index 11);
    a wrapper the env cannot see would make that feature lie when a user changes the cap.

    ## Info

    ``position_mm``, ``estimate_mm`` (tuples of float, mm), ``error_mm`` (estimate − true target),
    ``spread_mm``, ``reading_V``, ``n_observations``, ``success``, ``condition`` (name). ``error_mm``
    uses the ground truth: it is for evaluation, agents must not act on it.

    ## Accessors (read-only, on ``env.unwrapped``)

    ``belief`` (ParticleBelief over the target position), ``sensor_model``, ``condition``,
    ``position_mm`` (carriage), ``allowed_box_mm``, ``n_observations``, ``last_reading_V``, ``path_mm``;
    ``predicted_reading_model(particles_mm, moves_mm)`` → (mean_V, std_V) of the reading each target
    hypothesis predicts after a commanded move (offsets = particle − clip(carriage + move)), and
    ``predicted_particles_mm`` (the target does not move: the particles unchanged). The same calls
    exist on ``ElectroLocGlobal-v0`` (shared machinery, :mod:`electroloc_gym.envs.base`).

    ## Arguments

    ```python
    gym.make("ElectroLoc-v0", condition="fresh-steel-12.7", observation="belief",
             sensor_model="calibrated", n_particles=2500, max_observations=35,
             success_spread_mm=10.0, signal="fitted", action_type="continuous",
             randomize_target=False, calibration_seed=None, render_mode=None)
    ```

    * ``condition``: a preset name (``electroloc_gym.PRESET_NAMES``), a ``Condition``, or ``"random"`` to
      draw one of the eight presets per episode.
    * ``sensor_model``: the agent's (and the filter's) sensor model, ``"analytic"`` or ``"calibrated"``
      (the paper's 4 mm grid of 10 readings, drawn per episode from ``calibration_seed`` or, if None,
      from the env's seeded generator).
    * ``signal``: ``"fitted"`` (presets' signal scale fitted to the hardware, DESIGN §3.3) or
      ``"paper"`` (the paper's equations, scale 1); ignored for a ``Condition``.

    ## Version History

    * v0: initial version.
    """

    def __init__(
        self,
        condition: str | Condition = "fresh-steel-12.7",
        observation: str = "belief",
        sensor_model: str = "calibrated",
        n_particles: int = 2500,
        max_observations: int = 35,
        success_spread_mm: float = 10.0,
        signal: str | float = "fitted",
        action_type: str = "continuous",
        randomize_target: bool = False,
        calibration_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(condition, str) and condition == "random":
            self._condition_pool: tuple[Condition, ...] = tuple(get_condition(n, signal) for n in PRESET_NAMES)
        else:
            self._condition_pool = (get_condition(condition, signal),)
        self._init_common(observation, sensor_model, n_particles, max_observations, success_spread_mm, action_type,
                          calibration_seed, render_mode)
        self.randomize_target = bool(randomize_target)
        self._condition = self._condition_pool[0]
        self._sensor_model = make_sensor_model("analytic", self._condition)
        self._target = np.zeros(2)
        self._descriptor = condition_descriptor(self._condition)

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """Carriage centre (x, y), mm (a copy)."""
        return self._position.copy()

    @property
    def target_mm(self) -> NDArray[np.float64]:
        """True target centre (x, y), mm (a copy): ground truth for evaluation and rendering, not for agents."""
        return np.array(self._target, dtype=float)

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lo, hi) moves, mm, within ±10 mm that keep the carriage in the allowed box (0 always inside)."""
        low, high = self.allowed_box_mm
        lo = np.minimum(np.maximum(-MAX_STEP_MM, low - self._position), 0.0)
        hi = np.maximum(np.minimum(MAX_STEP_MM, high - self._position), 0.0)
        return lo, hi

    # ---- gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        rng = self.np_random
        pool = self._condition_pool
        self._condition = pool[int(rng.integers(len(pool)))] if len(pool) > 1 else pool[0]
        c = self._condition
        cal_seed = self.calibration_seed if self.calibration_seed is not None else int(rng.integers(2**31 - 1))
        self._sensor_model = make_sensor_model(self.sensor_model_name, c, cal_seed)
        self._descriptor = condition_descriptor(c)
        s = c.start_half_width_mm
        if self.randomize_target:
            self._target = rng.uniform(-s, s, size=2)
        else:
            self._target = np.asarray(c.target_xy_mm, dtype=float)
        self._position = rng.uniform(-s, s, size=2)
        return self._begin_episode(rng)

    # ---- hooks of ParticleFilterEnv -----------------------------------------------------------
    def _execute_move(self, move_mm: NDArray[np.float64]) -> None:
        low, high = self.allowed_box_mm
        self._position = np.clip(self._position + move_mm, low, high)

    def _true_reading(self, rng: np.random.Generator) -> float:
        return float(noisy_reading(self._condition, self._target - self._position, rng))

    def _particle_offsets(self, particles: NDArray) -> NDArray:
        # offsets = target hypothesis − carriage (the sensor models' convention)
        return particles - self._position.astype(particles.dtype)

    def _particles_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        # The target does not move.
        return np.broadcast_to(particles, moves.shape[:-1] + particles.shape).copy()

    def _offsets_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        low, high = self.allowed_box_mm
        carriage = np.clip(self._position + moves, low, high).astype(particles.dtype)  # (..., 2)
        return particles - carriage[..., None, :]

    def _true_state_mm(self) -> NDArray[np.float64]:
        return self._target

    def _make_renderer(self) -> Any:
        from electroloc_gym.render import EpisodeRenderer

        return EpisodeRenderer(self.render_mode)

    def _get_obs(self) -> NDArray[np.float32]:
        c = self._condition
        if self.observation_mode == "raw":
            return raw_observation(self._position, np.asarray(self._reading), c.allowed_half_width_mm, c.saturation_V)
        b = self.belief
        return belief_observation(
            self._position, np.asarray(self._reading), b.particles, None, self._n_obs, self.max_observations,
            c.allowed_half_width_mm, c.noise_std_V, c.saturation_V, self.success_spread_mm, self._descriptor,
            mean_cov=(b.mean(), b.covariance()))
