"""Packaging: baselines/, train/ and models/ install inside electroloc_gym; nothing else is a top-level name."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python ≥ 3.11

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
MAPPED = {"electroloc_gym.baselines": "baselines", "electroloc_gym.train": "train", "electroloc_gym.models": "models"}
ENV = {**os.environ, "OMP_NUM_THREADS": "1"}


def _packages_on_disk() -> set[str]:
    """Every folder holding Python modules, as a dotted package name (with or without ``__init__.py``)."""
    found = set()
    roots = {"electroloc_gym": ROOT / "electroloc_gym", **{name: ROOT / folder for name, folder in MAPPED.items()}}
    for name, root in roots.items():
        for module in root.rglob("*.py"):
            if "__pycache__" not in module.parts:
                found.add(".".join((name, *module.parent.relative_to(root).parts)))
    return found


def test_every_package_is_listed_in_pyproject() -> None:
    setuptools = PYPROJECT["tool"]["setuptools"]
    assert setuptools["package-dir"] == MAPPED
    listed = set(setuptools["packages"])
    missing = _packages_on_disk() - listed
    assert not missing, f"add {sorted(missing)} to [tool.setuptools] packages in pyproject.toml"
    assert all(p == "electroloc_gym" or p.startswith("electroloc_gym.") for p in listed)


def test_namespaced_imports_and_no_top_level_names(tmp_path) -> None:
    code = ("import importlib.util as u, electroloc_gym.baselines, electroloc_gym.train, electroloc_gym.models as m\n"
            "assert u.find_spec('baselines') is None and u.find_spec('train') is None\n"
            "assert (m.MODELS_DIR / 'ppo-belief').is_dir()\n"
            "print(electroloc_gym.baselines.make_agent('rnd-wlk').name)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=ENV,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "rnd-wlk"


def test_python_m_train_works_from_the_repository_root() -> None:
    proc = subprocess.run([sys.executable, "-m", "train", "--help"], capture_output=True, text=True, cwd=ROOT,
                          env=ENV, timeout=120)
    if proc.returncode != 0 and "No module named" in proc.stderr and "torch" in proc.stderr:
        pytest.skip("the training extra is not installed")
    assert proc.returncode == 0, proc.stderr
    assert "--algo" in proc.stdout


def test_wheel_ships_the_namespaced_packages_and_the_models(tmp_path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        if (ROOT / name).exists():
            shutil.copy2(ROOT / name, src / name)
    for folder in ("electroloc_gym", *MAPPED.values()):
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                           str(tmp_path / "dist"), str(src)], capture_output=True, text=True, env=ENV, timeout=600)
    assert proc.returncode == 0, proc.stderr
    (wheel,) = (tmp_path / "dist").glob("electroloc_gym-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/", 1)[0] for n in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"electroloc_gym"}
    for needed in ("electroloc_gym/baselines/agent.py", "electroloc_gym/policy/load.py",
                   "electroloc_gym/train/hyperparams/ppo.yml", "electroloc_gym/bench/records.py",
                   "electroloc_gym/models/__init__.py"):
        assert needed in names, needed
    for model in ("ppo-belief", "ppo-raw-framestack"):
        shipped = {Path(n).name for n in names if n.startswith(f"electroloc_gym/models/{model}/")}
        on_disk = {p.name for p in (ROOT / "models" / model).iterdir() if p.suffix != ".pkl"}
        assert shipped == on_disk, (model, on_disk - shipped)
    assert not [n for n in names if n.endswith(".pkl")]  # pickles never ship
    top_level = next(n for n in names if n.endswith(".dist-info/top_level.txt"))
    assert zipfile.ZipFile(wheel).read(top_level).decode().split() == ["electroloc_gym"]
