"""The ``ray`` benchmark backend: trials as Ray tasks, on this machine or a cluster.

``electroloc bench --backend ray [--address ray://head:10001 | auto]`` (optional extra:
``pip install .[ray]``). :func:`check_ray_address` runs before anything is written to ``--out``: without
Ray, or with an address where no Ray cluster answers, the command ends with one line naming the option.
Without an address a local Ray runtime with ``workers`` CPUs is started (and shut down afterwards); with
one, the run joins that cluster, which must have electroloc-gym installed on every node (or ship it with a
Ray ``runtime_env``).

Results do not depend on the backend (:mod:`electroloc_gym.bench.backends`): each Ray worker imports
``electroloc_gym`` itself — which registers the env ids in that worker — and pins its numeric libraries'
threads before running the trial. Ray is imported only when a run starts, so registering this backend costs
nothing when Ray is absent.
"""

from __future__ import annotations

import socket
import subprocess
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

from electroloc_gym.bench.backends import Backend, WorkerLost, register_backend
from electroloc_gym.options import message_words
from electroloc_gym.registry import import_plugin_modules, plugin_modules
from electroloc_gym.utils.runtime import pin_threads, thread_env

__all__ = ["RayBackend", "check_ray_address", "ray_missing"]

#: Seconds to wait for a cluster's port to accept a connection.
CONNECT_TIMEOUT_S = 3.0
#: Seconds the connection probe (a child process that joins the cluster and leaves) may take.
PROBE_TIMEOUT_S = 60.0
#: The probe: join the cluster at argv[1] and leave. In a child process, so that Ray's retry messages (printed
#: by its C++ core while it waits for an address that is not a Ray cluster) never reach the user's terminal.
_PROBE = (
    "import logging, sys\nimport ray\n"
    "ray.init(address=sys.argv[1], logging_level=logging.ERROR, log_to_driver=False)\nray.shutdown()\n"
)


def ray_missing(what: str, extra: str = "ray") -> str:
    """The one line for ``what`` (an option, a script) run where Ray is not installed: the install command of the
    package's ``extra`` that brings it (``"ray"``: the benchmark's backend; ``"rllib"``: RLlib training).
    """
    install = f"pip install 'electroloc-gym[{extra}]'" + (" (or pip install ray)" if extra == "ray" else "")
    return f"{what} needs Ray, which is not installed here: {install}"


#: How the Ray refusals name ``backend`` and ``address`` unless a front end gives its own words (Python's spelling).
_PYTHON_WORDS = {"backend": "backend", "address": "address"}


def _import_ray(backend: str) -> Any:
    try:
        import ray
    except ImportError as exc:
        raise ValueError(ray_missing(f"{backend} ray")) from exc
    return ray


def _host_port(text: str) -> tuple[str, int] | None:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def check_ray_address(address: str | None, names: Mapping[str, str] | None = None) -> None:
    """Check that the ray backend can run: Ray is installed and, for an ``address``, a cluster answers there.

    ``"auto"`` is resolved as ``ray.init`` resolves it; a ``"ray://host:port"`` or ``"host:port"`` address must
    accept a TCP connection within :data:`CONNECT_TIMEOUT_S`. None (no ``--address``: the run starts a local
    Ray) checks only that Ray is installed. Nothing is started and nothing is written. ``names``: how the
    messages name ``backend`` and ``address`` (the command line's ``--backend``, ``--address``; None: as here).

    Raises:
        ValueError: one line naming the backend (Ray missing) or the address (malformed or no cluster answers
            there).
    """
    names = message_words(_PYTHON_WORDS, names)
    ray = _import_ray(names["backend"])
    flag = names["address"]
    if address is None:
        return
    if not isinstance(address, str) or not address.strip():
        raise ValueError(
            f"{flag} must be a Ray cluster address ('auto', 'host:6379', 'ray://host:10001'), got {address!r}"
        )
    target = address.strip()
    if target.startswith("ray://"):
        target = target[len("ray://") :]
    elif target in ("auto", "local") or _host_port(target) is None:
        try:
            from ray._private.services import canonicalize_bootstrap_address_or_die
        except ImportError:  # pragma: no cover - Ray moved its resolver; ray.init reports instead
            return
        try:
            target = canonicalize_bootstrap_address_or_die(None if target == "local" else target)  # pyright: ignore[reportArgumentType]  # Ray annotates addr as str; its docstring and code take None
        except (ConnectionError, ValueError) as exc:
            raise ValueError(
                f"{flag} {address!r}: no running Ray cluster found (start one with "
                f"`ray start --head`, or omit {flag} for a local Ray); Ray says: "
                f"{str(exc).splitlines()[0]}"
            ) from None
    hp = _host_port(target)
    if hp is None:
        raise ValueError(f"{flag} {address!r} is not a Ray address ('auto', 'host:6379', 'ray://host:10001')")
    try:  # a refused or unroutable port: a clear answer within seconds
        with socket.create_connection(hp, timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        raise ValueError(
            f"{flag} {address!r}: no Ray cluster answers at {hp[0]}:{hp[1]} "
            f"({exc.strerror or exc}); start one with `ray start --head` or omit {flag}"
        ) from None
    _probe(address, ray, flag)


def _probe(address: str, ray: Any, flag: str) -> None:
    """Join the cluster at ``address`` from a child process (something else may listen on that port)."""
    if ray.is_initialized():
        return
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE, address],
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT_S,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise ValueError(
            f"{flag} {address!r}: no Ray cluster answered within {PROBE_TIMEOUT_S:g} s; start one "
            f"with `ray start --head` or omit {flag}"
        ) from None
    if proc.returncode != 0:
        lines = [ln for ln in proc.stderr.splitlines() if "Error" in ln] or proc.stderr.splitlines() or ["no answer"]
        raise ValueError(
            f"{flag} {address!r}: could not join a Ray cluster there ({lines[-1].strip()}); "
            f"start one with `ray start --head` or omit {flag}"
        )


