"""The release artefacts: an sdist and a wheel built as a release builds them, holding what a user needs.

The build runs on a copy of the checkout with leftovers planted where they collect (``build/lib``,
``results/``, ``experiments/``), so a packaging change that lets them in fails here. The wheel must hold
the package, the shipped policies (without pickles) and the hyper-parameter files, nothing of
``tests/``, ``results/``, ``build/``, ``experiments/`` or ``benchmarks/``, and stay small. The build is
the release's (``python -m build``, in an isolated build environment). These tests carry the marker
``wheel``: nox's ``wheel`` session runs exactly them, with ``ELECTROLOC_WHEEL_DIST`` naming a folder that
receives the sdist and the wheel, then checks them with twine and installs that wheel alone into an empty
venv and runs it (one build per run of the test command).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import zipfile
from collections import Counter
from pathlib import Path

import pytest

pytestmark = pytest.mark.wheel

ROOT = Path(__file__).resolve().parents[1]
MAX_WHEEL_MB = 5.0  # about 2.4 MB, the shipped policies 1.9 MB of it (their SB3 zips would add 5.6 MB)
LEFT_OUT = ("tests/", "results/", "build/", "experiments/", "benchmarks/", "docs/", ".nox/", "site/")
_SKIP = shutil.ignore_patterns(
    ".git",
    ".venv",
    ".nox",
    "site",
    "dist",
    "build",
    "__pycache__",
    "*.egg-info",
    ".pytest_cache",
    ".ruff_cache",
    ".hypothesis",
    "results",
    "logs",
)


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    src = tmp_path_factory.mktemp("checkout") / "electroloc-gym"
    shutil.copytree(ROOT, src, ignore=_SKIP)
    for leftover in (
        "build/lib/electroloc_gym/leftover.py",
        "results/bench/table.md",
        "experiments/leftover/run.py",
        "electroloc_gym/models/ppo-belief/stale.pkl",
        "electroloc_gym/models/ppo-belief/model.zip",  # an SB3 zip: a pickle, never shipped
    ):
        (src / leftover).parent.mkdir(parents=True, exist_ok=True)
        (src / leftover).write_text("# a leftover that must not ship\n", encoding="utf-8")
    dist = src.parent / "dist"
    proc = subprocess.run(
        [sys.executable, "-m", "build", "--outdir", str(dist), str(src)],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    (sdist,) = dist.glob("electroloc_gym-*.tar.gz")
    (wheel,) = dist.glob("electroloc_gym-*.whl")
    keep = os.environ.get("ELECTROLOC_WHEEL_DIST")
    if keep:  # nox's wheel session installs this very wheel
        Path(keep).mkdir(parents=True, exist_ok=True)
        for artefact in (sdist, wheel):
            shutil.copy2(artefact, Path(keep) / artefact.name)
    return sdist, wheel


def test_wheel_holds_the_package_and_the_shipped_policies(built: tuple[Path, Path]) -> None:
    _, wheel = built
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/", 1)[0] for n in names}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"electroloc_gym"}
    for needed in (
        "electroloc_gym/py.typed",
        "electroloc_gym/baselines/agent.py",
        "electroloc_gym/policy/load.py",
        "electroloc_gym/train/hyperparams/ppo.yml",
        "electroloc_gym/bench/records.py",
        "electroloc_gym/models/__init__.py",
    ):
        assert needed in names, needed
    for model in sorted(
        p.name for p in (ROOT / "electroloc_gym" / "models").iterdir() if p.is_dir() and p.name != "__pycache__"
    ):
        shipped = {Path(n).name for n in names if n.startswith(f"electroloc_gym/models/{model}/")}
        folder = ROOT / "electroloc_gym" / "models" / model
        on_disk = {p.name for p in folder.iterdir() if p.suffix not in (".pkl", ".zip")}
        assert shipped == on_disk, (model, on_disk - shipped)
        assert {"policy.json", "policy.safetensors"} <= shipped, model


def test_wheel_leaves_out_leftovers_tests_and_results(built: tuple[Path, Path]) -> None:
    _, wheel = built
    info = zipfile.ZipFile(wheel).infolist()
    names = [i.filename for i in info]
    assert not [n for n in names if n.endswith((".pkl", ".zip")) or "leftover" in n or "__pycache__" in n]
    inner = [n.split("/", 1)[1] for n in names if n.startswith("electroloc_gym/")]
    assert not [n for n in inner if n.startswith(LEFT_OUT)]
    size_mb = wheel.stat().st_size / 1e6
    by_folder = Counter(
        n.split("/")[1] if n.count("/") > 1 else "(package)" for n in names if n.startswith("electroloc_gym/")
    )
    print(f"\n{wheel.name}: {len(names)} files, {size_mb:.1f} MB; files per folder: {dict(sorted(by_folder.items()))}")
    assert size_mb < MAX_WHEEL_MB, f"{wheel.name} is {size_mb:.1f} MB"


def test_sdist_holds_the_sources_not_the_results(built: tuple[Path, Path]) -> None:
    sdist, _ = built
    with tarfile.open(sdist) as tar:
        names = [n.split("/", 1)[1] for n in tar.getnames() if "/" in n]
    for needed in (
        "pyproject.toml",
        "README.md",
        "LICENSE",
        "electroloc_gym/__init__.py",
        "electroloc_gym/baselines/agent.py",
        "electroloc_gym/models/ppo-belief/policy.safetensors",
    ):
        assert needed in names, needed
    assert not [n for n in names if n.startswith(("results/", "build/", "experiments/")) or "leftover" in n]
    assert sdist.stat().st_size / 1e6 < MAX_WHEEL_MB


def test_a_researchers_own_task_runs_on_the_installed_wheel(built: tuple[Path, Path], tmp_path: Path) -> None:
    """examples/own_task.py copied to a folder outside the checkout runs on the wheel's package (installed with
    ``pip --target``, first on the path; nox's ``wheel`` session runs the same in an empty venv): its main block,
    then ``electroloc bench --env own_task:frugal`` with PYTHONPATH set to that folder.
    """
    if os.environ.get("ELECTROLOC_WHEEL_DIST"):  # nox's wheel session: it runs the same in its empty venv next
        pytest.skip("nox's wheel session runs examples/own_task.py in its empty venv after the build")
    _, wheel = built
    site, mine = tmp_path / "site", tmp_path / "mine"
    mine.mkdir()
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile", "--target", str(site), str(wheel)]
    proc = subprocess.run(pip, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    shutil.copy2(ROOT / "examples" / "own_task.py", mine / "own_task.py")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1", "PYTHONPATH": f"{site}{os.pathsep}{mine}"}
    where = subprocess.run(
        [sys.executable, "-c", "import electroloc_gym; print(electroloc_gym.__file__)"],
        capture_output=True,
        text=True,
        cwd=mine,
        env=env,
        timeout=300,
    )
    assert where.stdout.strip().startswith(str(site)), where.stdout + where.stderr  # the wheel, not the checkout
    run = subprocess.run(
        [sys.executable, "own_task.py"], capture_output=True, text=True, cwd=mine, env=env, timeout=600
    )
    assert run.returncode == 0 and run.stdout.startswith("FrugalLoc-v0: "), run.stdout + run.stderr[-3000:]
    argv = ["--env", "own_task:frugal", "--agents", "rnd-wlk", "--conditions", "fresh-steel-12.7", "--trials", "1"]
    bench = subprocess.run(
        [str(site / "bin" / "electroloc"), "bench", *argv, "--out", str(tmp_path / "bench"), "--no-progress"],
        capture_output=True,
        text=True,
        cwd=mine,
        env=env,
        timeout=600,
    )
    assert bench.returncode == 0, bench.stderr[-3000:]
    assert "Travel median (mm)" in (tmp_path / "bench" / "table.md").read_text(encoding="utf-8")
