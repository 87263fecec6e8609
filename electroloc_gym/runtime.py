"""Process set-up shared by the benchmark workers, the training path, RLlib runners and the CLI.

:func:`pin_threads` pins every numeric library of the process to one thread. On a small machine two
BLAS/torch/numba threads per process run slower than one (the processes already fill the cores), so
the package parallelises by process and never by library thread.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["pin_threads", "THREAD_VARS", "use_user_numba_cache", "user_numba_cache_dir"]

#: The environment variables that size the thread pools of OpenMP, OpenBLAS, MKL, numexpr, Accelerate
#: (read when those libraries load, so set them before the first import where it matters).
THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)


def pin_threads() -> None:
    """Pin numeric libraries of this process to one thread.

    Sets :data:`THREAD_VARS` to 1 (for libraries loaded later), limits the thread pools already loaded
    (``threadpoolctl``, when installed) and torch's intra-op pool if torch is already imported (this
    never imports torch).
    """
    for var in THREAD_VARS:
        os.environ[var] = "1"
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:  # pragma: no cover - optional
        pass
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


def user_numba_cache_dir() -> Path:
    """The per-user numba cache folder: ``$XDG_CACHE_HOME/electroloc-gym/numba`` (``~/.cache`` without it)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "electroloc-gym" / "numba"


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
