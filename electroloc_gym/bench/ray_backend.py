"""The ``ray`` benchmark backend: trials as Ray tasks, on this machine or a cluster.

``electroloc bench --backend ray [--address ray://head:10001 | auto]`` (optional extra:
``pip install .[ray]``). Without an address a local Ray runtime with ``workers`` CPUs is started
(and shut down afterwards); with one, the run joins that cluster, which must have electroloc-gym
installed on every node (or ship it with a Ray ``runtime_env``).

Results do not depend on the backend: every trial spec carries its own seeds
(``numpy.random.SeedSequence``, :mod:`electroloc_gym.bench.config`), and each Ray worker imports
``electroloc_gym`` itself — which registers the env ids in that worker — and pins its numeric
libraries to one thread before running the trial. Ray is imported only when a run
starts, so registering this backend costs nothing when Ray is absent.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any

from electroloc_gym.bench.backends import Backend, register_backend
from electroloc_gym.runtime import THREAD_VARS, pin_threads

__all__ = ["RayBackend"]


def _run_in_worker(worker_fn: Callable[[Any], Any], spec: Any) -> Any:
    """What a Ray task runs: set up the worker process like the process pool's initializer, then the trial."""
    pin_threads()
    import electroloc_gym  # noqa: F401  (registers ElectroLoc-v0 & co. in this worker)

    return worker_fn(spec)


@register_backend
class RayBackend(Backend):
    """Trials as Ray tasks (one CPU each), yielded as they finish.

    Args:
        workers: CPUs of the local Ray runtime started when ``address`` is None (None: all cores);
            ignored when joining a cluster (the cluster's CPUs bound the parallelism).
        address: a Ray cluster address (``"auto"``, ``"ray://host:10001"``, ``"host:6379"``) or None
            for a local runtime.

    Raises:
        ValueError: bad ``workers`` or ``address`` (names the argument).
    """

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        super().__init__(workers)
        if address is not None and (not isinstance(address, str) or not address.strip()):
            raise ValueError(f"address must be None (local Ray) or a non-empty Ray address string, got {address!r}")
        self.address = address

    @staticmethod
    def _import_ray() -> Any:
        try:
            import ray
        except ImportError as exc:
            raise ValueError("the ray backend needs Ray: pip install 'electroloc-gym[ray]' "
                             "(or pip install ray)") from exc
        return ray

    def run_trials(self, specs: Sequence[Any], worker_fn: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
        if not specs:
            return
        ray = self._import_ray()
        started = False
        if not ray.is_initialized():
            env_vars = {v: "1" for v in THREAD_VARS}  # workers read these at numpy import
            kwargs: dict[str, Any] = {"runtime_env": {"env_vars": env_vars}, "log_to_driver": False,
                                      "include_dashboard": False}
            if self.address is None:
                kwargs["num_cpus"] = self.workers
            ray.init(address=self.address, **kwargs)
            started = True
        try:
            task = ray.remote(num_cpus=1)(_run_in_worker)
            fn_ref = ray.put(worker_fn)
            refs = {task.remote(fn_ref, spec): spec for spec in specs}
            pending = list(refs)
            try:
                while pending:
                    done, pending = ray.wait(pending, num_returns=1)
                    for ref in done:
                        yield refs[ref], ray.get(ref)
            finally:
                for ref in pending:  # an error or an abandoned iterator: stop the rest
                    ray.cancel(ref, force=True)
        finally:
            if started:
                ray.shutdown()
