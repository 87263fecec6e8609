"""Where benchmark trials run: pluggable backends behind one small interface.

A backend maps a picklable, module-level ``worker_fn`` over picklable trial specs and yields
``(spec, result)`` pairs *as trials finish* (any order). Results never depend on the backend or the
worker count: every trial carries its own seeds (``numpy.random.SeedSequence`` indexed by condition
and trial, see :mod:`electroloc_gym.bench.config`), and workers build their envs and agents
themselves.

Built in: ``"process"`` (default, :class:`ProcessBackend`) and ``"serial"`` (in-process, for debugging and
tests). More register with :func:`register_backend`, as :mod:`~electroloc_gym.bench.ray_backend`'s ``"ray"`` does.
"""

from __future__ import annotations

import abc
import concurrent.futures as cf
import contextlib
import itertools
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures.process import BrokenProcessPool
from typing import Any, ClassVar

from electroloc_gym.registry import import_plugin_modules, plugin_modules
from electroloc_gym.utils.runtime import chosen_threads, pin_threads, pinned_threads, restore_environ, thread_env

__all__ = [
    "Backend",
    "SerialBackend",
    "ProcessBackend",
    "BACKENDS",
    "register_backend",
    "make_backend",
    "default_workers",
    "exit_with_parent",
    "WorkerLost",
]


class WorkerLost(RuntimeError):
    """A worker process died without returning (``os._exit``, a signal, the OOM killer).

    Attributes:
        specs: the specs that were running on the lost worker, or the few in flight when the backend
            cannot tell which one it was.
        reason: what the backend saw, in a few words.
    """

    def __init__(self, specs: Sequence[Any], reason: str) -> None:
        super().__init__(f"a worker process died ({reason})")
        self.specs, self.reason = list(specs), reason


def exit_with_parent(parent_pid: int, poll_s: float = 0.5) -> None:
    """Make this (worker) process exit when ``parent_pid``, the process that started it, dies.

    Two mechanisms: on Linux the kernel's parent-death signal (``prctl(PR_SET_PDEATHSIG, SIGKILL)``),
    and everywhere a daemon thread that polls ``os.getppid()`` every ``poll_s`` seconds (a worker is
    re-parented when its parent dies). A worker whose parent died before this ran exits at once.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):  # an exotic libc: the poller still works
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    if os.getppid() != parent_pid:
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _init_worker(parent_pid: int, threads: int, modules: tuple[str, ...] = ()) -> None:
    """Initializer of a process-pool worker: it exits with ``parent_pid``, runs ``threads`` numeric threads and
    imports ``modules`` (those the parent imported for their envs, ``--env MODULE:NAME``: a spawned worker
    registers them as its parent did, :func:`~electroloc_gym.registry.plugin_modules`).
    """
    exit_with_parent(parent_pid)
    pin_threads(threads)
    import_plugin_modules(modules)


def default_workers() -> int:
    """All cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


class Backend(abc.ABC):
    """Runs trial specs through a worker function.

    Args:
        workers: parallel workers (None: all cores); backends that have no notion of it ignore it.
    """

    #: Name used by ``--backend``.
    name: ClassVar[str] = ""

    def __init__(self, workers: int | None = None, **options: Any) -> None:
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers must be an integer ≥ 1 or None (all cores), got {workers!r}")
        if options:
            raise ValueError(f"backend {self.name!r} takes no options, got {sorted(options)}")
        self.workers = default_workers() if workers is None else workers

    @abc.abstractmethod
    def run_trials(self, specs: Sequence[Any], worker_fn: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
        """Yield ``(spec, worker_fn(spec))`` for every spec as it finishes (any order).

        A failing trial raises its exception from the iterator (after which no more results come); a
        worker that dies without returning raises :class:`WorkerLost`.
        """


class SerialBackend(Backend):
    """In-process, one trial after another (debugging, tests, tiny runs)."""

    name = "serial"

    def run_trials(self, specs: Sequence[Any], worker_fn: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
        for spec in specs:
            yield spec, worker_fn(spec)


_POOL_BROKE = "the process pool broke: a worker exited or was killed"


class ProcessBackend(Backend):
    """A local process pool (``concurrent.futures.ProcessPoolExecutor``, spawn); every worker runs
    :func:`~electroloc_gym.utils.runtime.chosen_threads` numeric threads (one unless chosen) and exits when the
    process that started it dies (:func:`exit_with_parent`).

    At most one trial per worker is in flight, so a worker that dies (the pool breaks) is known to have
    been running one of those few (:class:`WorkerLost` lists them).
    """

    name = "process"

    def run_trials(self, specs: Sequence[Any], worker_fn: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
        if not specs:
            return
        threads = chosen_threads()
        if self.workers == 1:  # in this process, on the workers' count; the caller's counts restored after
            with pinned_threads(threads):
                yield from SerialBackend(1).run_trials(specs, worker_fn)
            return
        ctx = mp.get_context("spawn")  # no inherited locks/threads (tqdm's monitor, BLAS pools)
        child_env = thread_env(threads)
        saved = {v: os.environ.get(v) for v in child_env}
        os.environ.update(child_env)  # children read these at numpy import, before the initializer runs
        try:
            with cf.ProcessPoolExecutor(
                max_workers=min(self.workers, len(specs)),
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(os.getpid(), threads, plugin_modules()),
            ) as pool:
                todo = iter(specs)
                futures = {pool.submit(worker_fn, spec): spec for spec in itertools.islice(todo, self.workers)}
                try:
                    while futures:
                        done, _ = cf.wait(futures, return_when=cf.FIRST_COMPLETED)
                        if any(isinstance(f.exception(), BrokenProcessPool) for f in done):
                            raise WorkerLost(list(futures.values()), _POOL_BROKE)
                        for fut in done:
                            spec = futures.pop(fut)
                            yield spec, fut.result()
                            nxt = next(todo, None)
                            if nxt is not None:
                                try:
                                    futures[pool.submit(worker_fn, nxt)] = nxt
                                except BrokenProcessPool:  # a worker died while this trial's result was kept
                                    raise WorkerLost(list(futures.values()) or [nxt], _POOL_BROKE) from None
                finally:
                    for fut in futures:
                        fut.cancel()
        finally:
            restore_environ(saved)


#: Backend name → class. Add more with :func:`register_backend`.
BACKENDS: dict[str, type[Backend]] = {"process": ProcessBackend, "serial": SerialBackend}


def register_backend(cls: type[Backend]) -> type[Backend]:
    """Register a :class:`Backend` subclass under its ``name`` (usable as a decorator)."""
    if not (isinstance(cls, type) and issubclass(cls, Backend)) or not cls.name:
        raise ValueError(f"backend must be a Backend subclass with a name, got {cls!r}")
    BACKENDS[cls.name] = cls
    return cls


def make_backend(name: str, workers: int | None = None, **options: Any) -> Backend:
    """Build a backend by name.

    Raises:
        ValueError: unknown name (lists the known ones) or bad options.
    """
    if name not in BACKENDS:
        raise ValueError(f"backend must be one of {sorted(BACKENDS)}, got {name!r}")
    return BACKENDS[name](workers=workers, **options)
