"""The project's checks as nox sessions; `nox` runs them all (the README's test command, and .ci/run).

* ``tests``  — the suite on the main job's install: ``-e .[dev,zoo,minari,docs]``, the newest releases the
  resolver picks (no RLlib pin), without the Ray/RLlib tests and the release build (``wheel`` runs those);
  and, in the same venv, the docs site built with ``mkdocs build --strict`` (a broken link, anchor or API
  reference fails it).
* ``lowest`` — the suite on every declared minimum (``constraints-lowest.txt``); the tests of extras that
  cannot install there (``zoo``: rl-zoo3 needs SB3 2.9; ``minari``: numpy 2) are deselected by marker, and
  so are the ``long`` tests (minutes of episodes, version-independent: the tests session runs them) and the
  ``once`` tests (what no minimum version can change: the project's own text and plumbing, the OS side of a run,
  the torch engine's graphs on the one pinned torch; conftest.py's ``ONCE_FILES``).
* ``rllib``  — every extra at once, with RLlib's gymnasium pin: exactly the Ray/RLlib tests (marker
  ``rllib``), and pyright over the package (its settings: ``[tool.pyright]`` in pyproject.toml: basic
  checks on every module, strict on the public API), every import resolved; it fails on any error.
* ``wheel``  — sdist and wheel built once (``python -m build``, by tests/test_wheel.py, marker ``wheel``, which
  checks what they hold) and checked (``twine check``); the wheel installed alone into an empty venv
  outside the checkout, then every registered id made, a shipped policy benchmarked, the CLI's help
  printed, and a researcher's task of their own (examples/own_task.py, copied outside the checkout) run and
  benchmarked by ``--env own_task:frugal``.

With ``-j auto`` (nox's ``--parallel``: one session per core; the README's test command and CI pass it), ``tests``
runs alone, then ``lowest``, ``rllib`` and ``wheel`` run beside each other, each session's output printed whole
when it ends; a plain ``nox`` runs them one after the other. ``tests`` holds the suite's timing and
long tests, which the others' load would slow; the other three each leave a core idle much of their time (pip
installing one package at a time, the kernels compiling in one process, Ray's tests, the wheel's serial steps), and
beside each other they fill it. On an otherwise idle 2-core machine the three took 242 s beside each other and
333 s one after the other, in two fresh clones run 13 minutes apart.

Installs are shared: each session's venv is reused (``.nox/``), pip's download cache serves every session,
and pip does not byte-compile what it installs (``--no-compile``: Python compiles the modules a test
imports, once per venv, not the whole of torch and Ray; the sessions let it write that bytecode even where
the caller's environment sets ``PYTHONDONTWRITEBYTECODE``, which would make every process, each pytest
worker, each subprocess a test starts, each Ray worker, compile torch, Ray and SB3 from source again);
``constraints.txt`` pins the CPU-only torch wheel. Before the suite, one process compiles the numba
kernels into the cache every worker then loads. A step that keeps one core busy has the session's other
checks beside it (``_beside``): the extras' import check and the docs build beside that compile, the import
check and pyright beside Ray's tests. Sessions pin numeric libraries to one thread per process
and run pytest on every core (pytest-xdist, one worker per core, a test module per worker). Arguments
after ``--`` go to pytest (``nox -s tests -- tests/test_env.py``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import nox

ROOT = Path(__file__).resolve().parent
# pip installs without bytecode (NO_COMPILE); the sessions' processes write it as they import (module docstring)
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
nox.options.reuse_venv = "yes"
nox.options.default_venv_backend = "virtualenv"  # nox's default: a venv in under a second (venv: 3 s)
nox.options.sessions = ["tests", "lowest", "rllib", "wheel"]

CONSTRAINTS = ("-c", str(ROOT / "constraints.txt"))
#: pip: no byte-compiling of every installed module (the tests compile what they import).
NO_COMPILE = "--no-compile"
ONE_THREAD = {
    var: "1"
    for var in (
        "OMP_NUM_THREADS",
        "OPENBLAS_NUM_THREADS",
        "MKL_NUM_THREADS",
        "NUMEXPR_NUM_THREADS",
        "NUMBA_NUM_THREADS",
    )
}
#: What the default sessions leave out (the fast suite's ``not slow`` plus the extras they do not install).
NOT_RLLIB = "not slow and not rllib and not wheel"
NOT_LOWEST = "not slow and not rllib and not wheel and not zoo and not minari and not long and not once"
#: Where tests/test_wheel.py copies the sdist and the wheel it built (the wheel session installs that wheel).
WHEEL_DIST = "ELECTROLOC_WHEEL_DIST"
#: pytest-xdist: one worker per core, each test module on one worker (its module fixtures built once), the
#: modules handed out in collection order (conftest.py puts the files of the long tests first), not xdist's
#: default of the modules with the most tests first.
PARALLEL = ("-n", "auto", "--dist", "loadfile", "--no-loadscope-reorder")

#: What each session's optional-path tests import (a missing one fails the session: a skipped test checks nothing).
ZOO_IMPORTS = ("rl_zoo3", "sb3_contrib", "rliable", "safetensors", "requests", "moviepy", "hypothesis", "minari")
RLLIB_IMPORTS = ("ray", "ray.rllib", "torch", "safetensors")


def _imports(modules: tuple[str, ...]) -> str:
    return f"import {', '.join(modules)}; print('imports ok: {' '.join(modules)}')"


#: Compiles the numba kernels of every registered env once, before the workers start (they load the cache).
_WARM_KERNELS = """
import gymnasium as gym
import electroloc_gym
from electroloc_gym.registry import ENV_IDS

