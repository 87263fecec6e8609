"""The markdown-table helper: its exact format on fixed examples, and one ValueError per bad input."""

from __future__ import annotations

import pytest

from electroloc_gym.utils.markdown import markdown_table


def test_the_format_on_a_fixed_example() -> None:
    assert markdown_table(("a", "b"), [(1, "x"), ("", 2.5)]) == ["| a | b |", "|---|---|", "| 1 | x |", "|  | 2.5 |"]


def test_the_alignment_letters() -> None:
    lines = markdown_table(("name", "n", "mid"), [("min-var", 35, "·")], align="lrc")
    assert lines == ["| name | n | mid |", "|---|---:|:---:|", "| min-var | 35 | · |"]
    assert markdown_table(("a", "b"), [], align="ll") == markdown_table(("a", "b"), []) == ["| a | b |", "|---|---|"]


def test_cells_are_str_and_rows_may_be_any_iterable() -> None:
    lines = markdown_table(["x"], iter([[None], [True], ["a | b"]]))
    assert lines[2:] == ["| None |", "| True |", "| a | b |"]


@pytest.mark.parametrize(
    ("header", "rows", "align", "names"),
    [
        (("a", "b"), [(1,)], None, "rows[0]"),
        (("a", "b"), [(1, 2), (1, 2, 3)], None, "rows[1]"),
        (("a", "b"), [], "l", "align"),
        (("a", "b"), [], "lrr", "align"),
        (("a", "b"), [], "lx", "align"),
        (("a", "b"), [], "LR", "align"),
        ((), [], None, "header"),
    ],
)
def test_bad_input_raises_one_value_error_naming_the_argument(
    header: tuple, rows: list, align: str | None, names: str
) -> None:
    with pytest.raises(ValueError, match=r"^" + names.replace("[", r"\[")):
        markdown_table(header, rows, align)
