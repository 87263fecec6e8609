"""mkdocs hook: links from the docs pages to files of the repository outside ``docs/``.

The pages are read on GitHub as well as on the site, so they link to ``../examples/x.py`` or
``../README.md`` as paths in the checkout. mkdocs can only resolve links inside ``docs/``; this hook
rewrites each such link before mkdocs sees it: ``../README.md`` becomes the site's start page and any
other file becomes its repository path in code (``examples/x.py``). A target that does not exist is an
error, so a broken link still fails ``mkdocs build --strict``. mkdocs has no setting for links out of the
docs folder, hence the hook.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.exceptions import PluginError

ROOT = Path(__file__).resolve().parents[1]
_OUTSIDE = re.compile(r"(!?)\[((?:[^\]\[]|\[[^\]]*\])*)\]\((\.\./[^)\s#]+)(#[^)\s]*)?\)")


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ANN001, D103 (mkdocs' hook signature)
    src = Path(config["docs_dir"]) / page.file.src_path

    def rewrite(m: re.Match[str]) -> str:
        image, text, target, anchor = m.group(1), m.group(2), m.group(3), m.group(4) or ""
        dest = (src.parent / target).resolve()
        if not dest.exists():
            raise PluginError(f"{page.file.src_path}: link to {target}: no such file")
        rel = dest.relative_to(ROOT).as_posix()
        if rel == "README.md":
            return f"[{text}](index.md{anchor})"
        return f"{text} (`{rel}`)" if not image else f"*{text}* (figure: `{rel}`)"

    return _OUTSIDE.sub(rewrite, markdown)
