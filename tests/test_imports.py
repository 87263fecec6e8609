"""The package's import graph: no cycles, and the layers import only downward (docs/design.md).

Every ``import`` and ``from … import`` of every module of the installed package is read with ``ast`` —
function-level imports included, only those under ``if TYPE_CHECKING:`` left out (they never run) — and
resolved to the package's modules (``from electroloc_gym.x import y`` is an edge to the module
``electroloc_gym.x.y`` if there is one, else to ``electroloc_gym.x``). A package's ``__init__`` running
before its submodules is Python's order, not an edge. The modules are found from pyproject.toml's
package list (the tree on disk is the import tree).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def package_modules() -> dict[str, Path]:
    """Every module of the package (dotted name → file), from pyproject.toml's package list."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    out: dict[str, Path] = {}
    for pkg in cfg["packages"]:
        folder = ROOT / pkg.replace(".", "/")
        for f in sorted(folder.glob("*.py")):
            out[pkg if f.stem == "__init__" else f"{pkg}.{f.stem}"] = f
    return out


def _type_checking_only(tree: ast.AST) -> set[int]:
    """ids of the import nodes under ``if TYPE_CHECKING:``."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            t = node.test
            name = t.id if isinstance(t, ast.Name) else t.attr if isinstance(t, ast.Attribute) else None
            if name == "TYPE_CHECKING":
                skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return skip


def import_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module → the package's modules it imports (anywhere in the file)."""
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        skip = _type_checking_only(tree)
        is_pkg = path.stem == "__init__"
        edges: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from the module's package, up level − 1 more
                    parts = (name if is_pkg else name.rpartition(".")[0]).split(".")
                    parts = parts[: len(parts) - (node.level - 1)]
                    base = ".".join(parts + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            else:
                continue
            for t in targets:
                while t and t not in modules:  # import a.b.c of a package: the deepest module named
                    t = t.rpartition(".")[0]
                if t and t != name:
                    edges.add(t)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan), each a set of modules."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(frozenset(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def describe(comp: frozenset[str], graph: dict[str, set[str]]) -> str:
    """One cycle's modules and the edges inside it."""
    edges = sorted(f"{a} → {b}" for a in comp for b in graph[a] if b in comp)
    return f"{sorted(comp)}: " + "; ".join(edges)


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(package_modules())


def test_the_scan_sees_function_level_and_relative_imports(tmp_path: Path) -> None:
    """The resolver on a fixed example: a function-level import is an edge, TYPE_CHECKING is not."""
    src = (
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from electroloc_gym.envs import adapter\n"
        "def f():\n    from electroloc_gym.engines.numba_core import step\n    import electroloc_gym.registry\n"
        "from . import worlds\n"
    )
    tmp = tmp_path / "_import_scan_example.py"
    tmp.write_text(src, encoding="utf-8")
    mods = {**package_modules(), "electroloc_gym.engines.numba_core.example": tmp}
    edges = import_graph(mods)["electroloc_gym.engines.numba_core.example"]
    assert edges == {
        "electroloc_gym.engines.numba_core.step",
        "electroloc_gym.registry",
        "electroloc_gym.engines.numba_core.worlds",
    }
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [frozenset("abc")]


def test_the_graph_covers_the_package(graph: dict[str, set[str]]) -> None:
    for name in (
        "electroloc_gym.engines.numba_core.step",
        "electroloc_gym.envs.adapter",
        "electroloc_gym.baselines.agent",
        "electroloc_gym.train",
        "electroloc_gym.registry",
    ):
        assert name in graph
    assert "electroloc_gym.engines.numba_core.task" in graph["electroloc_gym.engines.numba_core.step"]


def test_the_core_imports_no_upper_layer(graph: dict[str, set[str]]) -> None:
    """engines/numba_core/ imports nothing from the adapters or anything above them (one-way data flow)."""
    upper = (
        "electroloc_gym.envs",
        "electroloc_gym.baselines",
        "electroloc_gym.bench",
        "electroloc_gym.train",
        "electroloc_gym.cli",
        "electroloc_gym.demo",
        "electroloc_gym.views.render",
        "electroloc_gym.views.eev_maps",
    )
    bad = sorted(
        f"{m} → {t}"
        for m, ts in graph.items()
        if m.startswith("electroloc_gym.engines.numba_core")
        for t in ts
        if t.startswith(upper)
    )
    assert not bad, "the core imports an upper layer: " + "; ".join(bad)


