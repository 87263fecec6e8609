"""The batched simulation core (the only implementation of the envs' logic; docs/design.md).

* :mod:`~electroloc_gym.core.params` — :class:`EnvParams`, every env argument declared and validated once;
* :mod:`~electroloc_gym.core.state` — the explicit state arrays of N envs;
* :mod:`~electroloc_gym.core.tasks` — what differs between the tasks (one target, the mapped tank);
* :mod:`~electroloc_gym.core.unknown` — the unknown-target task (position, radius and contrast, §7);
* :mod:`~electroloc_gym.core.step` — reset and step of N envs.
"""
