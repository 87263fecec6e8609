"""Machinery shared by ElectroLoc-v0 and ElectroLocGlobal-v0: the hidden state differs, the machinery does not.

Both tasks are the same particle-filter loop (paper §4.1, Algorithm 1): the carriage moves by the
commanded action, takes one noisy reading, and the belief (a :class:`~electroloc_gym.belief.ParticleBelief`)
fuses it with the agent's sensor model; an episode ends when √trace Σ ≤ 10 mm (success) or after 35
readings. What differs is only *what the particles are* and hence how a particle predicts the reading:

=====================  =======================================  ==========================================
env                    hidden state (particles)                 sensor-model offsets of particle i
=====================  =======================================  ==========================================
ElectroLoc-v0          target position (world), static          particle_i − carriage (carriage known)
ElectroLocGlobal-v0    robot's own carriage position (map),     −particle_i (map origin − carriage); the
                       moves with every commanded move          particles are shifted by each move
=====================  =======================================  ==========================================

:class:`ParticleFilterEnv` implements the loop, the action handling, the accessors, the info dict and
:meth:`ParticleFilterEnv.predicted_reading_model` (what min-var needs: the reading each hypothesis
predicts after a move); subclasses supply the hooks ``_reset_episode``, ``_execute_move``,
``_true_reading``, ``_particle_offsets``, ``_offsets_after_move``, ``_true_state_mm``, ``_get_obs`` and
``_make_renderer``.

Per step, the env's ``self.np_random`` draws, in order: reading noise (1 normal), resampling
(1 uniform), jitter (M·2 float32 standard normals); motion is deterministic.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.belief import ParticleBelief
from electroloc_gym.conditions import Condition
from electroloc_gym.envs.observation import BELIEF_OBS_DIM, OBSERVATION_MODES, RAW_OBS_DIM
from electroloc_gym.sensor_models import SENSOR_MODEL_NAMES

__all__ = ["ParticleFilterEnv", "MAX_STEP_MM", "DISCRETE_MOVES_MM", "ACTION_TYPES", "check_int"]

#: Largest move per axis per step, mm (paper §4.1.3).
MAX_STEP_MM = 10.0
#: The discrete action set: stay plus the 8 king moves of 10 mm per axis.
DISCRETE_MOVES_MM = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)], dtype=np.float64) * MAX_STEP_MM
ACTION_TYPES = ("continuous", "discrete")


def check_int(name: str, value: Any, low: int) -> int:
    """``value`` as an int, or a ValueError naming ``name`` and the allowed range."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
    return int(value)


