"""The environments of electroloc-gym, declared once: ids, classes, arguments, defaults and benchmark settings.

:data:`ENVS` is the one table that the rest of the package reads:

* ``electroloc_gym/__init__.py`` registers every entry's id with Gymnasium (``entry_point``,
  ``vector_entry_point``);
* the simulation core builds an entry's task from ``task_class`` (:func:`task_entry`) and validates its
  arguments against ``arguments`` and ``sensor_models`` (:mod:`electroloc_gym.core.params`);
* ``electroloc bench`` takes its ``--env`` names, default particle counts, sensor models and default
  agents from the entries' :class:`BenchEnv` rows (:mod:`electroloc_gym.bench.config`).

Adding an environment is one :class:`EnvEntry` here plus its task module (docs/design.md, "How to add
an environment"). This module is data: it imports only the sensor models' names, so every layer
above them may read it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from electroloc_gym.sensor_models.calibrated import SENSOR_MODEL_NAMES
from electroloc_gym.sensor_models.shape import SHAPE_SENSOR_MODELS

__all__ = ["EnvEntry", "BenchEnv", "ENVS", "ENV_IDS", "TASKS", "BENCH_ENVS", "COMMON_ARGUMENTS", "env_entry",
           "task_entry", "bench_env", "DYNAMIC_GAIN_LEVELS"]

#: The arguments every env takes (the fields of ``EnvParams`` shared by all tasks).
COMMON_ARGUMENTS = ("observation", "sensor_model", "n_particles", "max_observations", "success_spread_mm",
                    "action_type", "calibration_seed", "calibration", "max_episode_steps")
#: A dynamic-gain example (paper §7): a quarter, the preset and four times the preset amplifier gain
#: (``electroloc bench --env dynamic-gain``).
DYNAMIC_GAIN_LEVELS = (0.25, 1.0, 4.0)


def _frozen(d: Mapping[str, Any] | None = None) -> Mapping[str, Any]:
    return MappingProxyType(dict(d or {}))


@dataclass(frozen=True)
class BenchEnv:
    """One ``electroloc bench --env NAME`` choice: an env id with fixed extra arguments.

    Attributes:
        name: the ``--env`` name.
        env_kwargs: arguments the benchmark passes to every trial's env (e.g. ``gain_levels``).
        agents: the default agents' names, or None: every registered controller (then the shipped models
            trained on this env).
        condition: the one "condition" of a single-map env (its trial seeds use condition index 8), or
            None: the paper's eight presets.
    """

    name: str
    env_kwargs: Mapping[str, Any] = field(default_factory=_frozen)
    agents: tuple[str, ...] | None = None
    condition: str | None = None


@dataclass(frozen=True)
class EnvEntry:
    """One registered environment.

    Attributes:
        env_id: the Gymnasium id.
        task: the core's task name (``EnvParams.task``).
        task_class: ``"module:Class"`` of the task (a :class:`electroloc_gym.core.task.Task`).
        entry_point: ``"module:Class"`` of the single env (a ``CoreEnv``).
        vector_entry_point: ``"module:Class"`` of the native vector env (a ``CoreVectorEnv``).
        arguments: the task's own arguments (the env also takes :data:`COMMON_ARGUMENTS`).
        sensor_models: the sensor models the task implements (the first is the env's and the benchmark's
            default).
        defaults: the env's defaults that differ from ``EnvParams``' (the benchmark's too: its particle
            count and sensor model).
        bench: the ``electroloc bench --env`` choices on this env.
        summary: one line for the package docstring and the docs.
    """

    env_id: str
    task: str
    task_class: str
    entry_point: str
    vector_entry_point: str
    arguments: tuple[str, ...]
    sensor_models: tuple[str, ...]
    defaults: Mapping[str, Any] = field(default_factory=_frozen)
    bench: tuple[BenchEnv, ...] = ()
    summary: str = ""

    @property
    def all_arguments(self) -> tuple[str, ...]:
        """Every keyword argument of the env (its own, then the common ones)."""
        return self.arguments + COMMON_ARGUMENTS


ENVS: tuple[EnvEntry, ...] = (
    EnvEntry(
        env_id="ElectroLoc-v0", task="localize",
        task_class="electroloc_gym.core.electroloc:ElectroLocTask",
        entry_point="electroloc_gym.envs.localize:ElectroLocEnv",
        vector_entry_point="electroloc_gym.envs.vector:ElectroLocVectorEnv",
        arguments=("condition", "signal", "randomize_target", "gain_levels", "sensor_layout", "fixed_carriage",
                   "distractors"),
        sensor_models=SENSOR_MODEL_NAMES,
        bench=(BenchEnv("target"), BenchEnv("dynamic-gain", _frozen({"gain_levels": DYNAMIC_GAIN_LEVELS}))),
        summary="localise a target sphere with a particle-filter belief",
    ),
    EnvEntry(
        env_id="ElectroLocGlobal-v0", task="global",
        task_class="electroloc_gym.core.global_task:GlobalTask",
        entry_point="electroloc_gym.envs.global_env:GlobalEnv",
        vector_entry_point="electroloc_gym.envs.vector:GlobalVectorEnv",
        arguments=("layout", "position_blur_mm"),
        sensor_models=SENSOR_MODEL_NAMES,
        bench=(BenchEnv("global", agents=("rnd-wlk", "min-var"), condition="six-cylinders"),),
        summary="the robot localises itself in a mapped tank of six cylinders (§6.5)",
    ),
    EnvEntry(
        env_id="ElectroLocUnknownTarget-v0", task="unknown",
        task_class="electroloc_gym.core.unknown:UnknownTargetTask",
        entry_point="electroloc_gym.envs.unknown_target:UnknownTargetEnv",
        vector_entry_point="electroloc_gym.envs.vector:UnknownTargetVectorEnv",
        arguments=("condition", "signal", "randomize_target", "target_draw", "radius_range_mm", "contrast",
                   "eev_radii_mm", "gain_levels"),
        sensor_models=SHAPE_SENSOR_MODELS,
        # the eight tanks, the theoretical EEV, and 5000 particles for the 4-D belief (with the paper's 2500
        # one success in seven was more than 10 mm off, measured on validation seeds, docs/extensions.md)
        defaults=_frozen({"condition": "random", "n_particles": 5000}),
        bench=(BenchEnv("unknown-target"),),
        summary="localise a sphere of unknown size and material (§7)",
    ),
)

#: The registered ids, in table order.
ENV_IDS: tuple[str, ...] = tuple(e.env_id for e in ENVS)
#: The core's task names, in table order.
TASKS: tuple[str, ...] = tuple(e.task for e in ENVS)
#: ``electroloc bench --env`` names → (entry, bench row).
BENCH_ENVS: Mapping[str, tuple[EnvEntry, BenchEnv]] = MappingProxyType(
    {b.name: (e, b) for e in ENVS for b in e.bench})


def env_entry(env_id: str) -> EnvEntry:
    """The entry of ``env_id`` (a ValueError listing the ids otherwise)."""
    for e in ENVS:
        if e.env_id == env_id:
            return e
    raise ValueError(f"env_id must be one of {list(ENV_IDS)}, got {env_id!r}")


def task_entry(task: str) -> EnvEntry:
    """The entry of the core's task ``task`` (a ValueError listing the tasks otherwise)."""
    for e in ENVS:
        if e.task == task:
            return e
    raise ValueError(f"task must be one of {list(TASKS)}, got {task!r}")


def bench_env(name: str) -> tuple[EnvEntry, BenchEnv]:
    """(entry, bench row) of ``electroloc bench --env NAME`` (a ValueError listing the names otherwise)."""
    if name not in BENCH_ENVS:
        raise ValueError(f"--env must be one of {list(BENCH_ENVS)}, got {name!r}")
    return BENCH_ENVS[name]
