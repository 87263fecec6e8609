"""The native vector env's ``backend`` argument: which envs the torch core implements (imports no torch).

:class:`electroloc_gym.envs.vector.CoreVectorEnv` calls :func:`make_torch_vector_env` for any
``backend`` other than ``"numba"``; torch is imported only when the torch env is built.
"""

from __future__ import annotations

from typing import Any

__all__ = ["BACKENDS", "TORCH_ENV_IDS", "make_torch_vector_env"]

#: The core backends of the native vector env (numba: the default and the reference).
BACKENDS = ("numba", "torch")
#: The env ids the torch core implements.
TORCH_ENV_IDS = ("ElectroLoc-v0",)


def make_torch_vector_env(env_id: str, backend: Any, *args: Any, **kwargs: Any) -> Any:
    """The torch vector env of ``env_id``; one ValueError for an unknown backend or an env the torch core
    does not implement, or (``ImportError``) torch missing.
    """
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ValueError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    if env_id not in TORCH_ENV_IDS:
        raise ValueError(f"backend='torch' implements {list(TORCH_ENV_IDS)} only, not {env_id!r}; use backend='numba'")
    try:
        from electroloc_gym.torch_core.vector_env import TorchElectroLocVectorEnv
    except ImportError as exc:  # pragma: no cover - torch is in the train extra
        raise ImportError("backend='torch' needs torch: pip install 'electroloc-gym[train]'") from exc
    return TorchElectroLocVectorEnv(*args, **kwargs)
