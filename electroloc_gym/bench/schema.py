"""The trial record: one msgspec ``Struct`` that is the schema of every line of ``trials.jsonl``.

:class:`TrialRecord` declares each field once with its type and range (``msgspec.Meta``): msgspec's decode
(:meth:`TrialRecord.from_line`, :meth:`TrialRecord.from_json`) refuses what a type can say in one line naming
the field (``Expected `int` >= 1 - at `$.readings```), and ``__post_init__`` checks what none can (below).
:meth:`TrialRecord.problem` checks a record against the run it is read into (:class:`RecordRules`). The
worker (:func:`~electroloc_gym.bench.trials.run_trial`) builds its records through the same class. Why
msgspec: docs/design.md, "The files the project reads".

Consistency, for every record:

* Table-4 layout (the belief decides): ``ended_by == "success"`` ⇔ the env terminated: ``success``
  is true and ``spread_mm`` ≤ the success criterion; ``"cap"``: ``success`` is false,
  ``readings`` is the cap and ``spread_mm`` is above the criterion. An agent that ends trials
  itself (``"agent"``, and every Table-1 trial): ``success`` ⇔ it ended the trial with an estimate.
* ``readings`` ≤ ``max_observations`` (the run's cap; Table-1 trials: the agent's own budget), and
  ``decisions`` = ``readings − 1`` when the env
  ended the trial (the first reading comes with the reset), ``readings`` when the agent did (its last
  decision ends the trial).
* ``error_mm`` = ‖estimate − target‖ and ``error_x_mm``/``error_y_mm`` its components; no estimate,
  no error.
* ``far_success`` ⇔ a success whose estimate is more than :data:`FAR_ERROR_MM` from the target
  (:func:`is_far_success`; a tight belief on the wrong object, e.g. a distractor).
* ``agent`` is an agent spec or a policy path; ``shape`` (the task's own results) is exactly the record
  fields a registered task declares (``Task.metrics.record``,
  :class:`~electroloc_gym.contract.task_spec.RecordField`), each in its range; null on an env whose task
  declares none. Read into a run (:meth:`TrialRecord.problem`), they are the run's own task's
  (:attr:`RecordRules.metrics`).
* A trial of a task without a success criterion (``TaskMetrics.success_criterion`` false, e.g. the moving
  target) ends by the cap, whatever its spread.
* ``start`` is the start the trial's seed draws (checked on resume, :attr:`RecordRules.start_of`).

An older record may lack the keys added later (:data:`OPTIONAL_RECORD_KEYS`: their defaults, ``far_success``
computed) or hold old key names (:data:`OLD_KEY_NAMES`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Annotated, Any, Literal

import msgspec
from msgspec import UNSET, Meta, Struct, UnsetType

from electroloc_gym.contract.task_spec import TaskMetrics
from electroloc_gym.protocol import FAR_ERROR_MM
from electroloc_gym.utils.agentspec import is_path_like, parse_agent_spec
from electroloc_gym.world.distractors import MAX_DISTRACTORS
from electroloc_gym.world.sensor_array import LAYOUT_NAMES

__all__ = [
    "TrialRecord",
    "FAR_ERROR_MM",
    "is_far_success",
    "RecordRules",
    "RECORD_KEYS",
    "OPTIONAL_RECORD_KEYS",
    "TIMING_KEYS",
    "OLD_KEY_NAMES",
    "POSITION_BOUND_MM",
    "MAX_TEXT_CHARS",
]


def is_far_success(success: bool, error_mm: float | None) -> bool:
    """A success whose estimate is more than :data:`FAR_ERROR_MM` from the target (the one definition)."""
    return bool(success and error_mm is not None and error_mm > FAR_ERROR_MM)


#: Largest |coordinate| of a position in a record, mm (the tank is well under a metre across).
POSITION_BOUND_MM = 1000.0
#: Longest string field (agent spec, label), characters.
MAX_TEXT_CHARS = 2000
#: Largest per-decision or per-trial time accepted, ms / s (a day).
_MAX_TIME = 86_400e3
#: Largest count or index (a signed 64-bit integer).
_MAX_INT = 2**63 - 1
_P = POSITION_BOUND_MM

Text = Annotated[str, Meta(min_length=1, max_length=MAX_TEXT_CHARS)]
Seed = Annotated[int, Meta(ge=0, le=2**32 - 1)]
Index = Annotated[int, Meta(ge=0, le=_MAX_INT)]
Count = Annotated[int, Meta(ge=1, le=_MAX_INT)]
Coord = Annotated[float, Meta(ge=-_P, le=_P)]
XY = Annotated[list[Coord], Meta(min_length=2, max_length=2)]  # [x, y] mm
Offset = Annotated[float, Meta(ge=-2 * _P, le=2 * _P)]
Duration = Annotated[float, Meta(ge=0.0, le=_MAX_TIME)]
Gain = Annotated[float, Meta(gt=0.0, le=1e12)]


def _task_metrics() -> list[TaskMetrics]:
    """The metrics of every registered task that declares record fields (the table as it is now)."""
    from electroloc_gym.registry import ENVS

    out: list[TaskMetrics] = []
    for e in ENVS:
        m = e.task_class.metrics
        if m.record and m not in out:
            out.append(m)
    return out


def _agent_problem(spec: str) -> str | None:
    if is_path_like(spec):
        return None
    try:
        parse_agent_spec(spec)
    except ValueError as exc:
        return f"'agent' must be an agent spec: {exc}"
    return None


def _shape_problem(shape: dict[str, Any] | None) -> str | None:
    if shape is None or any(m.accepts_record(shape) for m in _task_metrics()):
        return None
    keys = " or ".join(str(list(m.record_keys)) for m in _task_metrics())
    return f"'shape' must be null or an object with exactly the keys of one task's results ({keys}), each in its range"


class TrialRecord(Struct, frozen=True, forbid_unknown_fields=True):
    """One trial's result: a line of trials.jsonl (JSON types; positions ``[x, y]`` in mm)."""

    condition: Annotated[str, Meta(min_length=1, max_length=64)]
    agent: Text
    agent_label: Text
    table_layout: Literal["table4", "table1"]
    trial: Index
    seed: Seed
    agent_seed: Seed
    success: bool
    ended_by: Literal["success", "cap", "agent"]
    readings: Count
    error_mm: Annotated[float, Meta(ge=0.0, le=2 * _P)] | None
    error_x_mm: Offset | None
    error_y_mm: Offset | None
    estimate: XY | None
    target: XY
    start: XY
    spread_mm: Annotated[float, Meta(ge=0.0, le=1e6)] | None
    decisions: Index
    decision_ms_median: Duration | None  # a timing
    decision_ms_mean: Duration | None  # a timing
    sensor_model: Text
    signal: Text
    max_observations: Count
    n_particles: Count
    env_id: Text
    wall_s: Duration | None  # a timing
    # keys added later: an older record may lack them
    shape: dict[str, Any] | None = None
    gain_levels: Annotated[list[Gain], Meta(min_length=1, max_length=64)] | None = None
    sensor_layout: Text | None = None  # one of LAYOUT_NAMES (checked with the fields' consistency)
    distractors: Annotated[int, Meta(ge=0, le=MAX_DISTRACTORS)] = 0
    far_success: bool | UnsetType = UNSET  # absent: computed from success and error_mm

    def __post_init__(self) -> None:
        why = self._inconsistency()
        if why is not None:
            raise ValueError(why)

    @classmethod
    def from_line(cls, line: bytes | str) -> TrialRecord:
        """Decode one JSON line into a record (old key names read as the current ones).

        Raises:
            ValueError: not JSON, a wrong type, a value out of range, a missing or unknown key, nested too
                deep, fields that contradict each other — one line naming the field.
        """
        try:
            rec = _DECODER.decode(line)
        except msgspec.ValidationError as exc:
            raw = _raw(line)
            if isinstance(raw, dict) and any(old in raw for old in OLD_KEY_NAMES):
                return cls.from_json(raw)
            raise ValueError(str(exc)) from None
        except msgspec.DecodeError as exc:
            raise ValueError(f"not JSON ({exc})") from None
        except RecursionError:
            raise ValueError("nested too deep") from None
        return rec._completed()

    @classmethod
    def from_json(cls, obj: Any) -> TrialRecord:
        """Check a parsed object (old key names read as the current ones) and build the record.

        Raises:
            ValueError: what :meth:`from_line` refuses — one line naming the field.
        """
        if isinstance(obj, dict):
            obj = _current_names(obj)
        try:
            return msgspec.convert(obj, cls)._completed()
        except msgspec.ValidationError as exc:
            raise ValueError(str(exc)) from None

    def _completed(self) -> TrialRecord:
        if self.far_success is UNSET:  # a record written before the key: what such a record means
            return msgspec.structs.replace(self, far_success=is_far_success(self.success, self.error_mm))
        return self

    def to_json(self) -> dict[str, Any]:
        """The record as the JSON object written to trials.jsonl."""
        return msgspec.structs.asdict(self._completed())

    def _inconsistency(self) -> str | None:
        """What no field's type says: the fields against each other, the agent spec, the task's results."""
        why = _agent_problem(self.agent) or _shape_problem(self.shape)
        if why is not None:
            return why
        if self.sensor_layout is not None and self.sensor_layout not in LAYOUT_NAMES:
            return f"'sensor_layout' must be null or one of {list(LAYOUT_NAMES)}, got {self.sensor_layout!r}"
        if self.estimate is None:
            if (self.error_mm, self.error_x_mm, self.error_y_mm) != (None, None, None):
                return "an error without an estimate"
        else:
            dx, dy = self.estimate[0] - self.target[0], self.estimate[1] - self.target[1]
            for name, got, want in (
                ("error_x_mm", self.error_x_mm, dx),
                ("error_y_mm", self.error_y_mm, dy),
                ("error_mm", self.error_mm, math.hypot(dx, dy)),
            ):
                if got is None or not math.isclose(got, want, rel_tol=1e-9, abs_tol=1e-9):
                    return f"{name!r} is {got!r}, but estimate − target gives {want!r}"
        if self.far_success is not UNSET and self.far_success != is_far_success(self.success, self.error_mm):
            return (
                f"'far_success' {self.far_success} contradicts 'success' {self.success} and 'error_mm' "
                f"{self.error_mm} (far: a success more than {FAR_ERROR_MM} mm off)"
            )
        if self.table_layout == "table4" and self.readings > self.max_observations:  # Table 1: the agent's own budget
            return f"'readings' {self.readings} exceeds the record's cap 'max_observations' {self.max_observations}"
        if self.ended_by == "agent":
            if self.decisions != self.readings:
                return f"'decisions' {self.decisions} ≠ 'readings' {self.readings} (the agent ended the trial)"
        elif self.decisions != self.readings - 1:
            return f"'decisions' {self.decisions} ≠ 'readings' − 1 = {self.readings - 1} (the env ended the trial)"
        if self.ended_by == "agent" or self.table_layout == "table1":  # the agent's own estimate decides
            if self.success != (self.ended_by == "agent" and self.estimate is not None):
                return "'success' must be true exactly when an agent that ended the trial reported an estimate"
            return None
        if self.success != (self.ended_by == "success"):
            return f"'success' {self.success} contradicts 'ended_by' {self.ended_by!r}"
        if self.estimate is None or self.spread_mm is None:
            return "a trial the env ended has the belief's estimate and spread"
        return None

    def problem(self, rules: RecordRules) -> str | None:
        """Why this record cannot belong to the run ``rules`` describes (None: it can)."""
        if self.condition not in rules.conditions:
            return f"condition {self.condition!r} is not one of the run's {sorted(rules.conditions)}"
        if self.agent not in rules.agents:
            return f"agent {self.agent!r} is not one of the run's {sorted(rules.agents)}"
        if self.table_layout != rules.table_layouts.get(self.agent, self.table_layout):
            return (
                f"table_layout {self.table_layout!r}, but agent {self.agent!r} reports to "
                f"{rules.table_layouts[self.agent]!r}"
            )
        if self.trial >= rules.trials:
            return f"trial {self.trial} is outside the run's range 0–{rules.trials - 1}"
        cap = rules.caps.get(self.agent, self.max_observations)
        if self.readings > cap:
            return f"'readings' {self.readings} exceeds the cap of {cap}"
        if self.ended_by == "cap" and self.readings != cap:
            return f"ended by the cap of {cap} after {self.readings} readings"
        criterion_free = not rules.metrics.success_criterion
        if criterion_free and self.ended_by != "cap":  # no success criterion: every trial runs to the cap
            return f"a trial of a task without a success criterion runs to the cap, got 'ended_by' {self.ended_by!r}"
        if self.ended_by != "agent" and self.table_layout == "table4" and not criterion_free:
            criterion = rules.criteria.get(self.agent, rules.success_spread_mm)
            assert self.spread_mm is not None  # checked by from_json
            if (self.spread_mm <= criterion) != self.success:
                return f"'success' {self.success} but 'spread_mm' {self.spread_mm} vs the criterion {criterion} mm"
        keys = rules.metrics.record_keys
        if (self.shape is not None) != bool(keys) or (keys and not rules.metrics.accepts_record(self.shape)):
            return "'shape' must be " + (
                f"the task's results, exactly the keys {list(keys)}"
                if keys
                else "null (the run's task declares no results of its own)"
            )
        if rules.start_of is not None:
            want = rules.start_of(self.condition, self.agent, self.seed)
            if want is not None and not all(
                math.isclose(a, b, rel_tol=0.0, abs_tol=1e-6) for a, b in zip(self.start, want)
            ):
                return (
                    f"'start' {self.start} is not the start {[round(w, 6) for w in want]} mm the trial's "
                    f"seed {self.seed} draws"
                )
        return None