def test_the_torch_engine_imports_nothing_of_the_numba_engine(graph: dict[str, set[str]]) -> None:
    """engines/torch_core/ reads what both engines need from the layers below them (contract/, sensor_models/,
    the env table), never a module of engines/numba_core/: either engine can change without the other."""
    bad = sorted(
        f"{m} → {t}"
        for m, ts in graph.items()
        if m.startswith("electroloc_gym.engines.torch_core")
        for t in ts
        if t.startswith("electroloc_gym.engines.numba_core")
    )
    assert not bad, "the torch engine imports the numba engine: " + "; ".join(bad)


def test_no_import_cycle_anywhere(graph: dict[str, set[str]]) -> None:
    found = cycles(graph)
    assert not found, "import cycles (none may remain):\n" + "\n".join(describe(c, graph) for c in found)


#: The package's layers, bottom to top (docs/design.md's diagram): a module imports only its own layer and
#: those below. Names are relative to ``electroloc_gym``; a package name covers its submodules. Each layer is
#: whole subpackages (the tree on disk shows the layers) but for the root's five modules.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("data", ("protocol", "registry", "options", "utils", "models")),
    ("kernels", ("kernels",)),
    ("world", ("world",)),
    ("sensor models", ("sensor_models",)),
    ("contract", ("contract",)),
    ("engines", ("engines",)),
    ("views", ("views",)),
    ("adapters", ("envs",)),
    ("agents", ("baselines", "policy")),
    ("benchmark", ("bench",)),
    ("tools", ("dataset", "train", "demo")),
    ("entry points", ("cli", "tasks", "")),  # "" is the package's __init__ (registers the table's envs)
)


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of a package module (its longest matching name)."""
    rel = module.removeprefix("electroloc_gym").removeprefix(".")
    best, at = -1, None
    for i, (_, names) in enumerate(LAYERS):
        for n in names:
            if (rel == n or rel.startswith(n + ".")) and len(n) > best:
                best, at = len(n), i
    if at is None:
        raise KeyError(module)
    return at


def test_every_module_has_a_layer(graph: dict[str, set[str]]) -> None:
    missing = []
    for m in graph:
        try:
            layer_of(m)
        except KeyError:
            missing.append(m)
    assert not missing, f"modules in no layer of LAYERS (add them, and to docs/design.md's diagram): {missing}"


def test_the_layers_import_only_downward(graph: dict[str, set[str]]) -> None:
    """The whole order, not only the core's: every edge goes to the same layer or one below."""
    bad = sorted(
        f"{m} ({LAYERS[layer_of(m)][0]}) → {t} ({LAYERS[layer_of(t)][0]})"
        for m, ts in graph.items()
        for t in ts
        if layer_of(t) > layer_of(m)
    )
    assert not bad, "upward imports against the layer order:\n" + "\n".join(bad)


def test_the_check_sees_an_upward_import() -> None:
    assert layer_of("electroloc_gym.engines.numba_core.step") < layer_of("electroloc_gym.envs.adapter")
    assert layer_of("electroloc_gym.sensor_models.map") == layer_of("electroloc_gym.sensor_models")
    assert layer_of("electroloc_gym") == len(LAYERS) - 1
    with pytest.raises(KeyError):
        layer_of("electroloc_gym.nothing_here")


def diagram_paths(block: str) -> set[str]:
    """The module paths (relative to ``electroloc_gym/``) a diagram shows: parenthesised notes are dropped,
    a folder token (``engines/numba_core/``) is the base of the file names after it until the next folder
    or the next layer's line, and a file name with no folder before it is a root module."""
    import re

    text = block
    while re.search(r"\([^()]*\)", text):
        text = re.sub(r"\([^()]*\)", " ", text)
    shown: set[str] = set()
    folder = ""
    for line in text.splitlines():
        if re.match(r"^ [a-z]", line):  # a layer's first line
            folder = ""
        for tok in re.findall(r"[\w/]+/|[\w]+\.py", line):
            if tok.endswith("/"):
                folder = tok
                shown.add(folder)
            else:
                shown.add(folder + tok)
    return shown


