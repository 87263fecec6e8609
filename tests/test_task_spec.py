"""The declaration types of a task (electroloc_gym/contract/task_spec.py): options checked field by field then as
a whole, their docs rows, and a task's per-env arrays allocated, gathered, copied and reset over their fields."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from electroloc_gym.contract.task_spec import (
    Boolean,
    Choice,
    Integer,
    Numbers,
    Optional,
    Real,
    TaskOptions,
    TaskState,
    option,
    state_array,
)


@dataclasses.dataclass(frozen=True)
class _Options(TaskOptions):
    mode: str = option("a", doc="the mode", check=Choice(("a", "b")))
    speed_mm: float = option(1.0, doc="a speed", check=Real(0.0, 20.0, inclusive=True), unit="mm")
    count: int = option(2, doc="a count", check=Integer(1, 5))
    flag: bool = option(False, doc="a flag", check=Boolean())
    radii_mm: tuple = option((5.0, 20.0), doc="radii", check=Numbers(2, 1.0, 50.0, " mm"), unit="mm")
    step_mm: float | None = option(None, doc="a step", check=Optional(Real(0.0, 20.0, inclusive=True)))

    def check(self) -> None:
        if self.mode == "b" and self.step_mm is not None:
            raise ValueError("step_mm applies only when mode is 'a'")


def test_options_are_checked_and_normalised_field_by_field() -> None:
    o = _Options(speed_mm=np.float32(2.5), count=np.int64(3), flag=np.bool_(True), radii_mm=[2, 3])
    assert (o.speed_mm, o.count, o.flag, o.radii_mm) == (2.5, 3, True, (2.0, 3.0))
    assert type(o.speed_mm) is float and type(o.count) is int and type(o.flag) is bool
    for kw, msg in [
        ({"mode": "c"}, r"^mode must be one of \['a', 'b'\], got 'c'$"),
        ({"speed_mm": 21.0}, r"^speed_mm must be a finite number ≥ 0 and ≤ 20, got 21.0$"),
        ({"count": 0}, r"^count must be an integer in \[1, 5\], got 0$"),
        ({"flag": 1}, r"^flag must be True or False, got 1$"),
        ({"radii_mm": (1.0,)}, r"^radii_mm must be a tuple of 2 numbers in \[1, 50\] mm, got \(1.0,\)$"),
        ({"step_mm": -1.0}, r"^step_mm must be a finite number ≥ 0 and ≤ 20, got -1.0$"),
        ({"mode": "b", "step_mm": 1.0}, r"^step_mm applies only when mode is 'a'$"),
    ]:
        with pytest.raises(ValueError, match=msg):
            _Options(**kw)
    assert _Options(step_mm=None, mode="b").replace(mode="a").mode == "a"
    with pytest.raises(ValueError, match="step_mm applies"):
        _Options(step_mm=1.0).replace(mode="b")
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.mode = "b"  # type: ignore[misc]


def test_options_describe_their_rows() -> None:
    assert _Options.names() == ("mode", "speed_mm", "count", "flag", "radii_mm", "step_mm")
    rows = {r[0]: r for r in _Options.describe()}
    assert rows["speed_mm"] == ("speed_mm", 1.0, "mm", "[0, 20]", "a speed")
    assert rows["mode"][3] == "`'a'`, `'b'`" and rows["count"][3] == "[1, 5]"
    assert rows["step_mm"][3] == "None or [0, 20]"
    assert TaskOptions.names() == () and TaskOptions() == TaskOptions()


@dataclasses.dataclass
class _State(TaskState):
    heading_rad: np.ndarray = state_array(np.float64)
    count: np.ndarray = state_array(np.int64, fill=-1)
    shape: np.ndarray = state_array(np.float32, (2,))


def test_task_arrays_are_allocated_gathered_copied_and_reset_over_their_fields() -> None:
    s = _State.empty(4)
    assert s.heading_rad.shape == (4,) and s.count.dtype == np.int64 and s.shape.shape == (4, 2)
    assert (s.count == -1).all() and s.shape.dtype == np.float32
    s.heading_rad[:] = np.arange(4)
    s.shape[:] = np.arange(8).reshape(4, 2)
    rows = s.take(np.array([3, 1]))
    assert rows.heading_rad.tolist() == [3.0, 1.0] and rows.shape.tolist() == [[6, 7], [2, 3]]
    rows.heading_rad[0] = 99.0  # a copy
    assert s.heading_rad[3] == 3.0
    s.put([0], rows.take([0]))
    assert s.heading_rad[0] == 99.0 and s.shape[0].tolist() == [6, 7]
    s.reset_rows(slice(0, 2))
    assert s.heading_rad[:2].tolist() == [0.0, 0.0] and s.count[:2].tolist() == [-1, -1]
    assert [n for n, _ in s.arrays()] == ["heading_rad", "count", "shape"]
    assert TaskState.empty(3) == TaskState()

    class _Holder:
        task = s

    assert _State.of(_Holder) is s
    with pytest.raises(TypeError, match="not a"):
        TaskState.of(type("H", (), {"task": object()}))
