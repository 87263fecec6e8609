"""What the simulation core reports, one row per env: the observation layouts and the info keys.

The "belief" observation (float32, every entry in [−1, 1]) makes the task close to Markov:

=====  =============================================  ==========================================
index  feature                                        normalisation
=====  =============================================  ==========================================
0–1    carriage position (x, y)                       / allowed half-width H (mm)
2      last reading Φ                                  / saturation (10 V)
3      last reading in noise units                     tanh(Φ / (3·G·σ_s))
4–5    belief mean − carriage (x, y)                   / 2H
6–7    belief standard deviation (x, y)                / H, clipped to [0, 1]
8      belief correlation ρ_xy                         as is
9      spread √trace Σ                                 / H, clipped to [0, 1]
10     log₁₀(spread / success spread)                  clipped to [−1, 1]
11     observations used / observation cap             as is
12–75  8×8 egocentric particle histogram               mass fraction per cell; cells span
                                                       offsets ±H around the carriage (x-major)
76–80  condition descriptor                            radius/25 mm, χ, log₁₀(G)/4,
                                                       G·σ_s (V), signal_scale/8 (clipped)
=====  =============================================  ==========================================

Entries 0–11 are declared as data, each entry's quantity, scale, factor and transform, in
:data:`electroloc_gym.contract.belief_summary.BELIEF_SCALARS` (the numbers both engines read).

The "raw" observation is ``[x/H, y/H, Φ/10 V]`` (with dynamic gain a fourth entry, the reading's gain
level in [−1, 1]). Entries 0–1 are what the robot knows of its own position, the task's
:meth:`~electroloc_gym.engines.numba_core.task.Task.reference_mm` (the carriage; the odometry in the mapped tank);
entries 4–5 and the histogram are relative to the belief's frame origin
(:meth:`~electroloc_gym.engines.numba_core.task.Task.belief_origin_mm`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.contract.belief_summary import (
    BELIEF_SCALAR_FACTORS,
    CORRELATION_FLOOR_MM2,
    LOG_SPREAD_FLOOR_MM,
    N_SCALARS,
)
from electroloc_gym.kernels import belief_observation_rows
from electroloc_gym.protocol import HIST_BINS
from electroloc_gym.world.conditions import PRESET_NAMES, Condition

N_DESCRIPTOR = 5
BELIEF_OBS_DIM = N_SCALARS + HIST_BINS * HIST_BINS + N_DESCRIPTOR
RAW_OBS_DIM = 3
OBSERVATION_MODES = ("belief", "raw")
#: The reward of a step that takes a reading (the task: as few readings as possible), and of the step in
#: which an ended env resets (next-step autoreset: the action is ignored).
STEP_REWARD = -1.0
RESET_REWARD = 0.0
#: The info keys of every step and reset, in order (a task adds its own after them, ``Task.info_keys``);
#: ``error_mm``, ``spread_mm`` and ``success`` are :func:`~electroloc_gym.contract.belief_summary.belief_info_values`.
#: Every value is a number or a numeric array (so Gymnasium's vector envs stack it and its array wrappers convert
#: it): a name is given as its index into the env's ``metadata["info_names"]`` (:func:`info_names`).
INFO_KEYS = (
    "position_mm",
    "estimate_mm",
    "error_mm",
    "spread_mm",
    "reading_V",
    "n_observations",
    "success",
    "condition_index",
)

__all__ = [
    "BELIEF_OBS_DIM",
    "RAW_OBS_DIM",
    "OBSERVATION_MODES",
    "INFO_KEYS",
    "info_names",
    "condition_index",
    "HIST_BINS",
    "STEP_REWARD",
    "RESET_REWARD",
    "condition_descriptor",
    "episode_flags",
    "belief_observation",
    "raw_observation",
    "raw_observation_values",
]


def condition_descriptor(condition: Condition) -> NDArray[np.float32]:
    """Five numbers in [−1, 1] that tell the policy which condition it is in."""
    d = np.array(
        [
            condition.target.radius_mm / 25.0,
            condition.chi,
            np.log10(condition.amplifier.gain) / 4.0,
            condition.noise_std_V,
            condition.signal_scale / 8.0,
        ]
    )
    return np.clip(d, -1.0, 1.0).astype(np.float32)


def episode_flags(
    spread_mm: Any,
    n_observations: Any,
    elapsed: Any,
    success_spread_mm: float,
    max_observations: int,
    max_episode_steps: int | None,
) -> tuple[Any, Any]:
    """(terminated, truncated) per env, the rule of both engines: terminated when the belief's spread
    √trace Σ (mm) is at most ``success_spread_mm``; truncated when not terminated and ``n_observations``
    reached ``max_observations``, or (terminated or not) when ``elapsed`` steps reached
    ``max_episode_steps``. Comparisons and boolean operators only, so numpy arrays and torch tensors
    (any device, traced or not) alike.
    """
    terminated = spread_mm <= success_spread_mm
    truncated = ~terminated & (n_observations >= max_observations)
    if max_episode_steps is not None:
        truncated = truncated | (elapsed >= max_episode_steps)
    return terminated, truncated


def raw_observation_values(xp: Any, carriage_mm: Any, reading_V: Any, half_width_mm: Any, saturation_V: Any) -> Any:
    """``clip([x/H, y/H, Φ/V_sat], −1, 1)`` with batch dims (..., 3), in the inputs' precision: the raw
    layout of both engines. ``xp`` is the arrays' namespace — numpy, or torch for the torch engine's
    tensors (only ``stack`` and ``clip``, which both have); the caller casts to float32.
    """
    cols = [carriage_mm[..., 0] / half_width_mm, carriage_mm[..., 1] / half_width_mm, reading_V / saturation_V]
    return xp.clip(xp.stack(cols, -1), -1.0, 1.0)


def raw_observation(
    carriage_mm: NDArray, reading_V: NDArray, half_width_mm: NDArray | float, saturation_V: NDArray | float = 10.0
) -> NDArray[np.float32]:
    """[x/H, y/H, Φ/V_sat] with batch dims (..., 3), float32 (:func:`raw_observation_values`)."""
    hw = np.asarray(half_width_mm, dtype=np.float64)
    values = raw_observation_values(np, np.asarray(carriage_mm), np.asarray(reading_V), hw, np.asarray(saturation_V))
    return values.astype(np.float32)


def belief_observation(
    carriage_mm: NDArray,
    reading_V: NDArray,
    mean_mm: NDArray,
    cov_mm2: NDArray,
    hist: NDArray,
    n_observations: NDArray,
    max_observations: int,
    half_width_mm: NDArray,
    noise_std_V: NDArray,
    saturation_V: NDArray,
    success_spread_mm: float,
    descriptor: NDArray,
) -> NDArray[np.float32]:
    """The belief observations (k, BELIEF_OBS_DIM) of k envs from their beliefs' statistics (layout:
    the module docstring), assembled per env by :func:`electroloc_gym.kernels.belief_observation_rows`
    with the scalar entries' numbers of :data:`~electroloc_gym.contract.belief_summary.BELIEF_SCALARS`.

    Args:
        carriage_mm: (k, 2) the reference point (the carriage; the map origin for self-localisation), mm.
        reading_V: (k,) last readings, V.
        mean_mm: (k, 2) belief means, mm.
        cov_mm2: (k, 2, 2) belief covariances, mm².
        hist: (k, 64) mass fraction of particles per histogram cell (cells span ±H around the reference).
        n_observations: (k,) readings fused so far.
        max_observations: the cap.
        half_width_mm: (k,) allowed half-width H, mm.
        noise_std_V: (k,) G·σ_s, V.
        saturation_V: (k,) clip level, V.
        success_spread_mm: the success threshold on √trace Σ, mm.
        descriptor: (k, 5) float32 from :func:`condition_descriptor`.
    """

    def rows(x: Any, dtype: Any = np.float64) -> NDArray:
        return np.ascontiguousarray(x, dtype=dtype)

    k = len(reading_V)
    out = np.empty((k, BELIEF_OBS_DIM), dtype=np.float32)
    belief_observation_rows(
        rows(carriage_mm),
        rows(reading_V),
        rows(mean_mm),
        rows(cov_mm2),
        rows(n_observations),
        float(max_observations),
        rows(half_width_mm),
        rows(noise_std_V),
        rows(saturation_V),
        float(success_spread_mm),
        rows(hist),
        rows(descriptor, np.float32),
        BELIEF_SCALAR_FACTORS,
        LOG_SPREAD_FLOOR_MM,
        CORRELATION_FLOOR_MM2,
        out,
    )
    return out


_PRESET_INDEX = {name: i for i, name in enumerate(PRESET_NAMES)}


def info_names(task_names: Mapping[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    """An env's ``metadata["info_names"]``: for each integer-coded info key, the name of each code (indexed by
    the code). ``condition_index``: :data:`~electroloc_gym.world.conditions.PRESET_NAMES` (−1, a world that is
    not a preset, has no entry: its name is the env's ``condition.name``, the vector env's ``condition_names``);
    then the task's own (``Task.info_names``, e.g. the unknown target's ``material_index``).
    """
    return {"condition_index": tuple(PRESET_NAMES), **{k: tuple(v) for k, v in task_names.items()}}


def condition_index(names: Any) -> NDArray[np.int64]:
    """``info["condition_index"]`` of worlds named ``names``: each name's index in
    :data:`~electroloc_gym.world.conditions.PRESET_NAMES`, −1 for a world that is not one of the eight presets (a
    custom condition, a map of the global env).
    """
    return np.array([_PRESET_INDEX.get(str(n), -1) for n in np.ravel(np.asarray(names, dtype=object))], np.int64)
