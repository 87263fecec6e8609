"""The package's utilities: argument checks, atomic file writes, threads and caches, the agent-spec parser, tables.

* :mod:`.checks` — the argument checks (one ``ValueError`` naming the argument and its allowed range);
* :mod:`.fileio` — atomic writes, strict JSON, locks, write probes;
* :mod:`.runtime` — the process's threads and caches;
* :mod:`.agentspec` — the one agent-spec and ``KEY=VALUE`` parser;
* :mod:`.markdown` — the one markdown-table helper.

They import nothing else of the package but :mod:`electroloc_gym.protocol` and :mod:`electroloc_gym.registry`.
"""

__all__: list[str] = []
