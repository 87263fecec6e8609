"""A training run's ``summary.json``: one msgspec schema, written by the training callback and read back.

:class:`TrainSummary` is the file: the callback (:class:`~electroloc_gym.train.callbacks.BenchEvalCallback`)
writes it beside ``eval.csv`` after every validation and at the end, the export copies it beside the policy,
and :func:`read_summary` is its one reader (the export, the finder of a finished run, the curves' title, the
learned suite). A file that is not one is refused in one line naming the file and the field.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated, Any

import msgspec
from msgspec import Meta, Struct

from electroloc_gym.utils.fileio import write_json_atomic

__all__ = ["TrainSummary", "Validation", "read_summary", "write_summary"]

Seconds = Annotated[float, Meta(ge=0.0)]


class Validation(Struct, forbid_unknown_fields=True):
    """The validation episodes that choose the checkpoint: how many, the first reset seed, the env's kwargs."""

    episodes: Annotated[int, Meta(ge=1)]
    first_seed: Annotated[int, Meta(ge=0)]
    env_kwargs: dict[str, Any]


class TrainSummary(Struct, forbid_unknown_fields=True):
    """What a training run did: the env, the algorithm, the command, its time and the checkpoint it chose."""

    env_id: str
    algo: str
    seed: int | None
    command: str  # the exact command, shell-quoted
    argv: list[str]  # rl-zoo3's arguments (without the interpreter)
    finished: bool
    timesteps: Annotated[int, Meta(ge=0)]  # env steps so far
    wall_time_s: Seconds
    evaluation_time_s: Seconds  # of it, validation
    fps_with_evaluation: Annotated[float, Meta(ge=0.0)] | None
    fps_training_only: Annotated[float, Meta(ge=0.0)] | None
    validation: Validation
    chosen_by: str  # the checkpoint rule, in words
    best: dict[str, Any] | None  # the chosen evaluation's row of eval.csv
    evaluations: Annotated[int, Meta(ge=0)]


def read_summary(path: str | os.PathLike[str]) -> TrainSummary:
    """The ``summary.json`` at ``path``.

    Raises:
        ValueError: missing, not JSON, or not a training summary — one line naming the file and the field.
    """
    p = Path(path)
    try:
        return msgspec.json.decode(p.read_bytes(), type=TrainSummary)
    except OSError as exc:
        raise ValueError(f"{p}: not readable ({exc.strerror or exc})") from None
    except (msgspec.MsgspecError, RecursionError) as exc:
        raise ValueError(f"{p}: not a training summary ({exc})") from None


def write_summary(path: str | os.PathLike[str], summary: TrainSummary) -> None:
    """Write ``summary`` to ``path`` atomically (the JSON of :func:`~electroloc_gym.utils.fileio.write_json_atomic`)."""
    write_json_atomic(path, msgspec.to_builtins(summary))
