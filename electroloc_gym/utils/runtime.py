"""Process set-up shared by the CLI, the benchmark workers, the training path, RLlib runners and the scripts.

:func:`pin_threads` sizes every numeric library's thread pool (torch, BLAS/OpenMP, numba) to one count and
writes it into the environment, so that the child processes the package starts inherit it.

Why one by default: the package parallelises by process (``electroloc bench --workers``, the vector envs'
batches), and the processes already fill the cores. Library threads on top of them oversubscribe the CPU:
on a busy 2-core machine the torch backend ran 10–25× slower with torch's default threads than with one,
and SB3's PPO 3.6–10× slower. The generic variables (``OMP_NUM_THREADS`` …) are overwritten rather than
read: a cluster job sets them to its cores for one process, which is exactly that oversubscription once the
package starts a process per core.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import numbers
import os
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

__all__ = [
    "pin_threads",
    "pinned_threads",
    "restore_environ",
    "chosen_threads",
    "thread_env",
    "add_threads_argument",
    "THREAD_VARS",
    "THREADS_VAR",
    "DEFAULT_THREADS",
    "MAX_THREADS",
    "use_user_numba_cache",
    "user_numba_cache_dir",
]

#: The environment variables that size the thread pools of OpenMP, OpenBLAS, MKL, numexpr, Accelerate
#: (read when those libraries load, so set them before the first import where it matters).
THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)
#: numba's pool size (read when numba's configuration loads).
NUMBA_THREADS_VAR = "NUMBA_NUM_THREADS"
#: The package's own setting: threads per process of every numeric library.
THREADS_VAR = "ELECTROLOC_THREADS"
#: Threads per process when nothing is chosen.
DEFAULT_THREADS = 1
#: The largest thread count accepted.
MAX_THREADS = 1024


def _check_threads(name: str, value: object, from_text: bool = False) -> int:
    """``value`` (an integer, numpy's too; with ``from_text`` a string of ASCII digits, as every integer option
    takes) as a thread count, else a ValueError naming ``name`` and the range.
    """
    number = int(value) if isinstance(value, numbers.Integral) and not isinstance(value, bool) else None
    if from_text and isinstance(value, str) and value.isascii() and value.isdigit() and len(value) <= 40:
        number = int(value)
    if number is None or not 1 <= number <= MAX_THREADS:
        raise ValueError(f"{name} must be an integer in [1, {MAX_THREADS}], got {value!r}")
    return number


def chosen_threads(threads: int | None = None) -> int:
    """The thread count of this process's numeric libraries: ``threads`` if given, else ``$ELECTROLOC_THREADS``,
    else :data:`DEFAULT_THREADS` (a ValueError when the one given is not an integer in [1, MAX_THREADS]).
    """
    if threads is not None:
        return _check_threads("threads", threads)
    text = os.environ.get(THREADS_VAR, "")
    if not text.strip():
        return DEFAULT_THREADS
    return _check_threads(THREADS_VAR, text, from_text=True)


def thread_env(threads: int | None = None) -> dict[str, str]:
    """The environment variables a child process needs to start with :func:`chosen_threads` ``(threads)``:
    :data:`THREAD_VARS`, numba's ``NUMBA_NUM_THREADS`` and :data:`THREADS_VAR`.
    """
    n = str(chosen_threads(threads))
    return {**{v: n for v in THREAD_VARS}, NUMBA_THREADS_VAR: n, THREADS_VAR: n}


def _threads_arg(text: str) -> int:
    """``--threads``: an integer in [1, MAX_THREADS] (argparse's one-line error otherwise)."""
    try:
        return _check_threads("--threads", text, from_text=True)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer in [1, {MAX_THREADS}], got {text!r}") from None


def add_threads_argument(parser: argparse.ArgumentParser) -> None:
    """Add ``--threads N`` (threads per process of every numeric library; see :func:`chosen_threads`)."""
    parser.add_argument(
        "--threads",
        type=_threads_arg,
        default=None,
        metavar="N",
        help=f"threads per process of torch, BLAS/OpenMP and numba (default: ${THREADS_VAR}, else "
        f"{DEFAULT_THREADS}: the package parallelises by process, and library threads on top of busy "
        "processes slow them down)",
    )


def pin_threads(threads: int | None = None) -> int:
    """Pin every numeric library of this process to :func:`chosen_threads` ``(threads)`` threads; return it.

    Writes :func:`thread_env` into ``os.environ`` (for libraries loaded later and for child processes),
    limits the BLAS/OpenMP pools already loaded (``threadpoolctl``) and the pools of torch and numba when
    they are loaded (this never imports them).
    """
    n = chosen_threads(threads)
    env = thread_env(n)
    if _numba_threads_started():  # numba refuses a new pool size once its threads run (it masks them instead)
        env.pop(NUMBA_THREADS_VAR)
    os.environ.update(env)
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(n)
    except ImportError:  # pragma: no cover - a dependency; kept optional for a partial install
        pass
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n)
    _pin_numba(n)
    return n