def test_the_diagram_reader_resolves_folders() -> None:
    block = " data  protocol.py (see x.py)  utils/ checks.py\n   │  fileio.py\n tools  demo.py train/ run.py\n"
    assert diagram_paths(block) == {
        "protocol.py",
        "utils/",
        "utils/checks.py",
        "utils/fileio.py",
        "demo.py",
        "train/",
        "train/run.py",
    }


def test_the_design_diagram_names_every_module(graph: dict[str, set[str]]) -> None:
    """docs/design.md's architecture diagram shows each module by its path in the package, and each layer's name."""
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    block = text.split("## Architecture", 1)[1].split("```text", 1)[1].split("```", 1)[0]
    shown = diagram_paths(block)
    root = ROOT / "electroloc_gym"
    missing = sorted(
        str(path.relative_to(root)) for path in package_modules().values() if str(path.relative_to(root)) not in shown
    )
    assert not missing, f"modules docs/design.md's diagram does not show (by path): {missing}"
    stale = sorted(p for p in shown if p.endswith(".py") and not (root / p).is_file())
    assert not stale, f"docs/design.md's diagram shows modules that are not in the package: {stale}"
    for name, _ in LAYERS:
        assert name in block, f"layer {name!r} is not named in docs/design.md's diagram"


def test_the_repository_map_names_every_top_level_folder() -> None:
    """docs/design.md's map of the repository ("## The repository") has a row for each top-level folder in git."""
    import subprocess

    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    table = text.split("## The repository", 1)[1].split("\n## ", 1)[0]
    tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    folders = sorted({line.split("/", 1)[0] for line in tracked.splitlines() if "/" in line})
    assert {"electroloc_gym", "tests", "docs"} <= set(folders)
    missing = [f for f in folders if f"| `{f}/` |" not in table]
    assert not missing, f"top-level folders docs/design.md's repository map does not describe: {missing}"


#: First words that open a history note (what a module was, where it came from) instead of its concern.
HISTORY_WORDS = frozenset(
    "formerly previously was were moved renamed now new newly split originally legacy deprecated replaces "
    "replaced since added fixed until old initially historically refactored extracted merged continued "
    "continuation rest part changed".split()
)


def concern_line_problem(docstring: str | None) -> str | None:
    """Why a module docstring's first line does not name the module's concern (None: it does): it must be
    there, be one whole sentence (one final full stop, no second sentence) and not open with a history word.
    """
    import re

    first = (docstring or "").split("\n", 1)[0].strip()
    if not first:
        return "no first line (no module docstring, or it starts with an empty line)"
    if not first.endswith("."):
        return f"the first line is not one whole sentence (it ends {first[-20:]!r}, not with a full stop)"
    second = re.search(r"[.!?]\s+[A-Z]", first[:-1])
    if second:
        return f"the first line holds more than one sentence ({first[max(0, second.start() - 20) : second.end()]!r})"
    word = re.match(r"[A-Za-z]+", first)
    if word and word.group().lower() in HISTORY_WORDS:
        return f"the first line opens with the history word {word.group()!r}"
    return None


def test_every_module_names_its_concern_in_its_first_line() -> None:
    """Each module of the package (electroloc_gym/ and its subpackages) opens its docstring with one
    sentence that names what it holds."""
    bad = []
    for path in package_modules().values():
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")), clean=False)
        why = concern_line_problem(doc)
        if why is not None:
            bad.append(f"{path.relative_to(ROOT)}: {why}")
    assert not bad, "module docstrings whose first line does not name the concern:\n" + "\n".join(bad)


@pytest.mark.parametrize(
    ("docstring", "says"),
    [
        (None, "no first line"),
        ("\nThe sensor array.", "no first line"),
        ("The sensor array: where K pairs sit and what they\nread.", "not one whole sentence"),
        ("The sensor array. It reads K pairs.", "more than one sentence"),
        ("Moved here from sensor_layouts: the layouts.", "history word 'Moved'"),
        ("Formerly the layouts module.", "history word 'Formerly'"),
    ],
)
def test_the_concern_check_refuses_what_names_no_concern(docstring: str | None, says: str) -> None:
    assert says in (concern_line_problem(docstring) or "")
    assert concern_line_problem("The sensor array (paper §7): where K pairs sit (Eq. 4), and what each reads.") is None