def _run_in_worker(worker_fn: Callable[[Any], Any], spec: Any, modules: tuple[str, ...] = ()) -> Any:
    """What a Ray task runs: set up the worker process like the process pool's initializer (threads, and the
    modules the driver imported for their envs, :func:`~electroloc_gym.registry.plugin_modules`), then the trial.
    """
    pin_threads()
    import_plugin_modules(modules)

    return worker_fn(spec)


def _result(ray: Any, ref: Any, spec: Any) -> Any:
    """``ray.get(ref)``; a task's own exception re-raised as itself (not Ray's traceback-laden wrapper), a
    dead worker as :class:`~electroloc_gym.bench.backends.WorkerLost`.
    """
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = getattr(exc, "cause", None)
        if isinstance(cause, BaseException):
            raise cause from None
        raise
    except (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError) as exc:
        raise WorkerLost([spec], f"Ray: {type(exc).__name__}") from None


@register_backend
class RayBackend(Backend):
    """Trials as Ray tasks (one CPU each), yielded as they finish.

    Args:
        workers: CPUs of the local Ray runtime started when ``address`` is None (None: all cores);
            ignored when joining a cluster (the cluster's CPUs bound the parallelism).
        address: a Ray cluster address (``"auto"``, ``"ray://host:10001"``, ``"host:6379"``) or None
            for a local runtime.
        names: how the run's refusals (Ray missing, a cluster that refuses ``ray.init``) name ``backend`` and
            ``address``, in the words of the front end that took them (:func:`check_ray_address`'s; None: as here).

    Raises:
        ValueError: bad ``workers``, ``address`` or ``names`` (names the argument).
    """

    name = "ray"

    def __init__(
        self, workers: int | None = None, address: str | None = None, names: Mapping[str, str] | None = None
    ) -> None:
        super().__init__(workers)
        if address is not None and (not isinstance(address, str) or not address.strip()):
            raise ValueError(f"address must be None (local Ray) or a non-empty Ray address string, got {address!r}")
        self.address = address
        self.names = message_words(_PYTHON_WORDS, names)

    def run_trials(self, specs: Sequence[Any], worker_fn: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
        if not specs:
            return
        ray = _import_ray(self.names["backend"])
        started = False
        if not ray.is_initialized():
            try:
                ray.init(
                    address=self.address,
                    num_cpus=self.workers if self.address is None else None,  # a cluster has its own CPUs
                    runtime_env={"env_vars": thread_env()},  # read at numpy import, and by pin_threads
                    log_to_driver=False,
                    include_dashboard=False,
                )
            except ConnectionError as exc:
                raise ValueError(f"{self.names['address']} {self.address!r}: {str(exc).splitlines()[0]}") from None
            started = True
        try:
            task = ray.remote(num_cpus=1)(_run_in_worker)
            fn_ref = ray.put(worker_fn)
            modules = plugin_modules()  # a worker imports them (on its own PYTHONPATH) before its trial
            refs = {task.remote(fn_ref, spec, modules): spec for spec in specs}
            pending = list(refs)
            try:
                while pending:
                    done, pending = ray.wait(pending, num_returns=1)
                    for ref in done:
                        yield refs[ref], _result(ray, ref, refs[ref])
            finally:
                for ref in pending:  # an error or an abandoned iterator: stop the rest
                    ray.cancel(ref, force=True)
        finally:
            if started:
                ray.shutdown()
