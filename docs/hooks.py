"""mkdocs hook: links from the docs pages to files of the repository outside ``docs/``.

The pages are read on GitHub as well as on the site, so they link to ``../examples/x.py`` or
``../README.md`` as paths in the checkout. mkdocs resolves links inside ``docs/`` only; this hook
rewrites the others before mkdocs sees them: ``../README.md`` becomes the site's start page,
``../CHANGELOG.md`` its changelog page, any other file its repository path in code
(``examples/x.py``). A target that does not exist is an error, so a broken link still fails ``mkdocs
build --strict``. The changelog page is the root's ``CHANGELOG.md``, its ``docs/…`` links turned into
links between pages. mkdocs has no setting for links out of the docs folder, hence the hook.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parents[1]
_OUTSIDE = re.compile(r"(!?)\[((?:[^\]\[]|\[[^\]]*\])*)\]\((\.\./[^)\s#]+)(#[^)\s]*)?\)")


#: Files of the repository that are pages of the site.
_PAGES = {"README.md": "index.md", "CHANGELOG.md": "changelog.md"}
_ROOT_DOCS_LINK = re.compile(r"\]\(docs/")


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ANN001, D103 (mkdocs' hook signature)
    docs = Path(config["docs_dir"]).resolve()
    src = docs / page.file.src_path
    if page.file.src_path == "changelog.md":  # the page is the repository's CHANGELOG.md, its docs/ links to pages
        markdown = _ROOT_DOCS_LINK.sub("](", (ROOT / "CHANGELOG.md").read_text(encoding="utf-8"))

    def rewrite(m: re.Match[str]) -> str:
        image, text, target, anchor = m.group(1), m.group(2), m.group(3), m.group(4) or ""
        dest = (src.parent / target).resolve()
        if dest.is_relative_to(docs):
            return m.group(0)  # a page or picture of the site: mkdocs checks it
        if not dest.exists():
            raise PluginError(f"{page.file.src_path}: link to {target}: no such file")
        rel = dest.relative_to(ROOT).as_posix()
        if rel in _PAGES:
            return f"[{text}]({os.path.relpath(docs / _PAGES[rel], src.parent)}{anchor})"
        return f"{text} (`{rel}`)" if not image else f"*{text}* (figure: `{rel}`)"

    return _OUTSIDE.sub(rewrite, markdown)
