"""The dataset command's settings, declared once: :class:`DatasetRequest` and :data:`DATASET_OPTIONS`.

What a dataset is (:class:`DatasetRequest`'s fields) and how it is built (:data:`BUILD_OPTIONS`,
:func:`~electroloc_gym.dataset.collect.build_dataset`'s keywords) are each an
:class:`~electroloc_gym.options.Option` (docs/design.md): ``electroloc dataset``'s parser is made from them, and
both front ends run their checks (:func:`check_settings`), every refusal one line naming the setting as the front
end spells it. The default id is :func:`dataset_id`'s.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from typing import Any

from electroloc_gym.dataset import store
from electroloc_gym.dataset.seed_protocol import DEFAULT_DATASET_SEED
from electroloc_gym.options import Option, SettingError, int_in, is_bool, one_of, options_of, setting
from electroloc_gym.registry import ENV_IDS, PAPER_ENV_ID, resolve_env_name

__all__ = [
    "DatasetRequest",
    "REQUEST_OPTIONS",
    "BUILD_OPTIONS",
    "DATASET_OPTIONS",
    "check_settings",
    "dataset_id",
    "MAX_EPISODES",
]

#: Most episodes one dataset may plan.
MAX_EPISODES = 1_000_000
_NAME_RE = re.compile(r"[^A-Za-z0-9_-]+")


def dataset_id(env_id: str, agent: str, version: int = 0) -> str:
    """Minari's ``electroloc/<env-id>/<agent>-v<version>``; the agent's display name with anything but ASCII
    letters, digits, ``_`` and ``-`` replaced by ``_`` (``min-var[n_voters=500]`` → ``min-var_n_voters_500``).
    """
    from electroloc_gym.bench.agents import agent_display_name

    name = _NAME_RE.sub("_", agent_display_name(agent.strip())).strip("_-") or "agent"
    return f"electroloc/{env_id}/{name}-v{int(version)}"


def _agent_spec(name: str, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise SettingError(name, "a non-empty agent spec", value)


def _reference(name: str, value: Any) -> None:
    if not isinstance(value, (str, os.PathLike)) or not str(value):
        raise SettingError(name, "None or a benchmark folder or trials.jsonl path", value)


def _condition(name: str, value: Any) -> None:
    from electroloc_gym.world.conditions import PRESET_NAMES

    if value != "random" and value not in PRESET_NAMES:
        raise SettingError(name, f"'random' or one of {list(PRESET_NAMES)}", value)


def _id(name: str, value: Any) -> None:
    store.check_dataset_id(value)


@dataclass(frozen=True)
class DatasetRequest:
    """One dataset's settings, checked on construction (every error one line naming the argument)."""

    env_id: str = setting(
        MISSING,
        default=PAPER_ENV_ID,
        python_default=MISSING,
        flag="--env",
        check=one_of(lambda: ENV_IDS),
        bad=("Nope-v0", "no_such_module_xyz:Nope-v0"),
        help=lambda: (
            f"a registered env id ({', '.join(ENV_IDS)}), or package.module:ENV_ID, an env your own "
            "module registers (a task of your own, electroloc_gym.tasks): imported like any module, it runs your code "
            "(default: %(default)s)"
        ),
    )
    agent: str = setting(
        MISSING, check=_agent_spec, bad=(" ",), help="an agent spec as electroloc bench --agents takes one"
    )
    episodes: int = setting(
        MISSING, kind="int", check=int_in(1, MAX_EPISODES), bad=(0, True), help="episodes to collect (≥ 1)"
    )
    seed: int = setting(
        DEFAULT_DATASET_SEED,
        kind="int",
        check=int_in(1, 2**63 - 1, " (0 is the benchmark's evaluation seed)"),
        bad=(0, -3),
        help="root seed of the episodes (≥ 1; 0 is the benchmark's evaluation seed)",
    )
    reference: str | os.PathLike[str] | None = setting(
        None,
        check=_reference,
        bad=("", 5),
        help="a benchmark folder (or trials.jsonl) with rnd-wlk and a planner on the env: "
        "ref_min_score / ref_max_score "
        "(e.g. experiments/learned/results/<env-id>/_baselines/bench); without it the dataset has no "
        "reference scores (the command says so)",
    )
    version: int | None = setting(
        None,
        kind="int",
        check=int_in(0, 10**6),
        bad=(-1,),
        help="the default id's version N (≥ 0; default 0; not with --id)",
    )
    dataset_id: str | None = setting(
        None,
        flag="--id",
        check=_id,
        bad=("no namespace",),
        help="the dataset id, NAMESPACE/NAME-vN, at most 200 characters "
        "(default electroloc/<env-id>/<agent>-v<version>)",
    )
    condition: str = setting(
        "random",
        check=_condition,
        bad=("mud",),
        help="'random' (a preset per episode) or a preset name",
    )
    trust_pickle: bool = setting(
        False,
        kind="switch",
        check=is_bool,
        bad=("yes",),
        help="let an SB3 .zip policy load (unpickling runs code: only files you trust)",
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "env_id", resolve_env_name(self.env_id, "env_id"))  # MODULE:ENV_ID imports MODULE
        checked = check_settings({f.name: getattr(self, f.name) for f in fields(self)}, lambda o: o.name)
        for key, value in checked.items():  # a numpy integer as the int the metadata records
            object.__setattr__(self, key, value)

    @property
    def id(self) -> str:
        return self.dataset_id or dataset_id(self.env_id, self.agent, self.version or 0)


#: The settings a dataset is (:class:`DatasetRequest`'s fields).
REQUEST_OPTIONS: tuple[Option, ...] = options_of(DatasetRequest)
#: How it is built (:func:`build_dataset`'s keywords).
BUILD_OPTIONS: tuple[Option, ...] = (
    Option(
        "resume",
        default=False,
        kind="switch",
        check=is_bool,
        bad=("yes",),
        help="continue an unfinished dataset of the same settings, or check a complete one (every kept episode "
        "checked; a damaged one set aside in the dataset's quarantine/ folder and collected again)",
    ),
    Option(
        "force",
        default=False,
        kind="switch",
        check=is_bool,
        bad=(1,),
        help="replace the existing dataset of this id, once the new one is complete (a failed or killed run "
        "leaves the old one as it was)",
    ),
    Option(
        "progress",
        default=True,
        python_default=False,
        kind="negated",
        flag="--no-progress",
        check=is_bool,
        bad=("yes",),
        help="no progress bar (from Python: progress=True draws one)",
    ),
)
#: Every setting of ``electroloc dataset`` (and of :class:`DatasetRequest` with :func:`build_dataset`).
DATASET_OPTIONS: tuple[Option, ...] = REQUEST_OPTIONS + BUILD_OPTIONS


def check_settings(values: dict[str, Any], spell: Callable[[Option], str]) -> dict[str, Any]:
    """The dataset settings in ``values`` checked, each refusal one line naming the setting as ``spell`` spells
    it (both front ends; :data:`DATASET_OPTIONS`); returned as the run stores them (:meth:`Option.check_value`).
    """
    name = {opt.name: spell(opt) for opt in DATASET_OPTIONS}
    checked = {
        opt.name: opt.check_value(name[opt.name], values[opt.name]) for opt in DATASET_OPTIONS if opt.name in values
    }
    if values.get("resume") and values.get("force"):
        raise ValueError(f"{name['resume']} and {name['force']} exclude each other")
    if values.get("dataset_id") is not None and values.get("version") is not None:
        raise ValueError(f"{name['version']} sets the default id's version; {name['dataset_id']} carries its own -vN")
    return checked
