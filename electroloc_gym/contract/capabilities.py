"""Which env options each simulation engine implements: the capability table, declared once.

Two engines step the envs: ``"numba"`` (:mod:`electroloc_gym.engines.numba_core`, every env, the reference) and
``"torch"`` (:mod:`electroloc_gym.engines.torch_core`, ElectroLoc-v0 on any ``torch.device``). For each engine and
each env option — every shared field of :class:`~electroloc_gym.contract.params.EnvParams`, every option of
every registered task (its ``Options``, :func:`option_names`) and every argument of the engines' vector-env
constructors (:data:`CONSTRUCTOR_OPTIONS`) — :data:`CAPABILITIES` says one of:

* implemented (:data:`IMPLEMENTED`): every valid value works;
* limited (:class:`Limit`): only some values are implemented; any other is refused at construction
  with one ValueError naming the option, the values the engine takes and why (:func:`check_engine`);
* absent (:class:`Absent`): not an argument of that engine (its constructor refuses it as an unknown
  argument), with the reason.

The torch engine's constructor refuses what it does not implement by reading this table; the docs'
table of the engines' support (docs/design.md, "Two engines") is :func:`capability_table_markdown`;
and ``tests/test_capabilities.py`` fails on an env option (:func:`option_names`) or a constructor argument
with no entry, and builds each engine with each limit's refused example to see the refusal.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from gymnasium.vector import AutoresetMode

from electroloc_gym.contract.params import EnvParams
from electroloc_gym.registry import ENVS
from electroloc_gym.utils.markdown import markdown_table

__all__ = [
    "ENGINES",
    "CONSTRUCTOR_OPTIONS",
    "CAPABILITIES",
    "IMPLEMENTED",
    "Implemented",
    "Limit",
    "Absent",
    "Support",
    "support",
    "check_engine",
    "params_options",
    "option_names",
    "capability_table_markdown",
]

#: The simulation engines (the ``backend`` argument of the native vector envs), the reference first.
ENGINES = ("numba", "torch")

#: The vector-env constructors' own arguments (beside the ``EnvParams`` fields), either engine's.
CONSTRUCTOR_OPTIONS = (
    "num_envs",
    "render_mode",
    "autoreset_mode",
    "backend",
    "device",
    "compile",
    "compile_backend",
    "action_check",
)


@dataclass(frozen=True)
class Implemented:
    """Every valid value of the option works on the engine."""


#: The one :class:`Implemented` entry.
IMPLEMENTED = Implemented()


@dataclass(frozen=True)
class Limit:
    """Only some values of the option are implemented on the engine.

    Attributes:
        allowed: the values it takes, as written in Python (``"None"``, ``"'single'"``).
        reason: why the others are not, a clause after the engine's name ("has no dynamic gain").
        holds: whether a value is implemented: ``holds(value, options)``, ``options`` every option's value
            (:func:`params_options` and the constructor's arguments), for a limit that depends on another.
        refused: a value the engine refuses (with ``refused_with``: the other options that make it so),
            the tests' example.
        refused_with: options given beside ``refused`` for it to be refused.
    """

    allowed: str
    reason: str
    holds: Callable[[Any, Mapping[str, Any]], bool]
    refused: Any
    refused_with: Mapping[str, Any] = dataclasses.field(default_factory=lambda: MappingProxyType({}))


@dataclass(frozen=True)
class Absent:
    """Not an argument of the engine (its constructor refuses it as an unknown argument).

    Attributes:
        reason: why.
    """

    reason: str


Support = Implemented | Limit | Absent


def _is_next_step(value: Any, _: Mapping[str, Any]) -> bool:
    return isinstance(value, (str, AutoresetMode)) and value in (
        AutoresetMode.NEXT_STEP,
        "next_step",
        AutoresetMode.NEXT_STEP.value,
    )


def _no_distractors(value: Any, _: Mapping[str, Any]) -> bool:
    return getattr(value, "count", value) in (0, (0,))


def _no_position_blur(value: Any, options: Mapping[str, Any]) -> bool:
    return options.get("sensor_model") != "calibrated" or value.position_blur_mm == 0


_GLOBAL_ONLY = Absent("ElectroLocGlobal-v0's; the torch engine implements ElectroLoc-v0 only")
_UNKNOWN_ONLY = Absent("ElectroLocUnknownTarget-v0's; the torch engine implements ElectroLoc-v0 only")
_TRACK_ONLY = Absent("ElectroLocTrack-v0's; the torch engine implements ElectroLoc-v0 only")
_CPU_ONLY = Absent("numba's compiled kernels run on the host's CPU")


def _tasks_on(backend: str) -> frozenset[str]:
    """The tasks whose env table entries declare ``backend`` (read when an env is built: the table is filled)."""
    return frozenset(e.task for e in ENVS if backend in e.backends)


#: option → engine → how the engine treats it (module docstring). The order is the docs table's.
CAPABILITIES: Mapping[str, Mapping[str, Support]] = MappingProxyType(
    {
        name: MappingProxyType(engines)
        for name, engines in {
            # ---- the shared EnvParams fields and the tasks' options ------------------------------------------
            "task": {
                "numba": IMPLEMENTED,
                "torch": Limit(
                    "'localize'",
                    "implements ElectroLoc-v0 only",
                    lambda v, _: v in _tasks_on("torch"),
                    "global",
                ),
            },
            "condition": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "signal": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "randomize_target": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "layout": {"numba": IMPLEMENTED, "torch": _GLOBAL_ONLY},
            "position_blur_mm": {"numba": IMPLEMENTED, "torch": _GLOBAL_ONLY},
            "observation": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "sensor_model": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "n_particles": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "max_observations": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "success_spread_mm": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "action_type": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "calibration_seed": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "calibration": {
                "numba": IMPLEMENTED,
                "torch": Limit(
                    "a protocol with position_blur_mm=0",
                    "has no position blur in the calibrated model",
                    _no_position_blur,
                    {"position_blur_mm": 2.0},
                    MappingProxyType({"sensor_model": "calibrated"}),
                ),
            },
            "max_episode_steps": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "target_draw": {"numba": IMPLEMENTED, "torch": _UNKNOWN_ONLY},
            "radius_range_mm": {"numba": IMPLEMENTED, "torch": _UNKNOWN_ONLY},
            "contrast": {"numba": IMPLEMENTED, "torch": _UNKNOWN_ONLY},
            "eev_radii_mm": {"numba": IMPLEMENTED, "torch": _UNKNOWN_ONLY},
            "gain_levels": {
                "numba": IMPLEMENTED,
                "torch": Limit(
                    "None", "has no dynamic gain: one calibration per level", lambda v, _: v is None, (0.5, 1.0)
                ),
            },
            "sensor_layout": {
                "numba": IMPLEMENTED,
                "torch": Limit(
                    "'single'", "simulates the paper's one electrode pair", lambda v, _: v == "single", "line-4"
                ),
            },
            "fixed_carriage": {
                "numba": IMPLEMENTED,
                "torch": Limit("False", "simulates a moving carriage", lambda v, _: v is False, True),
            },
            "distractors": {
                "numba": IMPLEMENTED,
                "torch": Limit("0", "has no distractors", _no_distractors, 2),
            },
            "target_motion": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "target_speed_mm": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "turn_std_rad": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "motion_model": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "motion_step_mm": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "motion_turn_std_rad": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            "motion_speed_mm": {"numba": IMPLEMENTED, "torch": _TRACK_ONLY},
            # ---- the vector envs' constructor arguments ------------------------------------------------
            "num_envs": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "render_mode": {
                "numba": Limit("None", "renders no vector env (render a single env)", lambda v, _: v is None, "human"),
                "torch": Limit("None", "renders no vector env (render a single env)", lambda v, _: v is None, "human"),
            },
            "autoreset_mode": {
                "numba": IMPLEMENTED,
                "torch": Limit(
                    "AutoresetMode.NEXT_STEP",
                    "resets an ended env at the next step only (its SB3 adapter resets in the same step)",
                    _is_next_step,
                    AutoresetMode.SAME_STEP,
                ),
            },
            "backend": {"numba": IMPLEMENTED, "torch": IMPLEMENTED},
            "device": {"numba": _CPU_ONLY, "torch": IMPLEMENTED},
            "compile": {"numba": Absent("numba compiles its kernels ahead, always"), "torch": IMPLEMENTED},
            "compile_backend": {"numba": Absent("numba compiles its kernels ahead, always"), "torch": IMPLEMENTED},
            "action_check": {"numba": Absent("every action is checked on the host"), "torch": IMPLEMENTED},
        }.items()
    }
)


def support(option: str, engine: str) -> Support:
    """How ``engine`` treats ``option`` (KeyError: an option or engine with no entry)."""
    return CAPABILITIES[option][engine]


def check_engine(engine: str, options: Mapping[str, Any]) -> None:
    """Refuse the first option value ``engine`` does not implement (a :class:`Limit` that does not hold),
    with one ValueError naming the option, the values the engine takes and why.

    Args:
        engine: one of :data:`ENGINES`.
        options: the option values to check (:func:`params_options`, the constructor's arguments); an
            option not given is not checked.
    """
    for name, engines in CAPABILITIES.items():
        rule = engines[engine]
        if name in options and isinstance(rule, Limit) and not rule.holds(options[name], options):
            hint = "; backend='numba' implements it" if isinstance(support(name, "numba"), Implemented) else ""
            raise ValueError(
                f"{name}: backend={engine!r} takes only {rule.allowed} (it {rule.reason}), got {options[name]!r}{hint}"
            )


def params_options(params: EnvParams) -> dict[str, Any]:
    """Every option's value, by name (the options :func:`check_engine` reads): the task, the shared fields
    of ``params`` and its task's own options.
    """
    shared = {name: getattr(params, name) for name in ("task", *params.shared_names())}
    return {**shared, **{f.name: getattr(params.options, f.name) for f in dataclasses.fields(params.options)}}


def option_names() -> tuple[str, ...]:
    """Every env option, once: the task, the shared ``EnvParams`` fields, then each registered task's own
    options (its ``Options`` fields, the env table's order).
    """
    names = ["task", *EnvParams.shared_names()]
    for e in ENVS:
        names += [n for n in e.arguments if n not in names]
    return tuple(names)


def _cell(rule: Support) -> str:
    if isinstance(rule, Implemented):
        return "yes"
    if isinstance(rule, Limit):
        return f"only {rule.allowed}: it {rule.reason}"
    return f"not an argument: {rule.reason}"


def capability_table_markdown() -> list[str]:
    """The capability table as markdown lines (docs/design.md's "Two engines" shows exactly these)."""
    rows = [[f"`{name}`", *(_cell(engines[e]) for e in ENGINES)] for name, engines in CAPABILITIES.items()]
    return markdown_table(["option", *ENGINES], rows)
