"""The native vector envs: the simulation core with N envs behind Gymnasium's ``VectorEnv``.

``gym.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point")`` builds the entry's native vector
env (its ``vector_entry_point`` in :mod:`electroloc_gym.registry`: a :class:`CoreVectorEnv` of its family,
:mod:`.generic`): one
:class:`~electroloc_gym.engines.numba_core.step.Simulation` of N envs, whose every step is one batched core step —
the same code, with the same per-env arithmetic, as the single env (:mod:`.adapter`, N = 1). Sub-env
``i`` reset with seed ``t`` (the i-th of ``reset(seed=[...])``, or ``t = sub_env_seeds(s, N)[i]`` for
``reset(seed=s)``) therefore produces exactly what the single env reset with ``t`` produces: observations,
rewards, terminations, truncations and infos, across autoresets (docs/design.md).

Seeds: an int ``s`` is spread over the sub-envs with :class:`numpy.random.SeedSequence` (child ``i`` of
``SeedSequence(s)``, :func:`sub_env_seeds`), not as ``s + i``: vector envs seeded ``s`` and ``s + 1`` —
RLlib seeds env runner k with ``seed + k`` — then share no sub-env (with ``s + i``, sub-env ``i`` of the
second would repeat sub-env ``i + 1`` of the first).

Autoreset: ``metadata["autoreset_mode"]`` is :attr:`gymnasium.vector.AutoresetMode.NEXT_STEP` by
default, like Gymnasium's built-in vector envs; ``autoreset_mode="same_step"`` resets an ending
sub-env within its last step and returns the final observation and info in ``info["final_obs"]`` (an
(N, obs_dim) float32 array, zero rows for the sub-envs that did not end) / ``info["final_info"]`` (masks
``info["_final_obs"]`` / ``info["_final_info"]``) — what the SB3 adapter
(``electroloc_gym.train.native_vec``) uses. ``reset(options={"reset_mask": mask})`` resets only the
masked sub-envs (after a first full reset; the options are checked as :mod:`electroloc_gym.contract.reset` says).

Info: a dict of arrays over the N envs (Gymnasium's vector convention), each key with an all-true
``"_key"`` mask: ``position_mm`` (N, 2), ``estimate_mm`` (N, 2), ``error_mm``, ``spread_mm``,
``reading_V`` (N,) float64, ``n_observations`` (N,) int64, ``success`` (N,) bool, ``condition_index`` (N,)
int64 (:func:`~electroloc_gym.contract.observation.condition_index`: the index in ``PRESET_NAMES``, −1 for another
world), then the task's own keys. Every entry is a numeric array — the single env's keys, as Gymnasium's
``SyncVectorEnv`` and ``AsyncVectorEnv`` stack them —, so Gymnasium's array wrappers (``NumpyToTorch``,
``ArrayConversion``) convert it in every vectorization mode. A name is an index: ``metadata["info_names"]``
maps ``condition_index`` and the task's coded keys (the unknown target's ``material_index``) to their names;
the condition of any world, a preset or not, is :attr:`CoreVectorEnv.condition_names`. Rendering is not
supported (``render_mode`` must be None): render a single env.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from electroloc_gym.contract.observation import info_names
from electroloc_gym.contract.params import EnvParams
from electroloc_gym.contract.reset import VECTOR_RESET_OPTIONS, check_first_reset, check_reset_options, reset_mask_error
from electroloc_gym.engines.numba_core.step import Simulation
from electroloc_gym.envs.actions import ActionParser, spaces_of
from electroloc_gym.envs.adapter import ParamAccessors
from electroloc_gym.envs.sim_backends import make_backend_vector_env
from electroloc_gym.registry import EnvEntry, entry_of_class, env_class_named
from electroloc_gym.utils.checks import check_int, check_seeds
from electroloc_gym.world.conditions import Condition

__all__ = [
    "CoreVectorEnv",
    "sub_env_seeds",
]

_AUTORESET_MODES: dict[Any, AutoresetMode] = {
    AutoresetMode.NEXT_STEP: AutoresetMode.NEXT_STEP,
    AutoresetMode.SAME_STEP: AutoresetMode.SAME_STEP,
    "next_step": AutoresetMode.NEXT_STEP,
    "same_step": AutoresetMode.SAME_STEP,
    AutoresetMode.NEXT_STEP.value: AutoresetMode.NEXT_STEP,
    AutoresetMode.SAME_STEP.value: AutoresetMode.SAME_STEP,
}
#: The core's name of each mode.
_CORE_MODE = {AutoresetMode.NEXT_STEP: "next_step", AutoresetMode.SAME_STEP: "same_step"}


def _autoreset_mode(value: object) -> AutoresetMode | None:
    """The mode of an ``autoreset_mode`` argument (None: not a mode; unhashable values included)."""
    return _AUTORESET_MODES.get(value if isinstance(value, (str, AutoresetMode)) else None)


def _reset_mask(value: object, n: int) -> NDArray[np.bool_]:
    """``options["reset_mask"]``: a bool array (n,) with a True entry, or a ValueError."""
    what = reset_mask_error(n)
    if not isinstance(value, np.ndarray):
        raise ValueError(what)
    mask = cast("NDArray[Any]", value)  # an ndarray (isinstance above); its dtype and shape are checked next
    if not (mask.dtype == np.bool_ and mask.shape == (n,) and mask.any()):
        raise ValueError(what)
    return mask


def sub_env_seeds(seed: int, num_envs: int) -> list[int]:
    """The seed of each sub-env of a vector env reset with the int ``seed``: the 128-bit state of child
    ``i`` of ``numpy.random.SeedSequence(seed)`` (depends on ``seed`` and ``i`` only, not on ``num_envs``).

    Raises:
        ValueError: ``seed`` not an int ≥ 0 or ``num_envs`` not an int ≥ 1 (names the argument).
    """
    root = np.random.SeedSequence(check_int("seed", seed, 0))
    children: list[np.random.SeedSequence] = root.spawn(check_int("num_envs", num_envs, 1))  # pyright: ignore[reportUnknownMemberType, reportUnknownVariableType]  # numpy types spawn with typing.Self, absent from Python 3.10
    return [int.from_bytes(child.generate_state(4, np.uint32).tobytes(), "little") for child in children]


class CoreVectorEnv(ParamAccessors, VectorEnv[NDArray[np.float32], Any, NDArray[Any]]):
    """N envs of the simulation core (see the module docstring); subclasses set the task.

    Args:
        num_envs: N (≥ 1).
        render_mode: must be None.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` / ``SAME_STEP`` or their values.
        backend: ``"numba"`` (this class) or another the entry declares (its ``backends``: ``"torch"``, the torch
            core on ``device``, :mod:`electroloc_gym.envs.torch_vector`).
        **kwargs: the single env's arguments (:class:`~electroloc_gym.contract.params.EnvParams`).
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    @classmethod
    def entry(cls) -> EnvEntry:
        """The env's entry in the env table (its id, task, arguments, defaults and other backends)."""
        return entry_of_class(cls)

    def __new__(cls, *args: Any, backend: Any = "numba", **kwargs: Any) -> Any:
        """Another ``backend`` of the entry (``"torch"``: the torch core, :mod:`electroloc_gym.engines.torch_core`)
        builds that backend's vector env instead.
        """
        if backend == "numba":
            return super().__new__(cls)
        return make_backend_vector_env(cls.entry(), backend, *args, **kwargs)

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        backend: str = "numba",
        **kwargs: Any,
    ) -> None:
        n = check_int("num_envs", num_envs, 1)
        if render_mode is not None:
            raise ValueError(
                f"render_mode must be None for the native vector env (got {render_mode!r}); render a single env instead"
            )
        mode = _autoreset_mode(autoreset_mode)
        if mode is None:
            raise ValueError(
                f"autoreset_mode must be AutoresetMode.NEXT_STEP or SAME_STEP (or 'next_step', "
                f"'same_step'), got {autoreset_mode!r}"
            )
        entry = self.entry()
        self.params = EnvParams.from_kwargs(entry.task, kwargs, entry.env_id)
        self._sim = Simulation(self.params, n)
        self._actions = ActionParser(self.params, n)
        self._state = self._sim.state
        self.num_envs = n
        self.autoreset_mode = mode
        self._mode = _CORE_MODE[mode]
        self.metadata = {
            "autoreset_mode": mode,
            "render_modes": [],
            "info_names": info_names(self._sim.task.info_names),
        }
        self.render_mode = None
        action_space, observation_space = spaces_of(self.params, self._sim.obs_dim)
        self.single_action_space, self.single_observation_space = action_space, observation_space
        self.action_space = batch_space(action_space, n)
        self.observation_space = batch_space(observation_space, n)

    # ---- parameters and read-only accessors ---------------------------------------------------
    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:  # pyright: ignore[reportIncompatibleMethodOverride]  # VectorEnv says one Generator; its SyncVectorEnv returns a tuple too
        """The sub-envs' generators (created unseeded on first use, as a single env's)."""
        return tuple(self._sim.generator(i) for i in range(self.num_envs))

    @property
    def np_random_seed(self) -> tuple[int | None, ...]:  # pyright: ignore[reportIncompatibleMethodOverride]  # a tuple per sub-env, as in Gymnasium's SyncVectorEnv
        """The seeds the sub-envs' generators were last created from."""
        return tuple(self._state.seeds)

    @property
    def particles_mm(self) -> NDArray[np.float32]:
        """Particles (N, M, 2), mm (a copy); the weights are uniform after every update."""
        return np.copy(np.transpose(self._state.particles_mm, (0, 2, 1)), order="C")

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """True carriage centres (N, 2), mm (a copy)."""
        return np.copy(self._state.position_mm, order="C")

    @property
    def conditions(self) -> tuple[Condition, ...]:
        """Each sub-env's current condition."""
        if not self._state.started:
            raise RuntimeError("call reset() first")
        return tuple(self._sim.task.world_condition(w) for w in self._state.world)

    @property
    def condition_names(self) -> tuple[str, ...]:
        """Each sub-env's current condition name (a preset's is ``metadata["info_names"]["condition_index"]`` at
        the info's ``condition_index``; another world's, index −1, only here).
        """
        if not self._state.started:
            raise RuntimeError("call reset() first")
        return tuple(str(n) for n in self._state.names)

    @property
    def sensor_models(self) -> tuple[Any, ...]:
        """Each sub-env's sensor model of its current episode (calibrated ones built on first use)."""
        if not self._state.started:
            raise RuntimeError("call reset() first")
        return tuple(self._sim.task.sensor_model(self._state, i) for i in range(self.num_envs))

    @property
    def allowed_half_width_mm(self) -> NDArray[np.float64]:
        """Half-width H of each sub-env's allowed box (N,), mm (the box is [−H, H]²)."""
        return np.copy(self._state.half_mm, order="C")

    @property
    def n_observations(self) -> NDArray[np.int64]:
        """Readings fused so far in each sub-env's episode (N,) (a copy)."""
        return np.copy(self._state.n_observations, order="C")

    @property
    def last_reading_V(self) -> NDArray[np.float64]:
        """Each sub-env's last reading Φ (N,), V (a copy)."""
        return np.copy(self._state.reading_V, order="C")

    # ---- gymnasium API ------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Reset all sub-envs (or those in ``options["reset_mask"]``, after a first full reset; ``options`` takes
        :data:`~electroloc_gym.contract.reset.VECTOR_RESET_OPTIONS` only, :mod:`electroloc_gym.contract.reset`);
        an int seed as :func:`sub_env_seeds`.
        """
        n = self.num_envs
        check_seeds(seed, n)  # everything is checked before any sub-env changes
        opts = check_reset_options(options, VECTOR_RESET_OPTIONS)
        mask = _reset_mask(opts["reset_mask"], n) if "reset_mask" in opts else np.ones(n, dtype=bool)
        check_first_reset(self._state.started, not bool(mask.all()))
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (Sequence, np.ndarray)):  # checked: one entry per sub-env
            seeds = [None if s is None else int(s) for s in seed]
        else:  # checked: an integer ≥ 0
            seeds = list(sub_env_seeds(int(seed), n))
        ids = np.flatnonzero(mask)
        reset_ids: list[int] = ids.tolist()
        for i in reset_ids:
            seed_i = seeds[i]
            if seed_i is not None:
                self._sim.seed(i, seed_i)
        self._sim.reset(ids)
        return self._sim.observation(), self._with_masks(self._sim.info())

    def step(
        self, actions: Any
    ) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        if not self._state.started:
            raise RuntimeError("call reset() before step()")
        moves, gains = self._actions(actions)
        obs, rewards, terminated, truncated, info = self._sim.step(moves, self._mode, gains)
        if "done" in info:
            done = info.pop("done")
            final_obs = np.zeros_like(obs)  # numeric, as every info entry: zero rows where the mask is False
            final_obs[done] = np.stack(list(info["final_obs"][done]))
            info["final_obs"] = final_obs
            info["final_info"] = self._with_masks(info["final_info"], done)
            info["_final_obs"], info["_final_info"] = done, done.copy()
        return obs, rewards, terminated, truncated, self._with_masks(info)

    @staticmethod
    def _with_masks(info: dict[str, Any], mask: NDArray[np.bool_] | None = None) -> dict[str, Any]:
        """Gymnasium's ``"_key"`` masks beside the info arrays (all true, or ``mask``)."""
        keys = [k for k in info if not k.startswith(("_", "final_"))]
        n = len(info[keys[0]])
        masks = np.ones((len(keys), n), dtype=bool) if mask is None else np.tile(mask, (len(keys), 1))
        for key, m in zip(keys, masks, strict=True):
            info["_" + key] = m
        return info

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release (no subprocesses, no renderer)."""


def __getattr__(name: str) -> Any:
    """An entry's env class by its name (recorded entry points name this module), else a name that moved out
    (``registry.env_class_named``).
    """
    return env_class_named(__name__, name)
