"""The package's utilities: argument checks, atomic file writes, threads and caches, the agent-spec parser, tables.

They import nothing else of the package but :mod:`electroloc_gym.protocol` and :mod:`electroloc_gym.registry`.
"""

__all__: list[str] = []
