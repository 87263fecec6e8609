"""Every relative link and image in README.md and docs/*.md resolves: the file exists, the #anchor is a heading."""

from __future__ import annotations

import re
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

_FENCE = re.compile(r"^(```|~~~).*?^\1", re.S | re.M)
_INLINE_CODE = re.compile(r"`[^`\n]*`")
_LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_HTML_REF = re.compile(r"<(?:img|a)\b[^>]*?\b(?:src|href)=\"([^\"]+)\"", re.I)
_HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$", re.M)


def _strip_code(text: str) -> str:
    return _INLINE_CODE.sub("", _FENCE.sub("", text))


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"<[^>]+>", "", heading)  # inline HTML
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links keep their text
    text = text.replace("`", "").lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading anchor of a markdown page (duplicates get -1, -2, … as on GitHub)."""
    seen: dict[str, int] = {}
    out: set[str] = set()
    for h in _HEADING.findall(_FENCE.sub("", page.read_text(encoding="utf-8"))):
        slug = github_slug(h)
        n = seen.get(slug, 0)
        out.add(slug if n == 0 else f"{slug}-{n}")
        seen[slug] = n + 1
    return out


def relative_links(page: Path) -> list[str]:
    """Link and image targets of ``page`` outside code, without external URLs."""
    text = _strip_code(page.read_text(encoding="utf-8"))
    targets = _LINK.findall(text) + _HTML_REF.findall(text)
    return [t for t in targets if not re.match(r"^[a-z][a-z0-9+.-]*:", t, re.I)]


def test_there_are_pages_to_check() -> None:
    assert (ROOT / "README.md").exists()
    assert len(PAGES) >= 2


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_relative_links_resolve(page: Path) -> None:
    broken = []
    for target in relative_links(page):
        path_part, _, anchor = target.partition("#")
        dest = (page.parent / unquote(path_part)).resolve() if path_part else page
        if not dest.exists():
            broken.append(f"{target} (no file {dest.relative_to(ROOT) if dest.is_relative_to(ROOT) else dest})")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{target} (no heading #{anchor} in {dest.name})")
    assert not broken, f"{page.relative_to(ROOT)}: broken links: {broken}"


def test_slugs_follow_github() -> None:
    assert github_slug("Where the simulation differs from the paper") == "where-the-simulation-differs-from-the-paper"
    assert github_slug("`trials.jsonl` schema") == "trialsjsonl-schema"
    assert github_slug("√trace Σ (spread)") == "trace-σ-spread"
    assert github_slug("ElectroLoc-v0") == "electroloc-v0"


def test_link_extraction_skips_code_and_urls(tmp_path) -> None:
    page = tmp_path / "p.md"
    page.write_text(
        "[a](x.md) ![i](img.png) [u](https://e.org) `[c](no.md)`\n```\n[d](no2.md)\n```\n"
        '<img src="pic.gif" width="300">\n',
        encoding="utf-8",
    )
    assert relative_links(page) == ["x.md", "img.png", "pic.gif"]


def test_tests_named_in_the_docs_exist() -> None:
    """`test_x.py::test_name`, `experiments/x/test_y.py::test_name` (or `::test_name`, of the last file named) in
    docs/*.md is a real test.
    """
    missing = []
    for page in PAGES:
        current = None
        pattern = r"`(?:((?:[\w.]+/)*test_\w+\.py)(?:::(\w+))?|::(test_\w+))`"
        for m in re.finditer(pattern, page.read_text(encoding="utf-8")):
            current = m.group(1) or current
            name = m.group(2) or m.group(3)
            # a bare file name is under tests/; a path (experiments/track/test_speed_sweep.py) is the checkout's
            path = (ROOT / current if "/" in current else ROOT / "tests" / current) if current else None
            if path is None or not path.exists():
                missing.append(f"{page.name}: {current}")
            elif name and not re.search(rf"^(?:async )?def {name}\(", path.read_text(encoding="utf-8"), re.M):
                missing.append(f"{page.name}: {current}::{name}")
    assert not missing, missing
