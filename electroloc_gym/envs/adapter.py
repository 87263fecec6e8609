"""The Gymnasium single-env adapter: the simulation core with N = 1.

:class:`CoreEnv` turns ``gym.Env`` calls into the core's (:class:`~electroloc_gym.engines.numba_core.step.Simulation`
with one env): ``reset`` hands the env's seeded ``np_random`` to the core and resets it; ``step``
converts the action, steps the core with autoreset disabled (stepping after the episode ended,
terminated or truncated, is an error: call reset) and returns row 0 of its arrays as Python
scalars. It adds only what a single env has and a batch has not: the carriage path for plots,
rendering, and the read-only accessors agents use (``belief``, ``sensor_model``, ``condition``,
``position_mm``, ``allowed_box_mm``, ``move_bounds_mm``, ``n_observations``, ``last_reading_V``,
``path_mm``, ``predicted_reading_model``, ``predicted_particles_mm``). Every env of the table
(:mod:`electroloc_gym.registry`) is this class with its entry's task, through its family's subclass
(:mod:`.localize`, :mod:`.self_localize`) and the accessors of its options (:mod:`.generic`).
Actions are parsed and checked here (:mod:`.actions`), before the core sees them.

Info: row 0 of the core's info, numbers as Python scalars and vectors (``position_mm``, ``estimate_mm``, mm) as
numpy arrays: numeric only, so Gymnasium's sync and async vector envs stack it into numeric arrays and its array
wrappers (``NumpyToTorch``, ``ArrayConversion``) convert it. A name is given by its index: ``condition_index``
(:func:`~electroloc_gym.contract.observation.condition_index`: the condition's index in ``PRESET_NAMES``, −1 for
any other world, whose name is :attr:`CoreEnv.condition`'s) and a task's own coded keys (the unknown target's
``material_index``); ``metadata["info_names"]`` maps each such key to its names
(:func:`~electroloc_gym.contract.observation.info_names`).
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.contract.observation import info_names
from electroloc_gym.contract.params import MAX_STEP_MM, EnvParams
from electroloc_gym.contract.reset import SINGLE_RESET_OPTIONS, check_reset_options
from electroloc_gym.engines.numba_core.step import Simulation
from electroloc_gym.envs.actions import ActionParser, spaces_of
from electroloc_gym.registry import EnvEntry, entry_of_class
from electroloc_gym.utils.checks import check_prediction_args
from electroloc_gym.utils.moved_paths import moved_name_error
from electroloc_gym.views.belief import BeliefView
from electroloc_gym.world.conditions import Condition

__all__ = ["CoreEnv", "ParamAccessors", "spaces_of"]


class ParamAccessors:
    """Read-only views of the env's :class:`~electroloc_gym.contract.params.EnvParams` (single and vector env)."""

    params: EnvParams

    @property
    def n_particles(self) -> int:
        """Particles M of the belief."""
        return self.params.n_particles

    @property
    def max_observations(self) -> int:
        """Readings per episode before truncation."""
        return self.params.max_observations

    @property
    def success_spread_mm(self) -> float:
        """Success when √trace Σ ≤ this, mm."""
        return self.params.success_spread_mm

    @property
    def observation_mode(self) -> str:
        """``"belief"`` or ``"raw"``."""
        return self.params.observation

    @property
    def sensor_model_name(self) -> str:
        """``"analytic"`` or ``"calibrated"``."""
        return self.params.sensor_model

    @property
    def action_type(self) -> str:
        """``"continuous"`` or ``"discrete"``."""
        return self.params.action_type

    @property
    def gain_levels(self) -> tuple[float, ...] | None:
        """The dynamic-gain factors of the amplifier gain, or None (every reading at the preset gain)."""
        return self.params.gain_levels

    @property
    def preset_gain_level(self) -> int:
        """The level of the preset amplifier gain (the factor nearest to 1), the one reset reads at (0
        without dynamic gain).
        """
        return self.params.reset_gain_index


class RenderModes(list):
    """The render modes (a list), refusing a non-string mode in a membership test with one ValueError:
    ``gym.make`` tests ``render_mode in metadata["render_modes"]`` before it builds the env, and would
    otherwise fail inside Gymnasium on ``render_mode=1``.
    """

    def __contains__(self, mode: object) -> bool:
        if mode is not None and not isinstance(mode, str):
            raise ValueError(f"render_mode must be one of {list(self)} or None, got {mode!r}")
        return super().__contains__(mode)


