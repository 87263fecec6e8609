"""The one markdown-table helper, which the package, its studies and its benchmarks build their tables with.

The format is the repository's own: ``| a | b |`` cells joined by single spaces and a separator line
without spaces (``|---|---:|``). It is written here rather than taken from a dependency such as
``tabulate``, which pads every column to its widest cell: that would change every committed table and
make each new number a diff of the whole table, and the format is twenty lines.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["markdown_table"]

#: The separator cell of each alignment letter: left (the default), right, centre.
_SEPARATORS = {"l": "---", "r": "---:", "c": ":---:"}


def _line(cells: Sequence[object]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]], align: str | None = None) -> list[str]:
    """A markdown table's lines (without line ends): the header, the separator, then one line per row.

    A cell is written as ``str(cell)``; ``align`` is one letter of ``lrc`` per column (None: every column
    left). A ValueError refuses an empty header, a bad ``align`` or a row of another length than the header.
    """
    n = len(header)
    if n == 0:
        raise ValueError("header must name at least one column")
    align = "l" * n if align is None else align
    if len(align) != n or any(a not in _SEPARATORS for a in align):
        raise ValueError(f"align must be one letter of 'l', 'r', 'c' per column ({n}), got {align!r}")
    out = [_line(header), "|" + "".join(_SEPARATORS[a] + "|" for a in align)]
    for i, row in enumerate(rows):
        if len(row) != n:
            raise ValueError(f"rows[{i}] has {len(row)} cells, the header {n}: {list(row)!r}")
        out.append(_line(row))
    return out