def _current_names(obj: dict[str, Any]) -> dict[str, Any]:
    """``obj`` with every old key name (:data:`OLD_KEY_NAMES`) read as the current one.

    Raises:
        ValueError: a record holding both a key and its old name.
    """
    out = dict(obj)
    for old, new in OLD_KEY_NAMES.items():
        if old in out:
            if new in out:
                raise ValueError(f"both {new!r} and its old name {old!r}")
            out[new] = out.pop(old)
    return out


#: Old key names still read (old → current): the count of readings was written ``observations``, the
#: paper table a record reports to ``layout``.
OLD_KEY_NAMES: Mapping[str, str] = MappingProxyType({"observations": "readings", "layout": "table_layout"})
#: Every key of a trial record, in the order written.
RECORD_KEYS: tuple[str, ...] = TrialRecord.__struct_fields__
#: Keys a record may lack (records written before the key existed read as what such a record means).
OPTIONAL_RECORD_KEYS: tuple[str, ...] = RECORD_KEYS[RECORD_KEYS.index("shape") :]
#: Keys of a trial record that vary run to run (timings); everything else is deterministic.
TIMING_KEYS: tuple[str, ...] = ("decision_ms_median", "decision_ms_mean", "wall_s")
_DECODER = msgspec.json.Decoder(TrialRecord)