for env_id in ENV_IDS:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
print(f"numba kernels compiled for {len(ENV_IDS)} ids")
"""


def _warm_kernels(session: nox.Session) -> None:
    session.run("python", "-c", _WARM_KERNELS, env=ONE_THREAD)


def _pytest(session: nox.Session, markexpr: str, *, parallel: bool = True, files: tuple[str, ...] = ()) -> None:
    workers = PARALLEL if parallel else ()
    args = session.posargs or list(files)
    session.run("python", "-m", "pytest", "-m", markexpr, *workers, *args, env=ONE_THREAD)


def _files_marked(marker: str) -> tuple[str, ...]:
    """The test files that use ``marker`` (``pytest.mark.<marker>``, on the module or a test): a session that runs
    only that marker's tests collects these, not the whole suite's two thousand tests to keep twenty.
    """
    pattern = f"mark.{marker}"
    found = [
        str(p.relative_to(ROOT))
        for folder in ("tests", "experiments")
        for p in sorted((ROOT / folder).rglob("test_*.py"))
        if pattern in p.read_text(encoding="utf-8")
    ]
    return tuple(found)


@contextlib.contextmanager
def _beside(session: nox.Session, *args: str) -> Iterator[None]:
    """Run ``args`` (a command of the session's venv) while the block runs, on the core a serial step leaves
    idle; then print its output, and fail the session if it failed. nox runs one command at a time and has
    no such step of its own.
    """
    env = {**os.environ, **ONE_THREAD, "VIRTUAL_ENV": str(session.virtualenv.location)}
    env["PATH"] = os.pathsep.join([str(session.bin), env.get("PATH", "")])
    session.log(f"{' '.join(args)}  (beside the next command)")
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(
            [str(Path(session.bin) / args[0]), *args[1:]], stdout=out, stderr=subprocess.STDOUT, env=env
        )
        try:
            yield
        except BaseException:
            proc.kill()
            proc.wait()
            raise
        code = proc.wait()
        out.seek(0)
        print(out.read().decode(errors="replace"), end="", flush=True)
    if code:
        session.error(f"{' '.join(args)} failed with exit code {code}")


@nox.session
def tests(session: nox.Session) -> None:
    """The default suite on the newest releases (the install of the README's main job plus dev, zoo and minari),
    and the docs site with every warning an error.
    """
    session.install(NO_COMPILE, *CONSTRAINTS, "-e", ".[dev,zoo,minari,docs]")
    site = str(Path(session.create_tmp()) / "site")
    # a test of an extra never skips for a missing import
    with (
        _beside(session, "python", "-c", _imports(ZOO_IMPORTS)),
        _beside(session, "mkdocs", "build", "--strict", "--site-dir", site),
    ):
        _warm_kernels(session)
    _pytest(session, NOT_RLLIB)


@nox.session(allow_parallel=True)
def lowest(session: nox.Session) -> None:
    """The default suite on each declared minimum (constraints-lowest.txt), the zoo and minari tests deselected."""
    session.install(NO_COMPILE, "-c", str(ROOT / "constraints-lowest.txt"), "-e", ".[dev,train]")
    session.run("python", "-m", "pip", "list", "--format=freeze", silent=False)
    _warm_kernels(session)
    _pytest(session, NOT_LOWEST)


@nox.session(allow_parallel=True)
def rllib(session: nox.Session) -> None:
    """Every extra at once (the rllib extra pins gymnasium to RLlib's version): the Ray/RLlib tests (marker
    ``rllib``), and pyright over the package, every import it makes resolved (SB3, torch, rl-zoo3, Ray/RLlib,
    Minari), so every import's types are checked.
    """
    session.install(NO_COMPILE, *CONSTRAINTS, "-e", ".[dev,zoo,rllib,minari,types]")
    # Ray's tests leave a core idle about half of the time: the import check and pyright run beside them
    with _beside(session, "python", "-c", _imports(RLLIB_IMPORTS)), _beside(session, "pyright"):
        # Ray starts its own worker processes; only the files that hold Ray/RLlib tests are collected
        _pytest(session, "rllib and not slow", parallel=False, files=_files_marked("rllib"))


_WHEEL_SMOKE = """
import sys
import gymnasium as gym
import electroloc_gym
from electroloc_gym.registry import ENV_IDS

assert "site-packages" in electroloc_gym.__file__, electroloc_gym.__file__  # the wheel, not the checkout
for env_id in ENV_IDS:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
print(f"electroloc-gym {electroloc_gym.__version__}: made {len(ENV_IDS)} ids: {', '.join(ENV_IDS)}")
"""


@nox.session(allow_parallel=True)
def wheel(session: nox.Session) -> None:
    """Build sdist and wheel once (tests/test_wheel.py, marker ``wheel``: their contents checked), check them
    with twine, install the wheel alone into an empty venv and run it from there.
    """
    session.install(NO_COMPILE, "build", "twine", "pytest", "hypothesis")  # the root conftest.py imports hypothesis
    tmp = Path(session.create_tmp()).resolve()
    dist, venv, work = tmp / "dist", tmp / "wheel-venv", tmp / "work"
    for folder in (dist, venv, work):
        shutil.rmtree(folder, ignore_errors=True)
    work.mkdir()
    # the build of the release, on a copy of the checkout with leftovers planted; the artefacts land in dist
    session.run(
        "python", "-m", "pytest", "-m", "wheel", "tests/test_wheel.py", env={**ONE_THREAD, WHEEL_DIST: str(dist)}
    )
    (sdist,) = dist.glob("electroloc_gym-*.tar.gz")
    (whl,) = dist.glob("electroloc_gym-*.whl")
    session.run("twine", "check", "--strict", str(sdist), str(whl))
    session.run(sys.executable, "-m", "virtualenv", "-q", str(venv), external=True)
    py = str(venv / "bin" / "python")
    electroloc = str(venv / "bin" / "electroloc")
    # the core dependencies only: a shipped policy runs without torch or SB3 (electroloc_gym.policy)
    session.run(py, "-m", "pip", "install", "-q", NO_COMPILE, *CONSTRAINTS, str(whl), external=True)
    session.chdir(work)  # nothing of the checkout on sys.path
    session.run(py, "-c", _WHEEL_SMOKE, external=True, env=ONE_THREAD)
    session.run(electroloc, "--help", external=True, silent=True)
    session.run(
        electroloc,
        "bench",
        "--agents",
        "ppo-belief,rnd-wlk",
        "--conditions",
        "fresh-steel-12.7",
        "--trials",
        "2",
        "--out",
        str(work / "bench"),
        "--no-progress",
        external=True,
        env=ONE_THREAD,
    )
    # a researcher's own task from a module outside the package (examples/own_task.py copied away from the
    # checkout): its main block, then the benchmark on it by MODULE:NAME, with the installed package only
    mine = work / "mine"
    mine.mkdir()
    shutil.copy2(ROOT / "examples" / "own_task.py", mine / "own_task.py")
    session.chdir(mine)
    session.run(py, "own_task.py", external=True, env=ONE_THREAD)
    session.run(
        electroloc,
        "bench",
        "--env",
        "own_task:frugal",
        "--agents",
        "rnd-wlk",
        "--conditions",
        "fresh-steel-12.7",
        "--trials",
        "1",
        "--out",
        str(work / "bench-own"),
        "--no-progress",
        external=True,
        env={**ONE_THREAD, "PYTHONPATH": str(mine)},
    )
