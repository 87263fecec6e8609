"""The native vector env's ``backend`` argument: the simulation backends an env table entry declares.

Every env runs on the numba core (the default and the reference); an entry's ``backends`` names its
other backends as ``"module:Class"`` (for ElectroLoc-v0: ``"torch"``, :mod:`electroloc_gym.engines.torch_core`).
The class is imported only when that backend is asked for, which is why the table holds a string here
and not the class: an optional dependency (torch) stays optional for everyone who does not use it.
"""

from __future__ import annotations

import importlib
from typing import Any

from electroloc_gym.registry import ENVS, EnvEntry

__all__ = ["DEFAULT_BACKEND", "backends_of", "make_backend_vector_env"]

#: The simulation backend of every env (the compiled numba core).
DEFAULT_BACKEND = "numba"
#: The extra that installs a backend's dependency, by the module it needs.
_EXTRAS = {"torch": "train"}


def backends_of(entry: EnvEntry) -> tuple[str, ...]:
    """The simulation backends of ``entry``'s native vector env (numba first)."""
    return (DEFAULT_BACKEND, *entry.backends)


def make_backend_vector_env(entry: EnvEntry, backend: Any, *args: Any, **kwargs: Any) -> Any:
    """The vector env of ``entry`` on the simulation backend ``backend``.

    Raises:
        ValueError: a backend no entry declares, or one this entry does not implement (the message lists
            the entry's backends).
        ImportError: the backend's dependency missing (the message names the extra that installs it).
    """
    known = tuple(dict.fromkeys(b for e in ENVS for b in backends_of(e)))
    if not isinstance(backend, str) or backend not in known:
        raise ValueError(f"backend must be one of {list(known)}, got {backend!r}")
    if backend not in entry.backends:
        implementing = [e.env_id for e in ENVS if backend in e.backends]
        raise ValueError(
            f"backend={backend!r} implements {implementing} only, not {entry.env_id!r}; use backend={DEFAULT_BACKEND!r}"
        )
    module, _, name = entry.backends[backend].partition(":")
    try:
        cls = getattr(importlib.import_module(module), name)
    except ModuleNotFoundError as exc:
        extra = _EXTRAS.get(str(exc.name).split(".")[0])
        hint = f": pip install 'electroloc-gym[{extra}]'" if extra else ""
        raise ImportError(f"backend={backend!r} needs {exc.name}{hint}") from exc
    return cls(*args, **kwargs)