def _raw(line: bytes | str) -> Any:
    try:
        return msgspec.json.decode(line)
    except (msgspec.DecodeError, RecursionError):
        return None


def _localisation_metrics() -> TaskMetrics:
    from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS

    return LOCALIZATION_METRICS


@dataclass(frozen=True)
class RecordRules:
    """What a record of one run may hold (built by the runner from its config and the stored run).

    Attributes:
        conditions: the run's conditions (and those of the stored run it continues).
        agents: the run's agent specs (and those of the stored run).
        trials: trial indices run from 0 to ``trials − 1``.
        success_spread_mm: the env's success criterion, mm.
        metrics: the run's task's metrics (its record fields: what ``shape`` holds; whether it has a success
            criterion); default: the paper's localisation metrics (``shape`` null).
        caps: each agent's observation cap (default: the record's ``max_observations``).
        criteria: each agent's success criterion, where it sets its own (default: ``success_spread_mm``).
        table_layouts: each agent's table layout (``"table4"`` or ``"table1"``), where known.
        start_of: (condition, agent, env seed) → the start (x, y) mm that trial's seed draws (None: the
            start is not checked; the callable may return None for a trial it cannot replay).
    """

    conditions: frozenset[str]
    agents: frozenset[str]
    trials: int
    success_spread_mm: float
    metrics: TaskMetrics = field(default_factory=_localisation_metrics)
    caps: Mapping[str, int] = field(default_factory=dict)
    criteria: Mapping[str, float] = field(default_factory=dict)
    table_layouts: Mapping[str, str] = field(default_factory=dict)
    start_of: Callable[[str, str, int], tuple[float, float] | None] | None = None