class CoreEnv(ParamAccessors, gym.Env[NDArray[np.float32], NDArray[np.float32] | int]):
    """One env of the simulation core (see the module docstring); subclasses set the task."""

    metadata = {"render_modes": RenderModes(["human", "rgb_array"]), "render_fps": 4}

    @classmethod
    def entry(cls) -> EnvEntry:
        """The env's entry in the env table (its id, task, arguments and defaults)."""
        return entry_of_class(cls)

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        modes = self.metadata["render_modes"]
        if render_mode is not None and render_mode not in modes:
            raise ValueError(f"render_mode must be one of {list(modes)} or None, got {render_mode!r}")
        self.render_mode = render_mode
        entry = self.entry()
        self.params = EnvParams.from_kwargs(entry.task, kwargs, entry.env_id)
        self._sim = Simulation(self.params, 1)
        self._state = self._sim.state
        self._task = self._sim.task
        #: The class's metadata and ``info_names``: the names of the info's integer-coded keys.
        self.metadata = {**type(self).metadata, "info_names": info_names(self._task.info_names)}
        self._actions = ActionParser(self.params, 1)
        self.action_space, self.observation_space = spaces_of(self.params, self._sim.obs_dim)
        self._belief = BeliefView(self._state, 0)
        self._path: list[tuple[float, float]] = []
        self._renderer: Any = None

    # ---- read-only accessors ------------------------------------------------------------------
    def _require_reset(self) -> None:
        if not self._state.started:
            raise RuntimeError("call reset() first")

    @property
    def belief(self) -> BeliefView:
        """The particle belief over the hidden position (mm), read-only."""
        self._require_reset()
        return self._belief

    @property
    def sensor_model(self) -> Any:
        """The agent's sensor model (``mean_std``, ``log_likelihood``) of the current episode."""
        self._require_reset()
        return self._task.sensor_model(self._state, 0)

    @property
    def condition(self) -> Condition:
        """The current episode's condition (before the first reset: the first of the pool; the task says what
        it shows, ``Task.episode_condition``).
        """
        return self._task.episode_condition(self._state, 0)

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """The true carriage centre (x, y), mm (a copy)."""
        return self._state.position_mm[0].copy()

    @property
    def allowed_box_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(low, high) corners of the carriage's allowed box, mm."""
        h = self.condition.allowed_half_width_mm
        return np.array([-h, -h]), np.array([h, h])

    @property
    def belief_frame(self) -> str:
        """What the belief's hypotheses are: ``"target"`` (a static target's position) or ``"robot"`` (the
        carriage's own position, moving with it).
        """
        return str(self._task.belief_frame)

    @property
    def truth_mm(self) -> NDArray[np.float64]:
        """What the belief estimates, its true (x, y), mm (a copy): ground truth, for evaluation only."""
        self._require_reset()
        return np.asarray(self._task.truth_mm(self._state, np.array([0]))[0], dtype=np.float64).copy()

    @property
    def hidden_keys(self) -> tuple[str, ...]:
        """The names of :meth:`hidden_state`'s entries (units in the names)."""
        return tuple(self._task.hidden_keys)

    @property
    def hides_sphere(self) -> bool:
        """The sphere's size and material are hidden from agents (the task's declaration; the unknown target)."""
        return bool(self._task.hides_sphere)

    def hidden_state(self) -> NDArray[np.float64]:
        """The episode's hidden state (:attr:`hidden_keys`), float64: ground truth, for evaluation and
        privileged critics (:class:`electroloc_gym.envs.privileged.PrivilegedInfo`), never for agents.
        """
        self._require_reset()
        return self._task.hidden_state(self._state, 0)

    @property
    def n_observations(self) -> int:
        """Readings fused so far in this episode."""
        return int(self._state.n_observations[0])

    @property
    def last_reading_V(self) -> float:
        """The last reading Φ, V (pair 0's with a sensor array)."""
        return float(np.ravel(self._state.reading_V[0])[0])

    @property
    def last_readings_V(self) -> NDArray[np.float64]:
        """The last reading of every sensing pair (K,), V (a copy)."""
        return np.atleast_1d(self._state.reading_V[0]).copy()

    @property
    def path_mm(self) -> NDArray[np.float64]:
        """Carriage positions visited this episode (k, 2), mm."""
        return np.asarray(self._path, dtype=float).reshape(-1, 2)

    # ---- what min-var needs -------------------------------------------------------------------
    def predicted_particles_mm(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> NDArray:
        """The hypotheses after a commanded move: (M, 2) for a (2,) move, (C, M, 2) for (C, 2) moves.

        Args:
            particles_mm: (M, 2) hypotheses in the belief's frame (normally ``belief.particles``), mm.
            moves_mm: (2,) or (C, 2) commanded moves, mm (clipped to ±``MAX_STEP_MM`` like ``step``).
        """
        p, u = self._check_prediction_args(particles_mm, moves_mm)
        return self._task.particles_after_move(self._state, 0, p, u)

    @property
    def gain_index(self) -> int:
        """The gain level of the last reading (0 without dynamic gain)."""
        return int(self._state.gain_index[0])

    def gain_action(self, level: int) -> Any:
        """The action component that selects gain level ``level`` (continuous: its bin's centre)."""
        k = len(self.params.gains)
        if not (isinstance(level, (int, np.integer)) and 0 <= level < k):
            raise ValueError(f"level must be an integer in [0, {k - 1}], got {level!r}")
        return int(level) if self.params.action_type == "discrete" else -1.0 + (2 * int(level) + 1) / k

    def predicted_reading_model(
        self, particles_mm: ArrayLike, moves_mm: ArrayLike, gain_level: int | None = None
    ) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of the reading each hypothesis predicts after a commanded move
        (the env's motion rule applied; the noise-free reading "that particle predicts" of min-var,
        paper Algorithm 1).

        Args:
            particles_mm: (M, 2) hypotheses (normally ``belief.particles``), mm; float32 stays float32.
            moves_mm: (2,) or (C, 2) commanded moves, mm (clipped to ±``MAX_STEP_MM`` like ``step``).

            gain_level: dynamic gain: the level of the reading (default: the last reading's).

        Returns:
            ``(mean_V, std_V)``, each (M,) for a (2,) move and (C, M) for (C, 2) moves.
        """
        p, u = self._check_prediction_args(particles_mm, moves_mm)
        if gain_level is not None:
            self.gain_action(gain_level)  # validates the level
        return self._task.predicted_mean_std(self._state, 0, p, u, gain_level)

    def _check_prediction_args(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        if not self._state.started:
            raise RuntimeError("call reset() before predicting readings")
        return check_prediction_args(particles_mm, moves_mm, self._task.particle_dims, MAX_STEP_MM)

    # ---- gymnasium API ------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start an episode; ``options`` must be None or empty (a single env takes no reset options:
        :mod:`electroloc_gym.contract.reset`), checked before anything changes.
        """
        check_reset_options(options, SINGLE_RESET_OPTIONS)
        super().reset(seed=seed)
        self._sim.set_generator(0, self.np_random)
        self._sim.reset()
        self._path = [tuple(self._state.position_mm[0].tolist())]
        if self.render_mode == "human":
            self.render()
        return self._sim.observation()[0], self._info_row(self._sim.info())

    def step(self, action: Any) -> tuple[NDArray[np.float32], SupportsFloat, bool, bool, dict[str, Any]]:
        if not self._state.started:
            raise RuntimeError("call reset() before step()")
        moves, gains = self._actions(action, single=True)
        obs, reward, terminated, truncated, info = self._sim.step(moves, autoreset="disabled", gains=gains)
        self._path.append(tuple(self._state.position_mm[0].tolist()))
        if self.render_mode == "human":
            self.render()
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), self._info_row(info)

    @staticmethod
    def _info_row(info: dict[str, NDArray]) -> dict[str, Any]:
        """Row 0 of the core's info arrays: numbers as Python scalars, vectors (positions, mm) as numpy arrays —
        numeric only, as Gymnasium's vector envs stack and its array wrappers convert (names are indices into
        ``metadata["info_names"]``).
        """
        return {k: v[0].item() if isinstance(v[0], np.generic) else v[0].copy() for k, v in info.items()}

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'.")
            return None
        if self._renderer is None:
            self._renderer = self._make_renderer(self.render_mode)
        return self._renderer.draw(self)

    def _make_renderer(self, render_mode: str) -> Any:
        """The renderer of ``render_mode`` ("human" or "rgb_array"), built on the first ``render()``."""
        raise NotImplementedError

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def __getattr__(name: str) -> Any:
    """A name that moved out of this module: one ImportError naming its new place (``utils.moved_paths``)."""
    raise moved_name_error(__name__, name)
