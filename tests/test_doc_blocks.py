"""The docs' snippets: every Python block of the README and docs/ runs, as a reader runs it.

A file's blocks run in order in one namespace (a later block uses what an earlier one defined), in an
empty folder that stands for the reader's own (nothing of the checkout is on the path but the installed
package). The blocks are found by mktestdocs (``grab_code_blocks``, the parser its own ``check_md_file``
uses); its runner is not used because it runs a file's blocks as one string, so a failure would not say
which block failed, and it has no way to mark a block that cannot run here. A block that cannot run in
the tests says so in an HTML comment on the line before its fence, with the reason::

    <!-- not run by the doc tests: it needs Ray (the rllib extra) ... -->

The README's shell blocks are checked too: every character a shell would expand as a pattern (``[``,
``*``, ``?``) is inside quotes, so a command copied into zsh (macOS's shell, which fails on an unmatched
pattern) or bash (which would expand a matching file name) runs as written.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from mktestdocs import grab_code_blocks

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
NOT_RUN = "<!-- not run by the doc tests:"


def doc_blocks(path: Path) -> list[tuple[int, str, str | None]]:
    """(line of the fence, code, the reason it is not run or None) of every Python block of ``path``."""
    text = path.read_text(encoding="utf-8")
    out: list[tuple[int, str, str | None]] = []
    pos = 0
    for code in grab_code_blocks(text, lang="python"):
        # mktestdocs strips the fence and the block's common indentation: find the block's first line
        first = code.strip("\n").splitlines()[0].strip()
        at = text.index(first, pos)
        fence = text.rfind("```python", 0, at)
        before = text[:fence].rstrip("\n").rsplit("\n", 1)[-1].strip()
        reason = before[len(NOT_RUN) :].rstrip("->").strip() if before.startswith(NOT_RUN) else None
        out.append((text.count("\n", 0, fence) + 1, code, reason))
        pos = at + len(first)
    return out


#: Pages whose blocks need an extra (their marker deselects them where it is not installed, as for the tests of
#: that extra): "Train an agent" trains with SB3 and benchmarks its zip through rl-zoo3's loader.
PAGE_MARKS = {"train.md": pytest.mark.zoo}
RUN_PAGES = [
    pytest.param(p, marks=PAGE_MARKS.get(p.name, ()), id=str(p.relative_to(ROOT))) for p in PAGES if doc_blocks(p)
]


def _setup(page: Path, folder: Path) -> None:
    """What a page's reader has made before its blocks, by the page's own earlier commands."""
    if page.name == "benchmark.md":  # `electroloc bench --out results/bench` (the page's first command), tiny
        import sys

        sys.path.insert(0, str(ROOT / "tests"))
        try:
            from tiny_bench_run import run_tiny
        finally:
            sys.path.remove(str(ROOT / "tests"))
        run_tiny(folder / "results" / "bench")


@pytest.mark.parametrize("page", RUN_PAGES)
def test_every_python_block_of_a_page_runs_in_order(page: Path, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    _setup(page, tmp_path)
    namespace: dict = {"__name__": "__main__"}
    ran = 0
    for line, code, reason in doc_blocks(page):
        if reason is not None:
            continue
        try:
            exec(compile(code, f"{page.relative_to(ROOT)}:{line}", "exec"), namespace)
        except Exception as exc:  # noqa: BLE001 - the block's failure, named by file and line
            pytest.fail(f"{page.relative_to(ROOT)}:{line}: the block raised {type(exc).__name__}: {exc}")
        ran += 1
    assert ran, f"{page.relative_to(ROOT)}: every block is marked not run"


def test_the_blocks_marked_not_run_say_why() -> None:
    marked = [(p.name, line, reason) for p in PAGES for line, _, reason in doc_blocks(p) if reason is not None]
    assert all(len(reason) > 20 for _, _, reason in marked), marked
    total = sum(len(doc_blocks(p)) for p in PAGES)
    assert len(marked) <= 3 < total  # a few, each with its reason; the rest run


def _unquoted_patterns(line: str) -> list[str]:
    """The shell pattern characters of ``line`` outside quotes (a comment ends the scan)."""
    found, quote, prev = [], None, ""
    for ch in line:
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and prev in ("", " "):
            break
        elif ch in "[*?":
            found.append(ch)
        prev = ch
    return found


def test_the_readmes_shell_commands_quote_what_a_shell_would_expand() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    bad = [
        line for block in grab_code_blocks(text, lang="bash") for line in block.splitlines() if _unquoted_patterns(line)
    ]
    assert not bad, bad
    assert _unquoted_patterns("electroloc bench --agents min-var,mypkg:make_agent[depth=2]") == ["["]
    assert not _unquoted_patterns("electroloc bench --agents 'min-var,mypkg:make_agent[depth=2]'")


def test_blocks_are_found_with_their_lines_and_markers(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text(
        "text\n\n```python\nx = 1\n```\n\n" + NOT_RUN + " needs a GPU, which the tests do not have -->\n"
        "```python\nraise SystemExit\n```\n\n```bash\nls\n```\n",
        encoding="utf-8",
    )
    assert doc_blocks(page) == [
        (3, "x = 1\n", None),
        (8, "raise SystemExit\n", "needs a GPU, which the tests do not have"),
    ]