def restore_environ(saved: Mapping[str, str | None]) -> None:
    """Put back the environment variables ``saved`` recorded (None: the variable was not set)."""
    for var, value in saved.items():
        if value is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = value


@contextmanager
def pinned_threads(threads: int | None = None) -> Iterator[int]:
    """:func:`pin_threads` for a ``with`` block, then this process's thread settings as they were before it: the
    variables :func:`thread_env` writes, the BLAS/OpenMP pools (``threadpoolctl``'s own restore), torch's and
    numba's pools. A library call that runs trials in its caller's process leaves the caller's counts alone.
    """
    saved_env = {v: os.environ.get(v) for v in thread_env(1)}
    torch = sys.modules.get("torch")
    torch_threads = torch.get_num_threads() if torch is not None else None
    config = sys.modules.get("numba.core.config")
    numba_threads = None if config is None else int(config.NUMBA_NUM_THREADS)
    if _numba_threads_started():
        import numba

        numba_threads = numba.get_num_threads()
    try:
        from threadpoolctl import threadpool_limits

        pools = threadpool_limits(limits=None)  # records the pools as they are; restores them below
    except ImportError:  # pragma: no cover - a dependency; kept optional for a partial install
        pools = None
    try:
        yield pin_threads(threads)
    finally:
        restore_environ(saved_env)
        if pools is not None:
            pools.restore_original_limits()
        if torch is not None and torch_threads is not None:
            torch.set_num_threads(torch_threads)
        if numba_threads is not None:
            _pin_numba(numba_threads)


def _numba_threads_started() -> bool:
    """Numba's threading layer is running (its pool size is then fixed)."""
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return parallel is not None and bool(getattr(parallel, "_is_initialized", False))


def _pin_numba(n: int) -> None:
    """Numba's pool (its configured size before its threads start, its active threads after): the package's
    kernels are serial; this pins what user code compiles with ``parallel=True``.
    """
    config = sys.modules.get("numba.core.config")
    if config is None:  # numba reads NUMBA_NUM_THREADS when it loads
        return
    if _numba_threads_started():
        import numba

        numba.set_num_threads(min(n, int(config.NUMBA_NUM_THREADS)))
    else:
        # as the compiler's next reload of the environment reads it
        config.NUMBA_NUM_THREADS = n  # pyright: ignore[reportAttributeAccessIssue]  # numba's config module


def user_numba_cache_dir() -> Path:
    """The per-user numba cache folder of the installed numba: ``$XDG_CACHE_HOME/electroloc-gym/numba/<numba
    version>`` (``~/.cache`` without ``XDG_CACHE_HOME``).

    One folder per numba version: numba keeps one index file per kernel and source file, and a version that
    finds another's index discards it and writes its own, so two environments of different numba versions
    sharing a folder (a project's lowest-versions venv beside its newest) would compile every kernel again
    each time the other had run. The version is read from the installed distribution's metadata, without
    importing numba (this runs before the first numba import).
    """
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    try:
        version = importlib.metadata.version("numba")
    except importlib.metadata.PackageNotFoundError:  # numba without its metadata (a copied tree)
        version = "unversioned"
    return Path(base) / "electroloc-gym" / "numba" / version


def use_user_numba_cache() -> str:
    """Set ``NUMBA_CACHE_DIR`` to :func:`user_numba_cache_dir` unless the user set it; return the folder in use.

    numba creates the folder when it first writes a kernel. If numba's configuration is already loaded
    (numba imported before this package), it is reloaded so the setting still applies.
    """
    if not os.environ.get("NUMBA_CACHE_DIR"):
        os.environ["NUMBA_CACHE_DIR"] = str(user_numba_cache_dir())
        config = sys.modules.get("numba.core.config")
        if config is not None:
            config.reload_config()
    return os.environ["NUMBA_CACHE_DIR"]
