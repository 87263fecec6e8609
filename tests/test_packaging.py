"""Packaging: the package tree on disk is the installed tree (no remapped folder); nothing else is a top-level name."""

from __future__ import annotations

import importlib.metadata
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python ≥ 3.11

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
ENV = {**os.environ, "OMP_NUM_THREADS": "1"}


def _packages_on_disk() -> set[str]:
    """Every folder holding Python modules, as a dotted package name (with or without ``__init__.py``)."""
    found = set()
    root = ROOT / "electroloc_gym"
    for module in root.rglob("*.py"):
        if "__pycache__" not in module.parts:
            found.add(".".join(("electroloc_gym", *module.parent.relative_to(root).parts)))
    return found


def test_every_package_is_listed_in_pyproject() -> None:
    setuptools = PYPROJECT["tool"]["setuptools"]
    assert "package-dir" not in setuptools, "the tree on disk is the import tree: no package-dir remap"
    assert not (ROOT / ".pyright-paths").exists()
    listed = set(setuptools["packages"])
    missing = _packages_on_disk() - listed
    assert not missing, f"add {sorted(missing)} to [tool.setuptools] packages in pyproject.toml"
    assert all(p == "electroloc_gym" or p.startswith("electroloc_gym.") for p in listed)
    assert not listed - _packages_on_disk(), "pyproject.toml lists a package that is not on disk"


def test_namespaced_imports_and_no_top_level_names(tmp_path) -> None:
    code = (
        "import importlib.util as u, electroloc_gym.baselines, electroloc_gym.train, electroloc_gym.models as m\n"
        "assert u.find_spec('baselines') is None and u.find_spec('train') is None\n"
        "assert (m.MODELS_DIR / 'ppo-belief').is_dir()\n"
        "print(electroloc_gym.baselines.make_agent('rnd-wlk').name)"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=ENV, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "rnd-wlk"


def test_python_m_electroloc_gym_train_works() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "electroloc_gym.train", "--help"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=ENV,
        timeout=120,
    )
    if proc.returncode != 0 and "No module named" in proc.stderr and "torch" in proc.stderr:
        pytest.skip("the training extra is not installed")
    assert proc.returncode == 0, proc.stderr
    assert "--algo" in proc.stdout


def _minimums(requirements: list[str]) -> dict[str, str]:
    out = {}
    for req in requirements:
        m = re.match(r"^([A-Za-z0-9_.-]+)(?:\[[^\]]*\])?\s*>=\s*([0-9][0-9.]*)", req)
        if m:
            out[m.group(1).lower().replace("_", "-")] = m.group(2)
    return out


def test_lowest_constraints_pin_every_declared_minimum() -> None:
    """constraints-lowest.txt holds each minimum of the core, train and dev requirements, and nothing older."""
    project = PYPROJECT["project"]
    extras = project["optional-dependencies"]
    declared = _minimums([*project["dependencies"], *extras["train"], *extras["dev"]])
    pins = {}
    for line in (ROOT / "constraints-lowest.txt").read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, version = line.partition("==")
            pins[name.strip().lower()] = version.strip()
    for name, minimum in declared.items():
        assert name in pins, f"constraints-lowest.txt: pin {name}=={minimum}"
        if name == "torch":  # the one CPU-only wheel at hand (constraints-lowest.txt says why)
            continue
        assert [int(x) for x in pins[name].split(".")] == [int(x) for x in minimum.split(".")] + [0] * (
            pins[name].count(".") - minimum.count(".")
        ), f"{name}: pinned {pins[name]}, declared >={minimum}"


def test_every_extra_is_explained() -> None:
    """Each extra has a comment in pyproject.toml saying what it is for, and the README names it."""
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for extra in PYPROJECT["project"]["optional-dependencies"]:
        assert re.search(rf"^# {extra}: ", text, re.M), f"pyproject.toml: say what the {extra} extra is for"
        assert f"`{extra}`" in readme, f"README.md: name the {extra} extra"


def test_version_is_declared_once() -> None:
    import electroloc_gym

    assert electroloc_gym.__version__ == importlib.metadata.version("electroloc-gym") == PYPROJECT["project"]["version"]
    init = (ROOT / "electroloc_gym" / "__init__.py").read_text(encoding="utf-8")
    assert PYPROJECT["project"]["version"] not in init


_CACHE_PROBE = (
    "import sys, os\n"
    "if sys.argv[1] == 'numba-first':\n    import numba\n"
    "import electroloc_gym, numba.core.config as c\n"
    "print(c.CACHE_DIR, os.environ['NUMBA_CACHE_DIR'])"
)


@pytest.mark.parametrize("order", ["package-first", "numba-first"])
def test_numba_caches_per_user(tmp_path, order) -> None:
    env = {k: v for k, v in ENV.items() if k != "NUMBA_CACHE_DIR"} | {"XDG_CACHE_HOME": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-c", _CACHE_PROBE, order], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    want = str(tmp_path / "electroloc-gym" / "numba" / importlib.metadata.version("numba"))
    assert proc.stdout.split() == [want, want]


def test_numba_cache_folder_is_per_numba_version(monkeypatch, tmp_path) -> None:
    from electroloc_gym.utils import runtime

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    versions = {"numba": "0.60.0"}

    def version(name: str) -> str:
        if name not in versions:
            raise importlib.metadata.PackageNotFoundError(name)
        return versions[name]

    monkeypatch.setattr(runtime.importlib.metadata, "version", version)
    older = runtime.user_numba_cache_dir()
    versions["numba"] = "0.68.1"
    assert (older, runtime.user_numba_cache_dir()) == (
        tmp_path / "electroloc-gym" / "numba" / "0.60.0",
        tmp_path / "electroloc-gym" / "numba" / "0.68.1",
    )
    versions.clear()  # numba without its metadata
    assert runtime.user_numba_cache_dir() == tmp_path / "electroloc-gym" / "numba" / "unversioned"


def test_numba_cache_set_by_the_user_is_kept(tmp_path) -> None:
    env = ENV | {"NUMBA_CACHE_DIR": str(tmp_path / "mine")}
    proc = subprocess.run(
        [sys.executable, "-c", _CACHE_PROBE, "package-first"],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == [str(tmp_path / "mine")] * 2


def test_every_module_name_is_used_once() -> None:
    """A traceback or a search names one file: no two modules of the package share a file name."""
    seen: dict[str, list[str]] = {}
    for module in (ROOT / "electroloc_gym").rglob("*.py"):
        if "__pycache__" not in module.parts and module.stem not in ("__init__", "__main__"):
            seen.setdefault(module.name, []).append(str(module.relative_to(ROOT)))
    twice = {name: paths for name, paths in seen.items() if len(paths) > 1}
    assert not twice, f"module names used more than once: {twice}"