class ParticleFilterEnv(gym.Env[NDArray[np.float32], NDArray[np.float32] | int]):
    """Base class of the electrolocation envs: move, read, fuse (see the module docstring)."""

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 4}

    def _init_common(
        self,
        observation: str,
        sensor_model: str,
        n_particles: int,
        max_observations: int,
        success_spread_mm: float,
        action_type: str,
        calibration_seed: int | None,
        render_mode: str | None,
    ) -> None:
        """Validate the shared arguments and build the action and observation spaces."""
        if observation not in OBSERVATION_MODES:
            raise ValueError(f"observation must be one of {list(OBSERVATION_MODES)}, got {observation!r}")
        if sensor_model not in SENSOR_MODEL_NAMES:
            raise ValueError(f"sensor_model must be one of {list(SENSOR_MODEL_NAMES)}, got {sensor_model!r}")
        if action_type not in ACTION_TYPES:
            raise ValueError(f"action_type must be one of {list(ACTION_TYPES)}, got {action_type!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.n_particles = check_int("n_particles", n_particles, 1)
        self.max_observations = check_int("max_observations", max_observations, 1)
        ok = isinstance(success_spread_mm, (int, float)) and not isinstance(success_spread_mm, bool)
        if not (ok and success_spread_mm > 0 and np.isfinite(success_spread_mm)):
            raise ValueError(f"success_spread_mm must be a finite number > 0, got {success_spread_mm!r}")
        if calibration_seed is not None:
            calibration_seed = check_int("calibration_seed", calibration_seed, 0)
        self.observation_mode = observation
        self.sensor_model_name = sensor_model
        self.success_spread_mm = float(success_spread_mm)
        self.action_type = action_type
        self.calibration_seed = calibration_seed
        self.render_mode = render_mode

        if action_type == "continuous":
            self.action_space: spaces.Space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        else:
            self.action_space = spaces.Discrete(len(DISCRETE_MOVES_MM))
        dim = BELIEF_OBS_DIM if observation == "belief" else RAW_OBS_DIM
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(dim,), dtype=np.float32)

        # Episode state (set by reset).
        self._belief: ParticleBelief | None = None
        self._position = np.zeros(2)
        self._reading = 0.0
        self._n_obs = 0
        self._path: list[tuple[float, float]] = []
        self._renderer: Any = None

    # ---- documented read-only accessors ------------------------------------------------------
    @property
    def belief(self) -> ParticleBelief:
        """The particle belief over the hidden position (mm). Read-only for agents."""
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
    def allowed_box_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(low, high) corners of the allowed box of the carriage, mm."""
        h = self._condition.allowed_half_width_mm
        return np.array([-h, -h]), np.array([h, h])

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lo, hi) per-axis moves, mm, that the robot *knows* keep the carriage in the allowed box.

        Within ±``MAX_STEP_MM``; always contains 0. Agents sample candidate moves from this box
        (min-var's options, paper §4.1.3).
        """
        raise NotImplementedError

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

    # ---- what min-var needs (the same call on every env) ----------------------------------
    def predicted_particles_mm(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> NDArray:
        """The hypotheses after a commanded move: (M, 2) for a (2,) move, (C, M, 2) for (C, 2) moves.

        Args:
            particles_mm: (M, 2) hypotheses in the belief's frame (normally ``belief.particles``), mm.
            moves_mm: (2,) or (C, 2) commanded moves, mm (clipped to ±``MAX_STEP_MM`` like ``step``).
        """
        p, u = self._check_prediction_args(particles_mm, moves_mm)
        return self._particles_after_move(p, u)

    def predicted_reading_model(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of the reading each hypothesis predicts after a commanded move.

        The env's own motion rule is applied (the carriage stays in the allowed box); ``mean_V`` is
        the noise-free reading "that particle predicts" of the paper's min-var (Algorithm 1).

        Args:
            particles_mm: (M, 2) hypotheses in the belief's frame (normally ``belief.particles``), mm;
                float32 stays float32.
            moves_mm: (2,) or (C, 2) commanded moves, mm (clipped to ±``MAX_STEP_MM`` like ``step``).

        Returns:
            ``(mean_V, std_V)``, each (M,) for a (2,) move and (C, M) for (C, 2) moves.
        """
        p, u = self._check_prediction_args(particles_mm, moves_mm)
        return self._sensor_model.mean_std(self._offsets_after_move(p, u))

    def _check_prediction_args(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        if self._belief is None:
            raise RuntimeError("call reset() before predicting readings")
        p = np.asarray(particles_mm)
        if p.dtype not in (np.float32, np.float64):
            p = p.astype(np.float64)
        if p.ndim != 2 or p.shape[-1] != 2:
            raise ValueError(f"particles_mm must have shape (M, 2), got {p.shape}")
        u = np.asarray(moves_mm, dtype=np.float64)
        if u.ndim not in (1, 2) or u.shape[-1] != 2:
            raise ValueError(f"moves_mm must have shape (2,) or (C, 2), got {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("moves_mm must be finite")
        return p, np.clip(u, -MAX_STEP_MM, MAX_STEP_MM)

    # ---- gymnasium API ----------------------------------------------------------------------
    def step(self, action) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        if self._belief is None:
            raise RuntimeError("call reset() before step()")
        move = self._action_to_move(action)
        self._execute_move(move)
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
        if self._renderer is None:
            self._renderer = self._make_renderer()
        return self._renderer.draw(self)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ---- shared internals ---------------------------------------------------------------------
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

    def _start_belief(self, rng: np.random.Generator) -> None:
        """A fresh uniform cloud over the allowed box (float32, the fast path)."""
        low, high = self.allowed_box_mm
        self._belief = ParticleBelief(self.n_particles, low, high, dtype=np.float32)
        self._belief.reset(rng)

    def _begin_episode(self, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """The end of every reset, once the carriage is placed: fresh belief, first reading, (obs, info)."""
        self._start_belief(rng)
        self._path = [tuple(map(float, self._position))]
        self._n_obs = 0
        self._observe()
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), self._get_info()

    def _observe(self) -> None:
        """Take a noisy reading at the carriage and fuse it into the belief (§4.1)."""
        rng = self.np_random
        self._reading = self._true_reading(rng)
        b = self._belief
        b.assimilate(self._sensor_model.log_likelihood(self._reading, self._particle_offsets(b.particles)), rng)
        self._n_obs += 1

    def _get_info(self) -> dict[str, Any]:
        b = self.belief
        est = b.mean()
        spread = b.spread()
        return {
            "position_mm": (float(self._position[0]), float(self._position[1])),
            "estimate_mm": (float(est[0]), float(est[1])),
            "error_mm": float(np.hypot(*(est - self._true_state_mm()))),
            "spread_mm": float(spread),
            "reading_V": float(self._reading),
            "n_observations": int(self._n_obs),
            "success": bool(spread <= self.success_spread_mm),
            "condition": self._condition.name,
        }

    # ---- hooks --------------------------------------------------------------------------------
    def _execute_move(self, move_mm: NDArray[np.float64]) -> None:
        """Apply a commanded move to the true carriage (and, for self-localisation, the belief)."""
        raise NotImplementedError

    def _true_reading(self, rng: np.random.Generator) -> float:
        """One noisy reading at the true carriage position (one normal draw)."""
        raise NotImplementedError

    def _particle_offsets(self, particles: NDArray) -> NDArray:
        """Sensor-model offsets (M, 2) of the current particles at the current carriage."""
        raise NotImplementedError

    def _particles_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        """Hypotheses after commanded moves (…, M, 2) (see :meth:`predicted_particles_mm`)."""
        raise NotImplementedError

    def _offsets_after_move(self, particles: NDArray, moves: NDArray) -> NDArray:
        """Sensor-model offsets (…, M, 2) of the hypotheses after commanded moves."""
        raise NotImplementedError

    def _true_state_mm(self) -> NDArray[np.float64]:
        """The true value of the hidden state the belief estimates (for info["error_mm"])."""
        raise NotImplementedError

    def _get_obs(self) -> NDArray[np.float32]:
        raise NotImplementedError

    def _make_renderer(self) -> Any:
        raise NotImplementedError