# ---- moved import paths: the CHANGELOG's table, the package's table, and what an old import says ----------------
def changelog_moves() -> dict[str, str]:
    """The CHANGELOG's "Moved" table, one old → new path a row: ``a.x, .y`` is ``a.x`` and ``a.y``; ``a (m, n)`` →
    ``b (the same module names)`` is ``a.m → b.m`` and ``a.n → b.n``; the cells' items pair in order."""
    import re

    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    # every release section's "Moved" table (a section ends at the next "### " or "## " heading)
    section = "\n".join(re.split(r"\n##+ ", part, maxsplit=1)[0] for part in text.split("### Moved")[1:])

    def items(cell: str) -> list[tuple[str, list[str] | None]]:
        out: list[tuple[str, list[str] | None]] = []
        for group in re.findall(r"`([^`]*)`", cell):
            listed = re.fullmatch(r"(\S+) \((.*)\)", group)
            if listed:
                out.append((listed.group(1), [s.strip() for s in listed.group(2).split(",")]))
                continue
            first = ""
            for part in (p.strip() for p in group.split(",")):
                first = first.rsplit(".", 1)[0] + part if part.startswith(".") else part
                out.append((first, None))
        return out

    moves: dict[str, str] = {}
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    assert rows, "the CHANGELOG has no Moved table"
    for row in rows:
        old_cell, new_cell = (c.strip() for c in row.strip().strip("|").split("|"))
        olds, news = items(old_cell), items(new_cell)
        assert len(olds) == len(news), f"a row of the Moved table pairs {len(olds)} with {len(news)} paths: {row}"
        for (old, subs), (new, same) in zip(olds, news):
            if subs is None:
                moves[old] = new
            else:
                assert same == ["the same module names"], row
                moves.update({f"{old}.{m}": f"{new}.{m}" for m in subs})
    return moves


def test_the_changelog_and_the_package_list_the_same_moves() -> None:
    from electroloc_gym.utils.moved_paths import MOVED

    assert changelog_moves() == MOVED


@pytest.mark.parametrize("old,new", sorted(changelog_moves().items()))
def test_an_old_path_says_where_it_went(old: str, new: str) -> None:
    """An old module path is a ModuleNotFoundError naming the new one (its package's error, listing where each
    module went, when the package itself is gone); an old name in a module that exists is not there any more:
    an ImportError naming its new place, for ``from module import name`` and for the attribute alike."""
    import importlib

    import electroloc_gym  # noqa: F401 - installs the moved-path finder

    assert importlib.import_module(new.rsplit(".", 1)[0]) is not None  # the new place exists
    parent, _, leaf = old.rpartition(".")
    try:
        module = importlib.import_module(parent)
    except ModuleNotFoundError:  # an old package: its own error is what an import of its module meets
        module = None
    from electroloc_gym.utils.moved_paths import MOVED_IN, MOVES_BY_RELEASE, UNRELEASED

    release = next(r for r, moves in MOVES_BY_RELEASE.items() if old in moves)
    when = f"after electroloc-gym {MOVED_IN} " if release == UNRELEASED else f"in electroloc-gym {release} "
    if module is not None and not hasattr(module, "__path__"):  # a name in a module, not a module
        with pytest.raises(ImportError, match=re.escape(new)) as info:
            exec(f"from {parent} import {leaf}", {})  # noqa: S102 - the import statement itself
        assert when in str(info.value), info.value
        with pytest.raises(ImportError, match=re.escape(new)):
            getattr(module, leaf)
        return
    with pytest.raises(ModuleNotFoundError) as info:
        importlib.import_module(old)
    text = str(info.value)
    new_parent, _, new_leaf = new.rpartition(".")
    assert "\n" not in text and when in text, text
    assert new in text or (new_leaf == leaf and re.search(rf"\b{leaf}\b[^;]* to {re.escape(new_parent)} ", text)), text


def test_a_path_that_never_existed_is_plain_module_not_found() -> None:
    import importlib

    import electroloc_gym  # noqa: F401

    with pytest.raises(ModuleNotFoundError, match=r"^No module named 'electroloc_gym\.nothing_here'$"):
        importlib.import_module("electroloc_gym.nothing_here")
    from electroloc_gym.envs import adapter

    with pytest.raises(AttributeError, match="has no attribute 'nothing_here'"):
        adapter.nothing_here  # noqa: B018
