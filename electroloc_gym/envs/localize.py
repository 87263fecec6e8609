"""ElectroLoc-v0: move the sensing carriage until the particle belief pins the target down."""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from electroloc_gym.belief import ParticleBelief
from electroloc_gym.conditions import PRESET_NAMES, Condition, get_condition
from electroloc_gym.envs.observation import (
    BELIEF_OBS_DIM,
    OBSERVATION_MODES,
    RAW_OBS_DIM,
    belief_observation,
    condition_descriptor,
    raw_observation,
)
from electroloc_gym.sensor import noisy_reading
from electroloc_gym.sensor_models import SENSOR_MODEL_NAMES, make_sensor_model

__all__ = ["ElectroLocEnv", "MAX_STEP_MM", "DISCRETE_MOVES_MM", "ACTION_TYPES"]

#: Largest move per axis per step, mm (paper §4.1.3).
MAX_STEP_MM = 10.0
#: The discrete action set: stay plus the 8 king moves of 10 mm per axis.
DISCRETE_MOVES_MM = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.float64) * MAX_STEP_MM
ACTION_TYPES = ("continuous", "discrete")


def _check_int(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
    return int(value)


class ElectroLocEnv(gym.Env[NDArray[np.float32], NDArray[np.float32] | int]):
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

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

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
        if observation not in OBSERVATION_MODES:
            raise ValueError(f"observation must be one of {list(OBSERVATION_MODES)}, got {observation!r}")
        if sensor_model not in SENSOR_MODEL_NAMES:
            raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {sensor_model!r}")
        if action_type not in ACTION_TYPES:
            raise ValueError(f"action_type must be one of {list(ACTION_TYPES)}, got {action_type!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.n_particles = _check_int("n_particles", n_particles, 1)
        self.max_observations = _check_int("max_observations", max_observations, 1)
        if isinstance(success_spread_mm, bool) or not (isinstance(success_spread_mm, (int, float)) and success_spread_mm > 0
                                                       and np.isfinite(success_spread_mm)):
            raise ValueError(f"success_spread_mm must be a finite number > 0, got {success_spread_mm!r}")
        if calibration_seed is not None:
            calibration_seed = _check_int("calibration_seed", calibration_seed, 0)
        self.observation_mode = observation
        self.sensor_model_name = sensor_model
        self.success_spread_mm = float(success_spread_mm)
        self.action_type = action_type
        self.randomize_target = bool(randomize_target)
        self.calibration_seed = calibration_seed
        self.render_mode = render_mode

        if action_type == "continuous":
            self.action_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        else:
            self.action_space = spaces.Discrete(len(DISCRETE_MOVES_MM))
        dim = BELIEF_OBS_DIM if observation == "belief" else RAW_OBS_DIM
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(dim,), dtype=np.float32)

        # Episode state (set by reset).
        self._condition = self._condition_pool[0]
        self._sensor_model = make_sensor_model("analytic", self._condition)
        self._belief: ParticleBelief | None = None
        self._position = np.zeros(2)
        self._target = np.zeros(2)
        self._reading = 0.0
        self._n_obs = 0
        self._path: list[tuple[float, float]] = []
        self._descriptor = condition_descriptor(self._condition)
        self._renderer: Any = None

    # ---- documented read-only accessors ------------------------------------------------------
    @property
    def belief(self) -> ParticleBelief:
        """The particle belief over the target position (world frame, mm). Read-only for agents."""
        if self._belief is None:
            raise RuntimeError("call reset() before reading the belief")
        return self._belief

    @property
    def sensor_model(self):
        """The agent's sensor model (``mean_std``, ``log_likelihood``) for the current episode."""
        return self._sensor_model

    @property
    def condition(self) -> Condition:
        """The current episode's condition."""
        return self._condition

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """Carriage centre (x, y), mm (a copy)."""
        return self._position.copy()

    @property
    def allowed_box_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(low, high) corners of the allowed box, mm."""
        h = self._condition.allowed_half_width_mm
        return np.array([-h, -h]), np.array([h, h])

    @property
    def n_observations(self) -> int:
        """Readings fused so far in this episode."""
        return self._n_obs

    @property
    def last_reading_V(self) -> float:
        """The last reading Φ, V."""
        return self._reading

    @property
    def path_mm(self) -> NDArray[np.float64]:
        """Carriage positions visited this episode (k, 2), mm."""
        return np.asarray(self._path, dtype=float).reshape(-1, 2)

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
        low, high = self.allowed_box_mm
        self._belief = ParticleBelief(self.n_particles, low, high, dtype=np.float32)
        self._belief.reset(rng)
        self._path = [tuple(map(float, self._position))]
        self._n_obs = 0
        self._observe()
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), self._get_info()

    def step(self, action) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        if self._belief is None:
            raise RuntimeError("call reset() before step()")
        move = self._action_to_move(action)
        low, high = self.allowed_box_mm
        self._position = np.clip(self._position + move, low, high)
        self._path.append(tuple(map(float, self._position)))
        self._observe()
        success = self._belief.spread() <= self.success_spread_mm
        terminated = bool(success)
        truncated = bool(not success and self._n_obs >= self.max_observations)
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), -1.0, terminated, truncated, self._get_info()

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'.")
            return None
        from electroloc_gym.render import EpisodeRenderer

        if self._renderer is None:
            self._renderer = EpisodeRenderer(self.render_mode)
        return self._renderer.draw(self)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ---- internals ----------------------------------------------------------------------------
    def _action_to_move(self, action) -> NDArray[np.float64]:
        if self.action_type == "discrete":
            a = np.asarray(action)
            if a.size != 1 or not np.issubdtype(a.dtype, np.integer) or not 0 <= int(a) < len(DISCRETE_MOVES_MM):
                raise ValueError(f"action must be an integer in [0, {len(DISCRETE_MOVES_MM) - 1}], got {action!r}")
            return DISCRETE_MOVES_MM[int(a)]
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ValueError(f"action must have shape (2,) (dx, dy in [-1, 1]), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite (dx, dy in [-1, 1]), got {action!r}")
        return np.clip(a, -1.0, 1.0) * MAX_STEP_MM

    def _observe(self) -> None:
        """Take a noisy reading at the carriage and fuse it into the belief (§4.1)."""
        rng = self.np_random
        self._reading = float(noisy_reading(self._condition, self._target - self._position, rng))
        b = self._belief
        offsets = b.particles - self._position.astype(b.dtype)
        b.assimilate(self._sensor_model.log_likelihood(self._reading, offsets), rng)
        self._n_obs += 1

    def _get_obs(self) -> NDArray[np.float32]:
        c = self._condition
        if self.observation_mode == "raw":
            return raw_observation(self._position, np.asarray(self._reading), c.allowed_half_width_mm, c.saturation_V)
        b = self.belief
        return belief_observation(
            self._position, np.asarray(self._reading), b.particles, None, self._n_obs, self.max_observations,
            c.allowed_half_width_mm, c.noise_std_V, c.saturation_V, self.success_spread_mm, self._descriptor,
            mean_cov=(b.mean(), b.covariance()))

    def _get_info(self) -> dict[str, Any]:
        b = self.belief
        est = b.mean()
        spread = b.spread()
        return {
            "position_mm": (float(self._position[0]), float(self._position[1])),
            "estimate_mm": (float(est[0]), float(est[1])),
            "error_mm": float(np.hypot(*(est - self._target))),
            "spread_mm": float(spread),
            "reading_V": float(self._reading),
            "n_observations": int(self._n_obs),
            "success": bool(spread <= self.success_spread_mm),
            "condition": self._condition.name,
        }
