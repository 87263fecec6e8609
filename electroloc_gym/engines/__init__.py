"""The simulation engines behind the env's task interface: N envs reset and stepped as arrays.

* :mod:`.numba_core` — the reference engine: numpy state, compiled numba kernels (:mod:`electroloc_gym.kernels`),
  every env id and option;
* :mod:`.torch_core` — ElectroLoc-v0 as batched torch operations on one device (``backend="torch"``), for
  thousands of tanks per step on an accelerator.

Both keep :mod:`electroloc_gym.contract`; which options each implements is its capability table. The adapters
(:mod:`electroloc_gym.envs`) choose an engine; nothing here imports the adapters' Gymnasium classes except the
torch engine's own ``VectorEnv``.
"""

__all__: list[str] = []
