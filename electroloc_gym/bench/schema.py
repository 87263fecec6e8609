"""The trial record: one dataclass that is the schema of every line of ``trials.jsonl``.

:class:`TrialRecord` declares each field once with its type and range; :func:`~TrialRecord.from_json`
checks a line read back field by field (types, ranges, finiteness, the consistency of the fields
with each other), and :meth:`TrialRecord.problem` checks it against the run it is read into
(:class:`RecordRules`: the run's conditions, agents, trial index range, each agent's observation
cap and success criterion, the env's own keys). The worker (:func:`~electroloc_gym.bench.trials.run_trial`)
builds a record through the same class, so what is written and what is accepted are one declaration.

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
* ``shape`` (the task's own results): exactly the record fields a registered task declares
  (``Task.metrics.record``, :class:`~electroloc_gym.contract.task_spec.RecordField`), each in its range;
  null on an env whose task declares none. Read into a run (:meth:`TrialRecord.problem`), they are the
  run's own task's (:attr:`RecordRules.metrics`).
* A trial of a task without a success criterion (``TaskMetrics.success_criterion`` false, e.g. the moving
  target) ends by the cap, whatever its spread.
* ``start`` is the start the trial's seed draws (checked on resume, :attr:`RecordRules.start_of`).

Keys added to the schema later (:data:`OPTIONAL_RECORD_KEYS`) may be absent from an older record; they
then read as what such a record means (``distractors`` 0, ``far_success`` computed from ``success`` and
``error_mm``), never as ``null``. The count of readings was once written ``observations``
(:data:`OLD_KEY_NAMES`): such a record reads as ``readings``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from types import MappingProxyType
from typing import Any

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
_CONDITION_CHARS = 64
_MATERIALS = ("conductor", "insulator")
Check = Callable[[Any], bool]


def _int(low: int, high: int | None = None) -> Check:
    return lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= low and (high is None or v <= high)


def _num(low: float = -math.inf, high: float = math.inf, none: bool = True) -> Check:
    def ok(v: Any) -> bool:
        if v is None:
            return none
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and low <= v <= high

    return ok


def _text(v: Any) -> bool:
    return isinstance(v, str) and 0 < len(v) <= MAX_TEXT_CHARS


def _agent(v: Any) -> bool:
    if not _text(v):
        return False
    if is_path_like(v):
        return True
    try:
        parse_agent_spec(v)
    except ValueError:
        return False
    return True


def _xy(none: bool) -> Check:
    coord = _num(-POSITION_BOUND_MM, POSITION_BOUND_MM, none=False)
    return lambda v: (none and v is None) or (isinstance(v, list) and len(v) == 2 and all(coord(x) for x in v))


def _gains(v: Any) -> bool:
    return v is None or (
        isinstance(v, list) and 0 < len(v) <= 64 and all(_num(0.0, 1e12, none=False)(g) and g > 0 for g in v)
    )


def _task_metrics() -> list[TaskMetrics]:
    """The metrics of every registered task that declares record fields (the table as it is now)."""
    from electroloc_gym.registry import ENVS

    out: list[TaskMetrics] = []
    for e in ENVS:
        m = e.task_class.metrics
        if m.record and m not in out:
            out.append(m)
    return out


def _shape(v: Any) -> bool:
    return v is None or any(m.accepts_record(v) for m in _task_metrics())


def _shape_what() -> str:
    keys = " or ".join(str(list(m.record_keys)) for m in _task_metrics())
    return f"null or an object with exactly the keys of one task's results ({keys}), each in its range"


def _f(check: Check, what: str | Callable[[], str], optional: bool = False, timing: bool = False) -> Any:
    """A schema field: its check, what the check wants (for messages; a callable: computed when said), whether
    old records may lack it, whether it is a timing (varies run to run).
    """
    return field(metadata={"check": check, "what": what, "optional": optional, "timing": timing})


@dataclass(frozen=True)
class TrialRecord:
    """One trial's result: a line of trials.jsonl (JSON types; positions ``[x, y]`` in mm)."""

    condition: str = _f(lambda v: isinstance(v, str) and 0 < len(v) <= _CONDITION_CHARS, "a condition name")
    agent: str = _f(_agent, "an agent spec")
    agent_label: str = _f(_text, "a non-empty string")
    table_layout: str = _f(lambda v: v in ("table4", "table1"), "'table4' or 'table1'")
    trial: int = _f(_int(0), "an integer ≥ 0")
    seed: int = _f(_int(0, 2**32 - 1), "an integer in [0, 2³²)")
    agent_seed: int = _f(_int(0, 2**32 - 1), "an integer in [0, 2³²)")
    success: bool = _f(lambda v: isinstance(v, bool), "true or false")
    ended_by: str = _f(lambda v: v in ("success", "cap", "agent"), "'success', 'cap' or 'agent'")
    readings: int = _f(_int(1), "an integer ≥ 1")
    error_mm: float | None = _f(_num(0.0, 2 * POSITION_BOUND_MM), "a distance in [0, 2000] mm or null")
    error_x_mm: float | None = _f(_num(-2 * POSITION_BOUND_MM, 2 * POSITION_BOUND_MM), "a number (mm) or null")
    error_y_mm: float | None = _f(_num(-2 * POSITION_BOUND_MM, 2 * POSITION_BOUND_MM), "a number (mm) or null")
    estimate: list[float] | None = _f(_xy(none=True), "[x, y] in ±1000 mm or null")
    target: list[float] = _f(_xy(none=False), "[x, y] in ±1000 mm")
    start: list[float] = _f(_xy(none=False), "[x, y] in ±1000 mm")
    spread_mm: float | None = _f(_num(0.0, 1e6), "a spread ≥ 0 mm or null")
    decisions: int = _f(_int(0), "an integer ≥ 0")
    decision_ms_median: float | None = _f(_num(0.0, _MAX_TIME), "a time ≥ 0 ms or null", timing=True)
    decision_ms_mean: float | None = _f(_num(0.0, _MAX_TIME), "a time ≥ 0 ms or null", timing=True)
    sensor_model: str = _f(_text, "a sensor-model name")
    signal: str = _f(_text, "a signal name")
    max_observations: int = _f(_int(1), "an integer ≥ 1")
    n_particles: int = _f(_int(1), "an integer ≥ 1")
    env_id: str = _f(_text, "an env id")
    wall_s: float | None = _f(_num(0.0, _MAX_TIME), "a time ≥ 0 s or null", timing=True)
    shape: dict[str, Any] | None = _f(_shape, _shape_what, optional=True)
    gain_levels: list[float] | None = _f(_gains, "null or a list of positive gain factors", optional=True)
    sensor_layout: str | None = _f(
        lambda v: v is None or v in LAYOUT_NAMES, f"null or one of {list(LAYOUT_NAMES)}", optional=True
    )
    distractors: int = _f(_int(0, MAX_DISTRACTORS), f"an integer in [0, {MAX_DISTRACTORS}]", optional=True)
    far_success: bool = _f(lambda v: isinstance(v, bool), "true or false", optional=True)

    @classmethod
    def from_json(cls, obj: Any) -> TrialRecord:
        """Check a parsed line field by field and build the record.

        Raises:
            ValueError: the first problem found, naming the field and what it must be.
        """
        if not isinstance(obj, dict):
            raise ValueError(f"not a JSON object ({type(obj).__name__})")
        obj = _current_names(obj)
        unknown = sorted(set(obj) - set(RECORD_KEYS))
        if unknown:
            raise ValueError(f"unknown key(s) {unknown[:5]}")
        missing = [k for k in RECORD_KEYS if k not in obj and k not in OPTIONAL_RECORD_KEYS]
        if missing:
            raise ValueError(f"missing key(s) {missing}")
        for f in fields(cls):
            if f.name not in obj:  # a key added later, absent from an older record: what such a record means
                continue
            value = obj[f.name]
            if not f.metadata["check"](value):
                what = f.metadata["what"]
                raise ValueError(f"{f.name!r} must be {what() if callable(what) else what}, got {_short(value)}")
        values = {k: obj.get(k) for k in RECORD_KEYS}
        if "distractors" not in obj:
            values["distractors"] = 0
        if "far_success" not in obj:
            values["far_success"] = is_far_success(obj["success"], obj["error_mm"])
        rec = cls(**values)
        why = rec._inconsistency()
        if why is not None:
            raise ValueError(why)
        return rec

    def to_json(self) -> dict[str, Any]:
        """The record as the JSON object written to trials.jsonl."""
        return asdict(self)

    def _inconsistency(self) -> str | None:
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
        if self.far_success != is_far_success(self.success, self.error_mm):
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
    if not any(old in obj for old in OLD_KEY_NAMES):
        return obj
    out = dict(obj)
    for old, new in OLD_KEY_NAMES.items():
        if old in out:
            if new in out:
                raise ValueError(f"both {new!r} and its old name {old!r}")
            out[new] = out.pop(old)
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


#: Old key names still read (old → current): the count of readings was written ``observations``, the
#: paper table a record reports to ``layout``.
OLD_KEY_NAMES: Mapping[str, str] = MappingProxyType({"observations": "readings", "layout": "table_layout"})
#: Every key of a trial record, in the order written.
RECORD_KEYS: tuple[str, ...] = tuple(f.name for f in fields(TrialRecord))
#: Keys a record may lack (records written before the key existed read as None).
OPTIONAL_RECORD_KEYS: tuple[str, ...] = tuple(f.name for f in fields(TrialRecord) if f.metadata["optional"])
#: Keys of a trial record that vary run to run (timings); everything else is deterministic.
TIMING_KEYS: tuple[str, ...] = tuple(f.name for f in fields(TrialRecord) if f.metadata["timing"])


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
