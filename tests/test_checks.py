"""The argument checks every parameter dataclass and agent option uses (electroloc_gym.utils.checks)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from electroloc_gym.utils.checks import check_bool, check_choice, check_float, check_int
from electroloc_gym.world.apparatus import Target
from electroloc_gym.world.scene import SceneObject


def test_good_values_come_back_as_python_types() -> None:
    assert check_int("n", np.int64(3), 1, 5) == 3 and type(check_int("n", np.int64(3), 1)) is int
    assert check_float("x", np.float32(2.5), 0.0) == 2.5 and type(check_float("x", 1, 0.0)) is float
    assert check_float("x", 0.0, 0.0, inclusive=True) == 0.0
    assert check_float("x", -1e300) == -1e300  # no bound
    assert check_bool("b", np.bool_(True)) is True
    assert check_choice("c", "a", ("a", "b")) == "a"


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: check_int("n", 0, 1, 5), "n must be an integer in [1, 5], got 0"),
        (lambda: check_int("n", True, 0), "n must be an integer ≥ 0, got True"),
        (lambda: check_int("n", 2.0, 0), "n must be an integer ≥ 0, got 2.0"),
        (lambda: check_float("x", 0.0, 0.0), "x must be a finite number > 0, got 0.0"),
        (lambda: check_float("x", 6.0, 0.0, high=5.0), "x must be a finite number > 0 and ≤ 5, got 6.0"),
        (lambda: check_float("x", -1.0, 0.0, inclusive=True), "x must be a finite number ≥ 0, got -1.0"),
        (lambda: check_float("x", math.nan), "x must be a finite number, got nan"),
        (lambda: check_float("x", math.inf, 0.0), "x must be a finite number > 0, got inf"),
        (lambda: check_float("x", "1", 0.0), "x must be a finite number > 0, got '1'"),
        (lambda: check_float("x", False, 0.0, inclusive=True), "x must be a finite number ≥ 0, got False"),
        (lambda: check_bool("b", 1), "b must be True or False, got 1"),
        (lambda: check_choice("c", "z", ("a", "b")), "c must be one of ['a', 'b'], got 'z'"),
    ],
)
def test_bad_values_are_one_line_naming_the_argument(call, message) -> None:
    with pytest.raises(ValueError) as err:
        call()
    assert str(err.value) == message


def test_the_dataclasses_read_the_same_message() -> None:
    with pytest.raises(ValueError, match=r"^radius_mm must be a finite number > 0, got -1$"):
        Target(radius_mm=-1, conductivity_uScm=1.0)
    with pytest.raises(ValueError, match=r"^radius_mm must be a finite number > 0, got -1$"):
        SceneObject("sphere", (0.0, 0.0), -1, 1.0)
