"""The batched simulation core (the only implementation of the envs' logic; docs/design.md).

* :mod:`~electroloc_gym.core.params` — :class:`EnvParams`, every env argument declared and validated once;
* :mod:`~electroloc_gym.core.state` — the explicit state arrays of N envs;
* :mod:`~electroloc_gym.core.observation` — the observation layouts and the info keys;
* :mod:`~electroloc_gym.core.task` — the task interface (what a task provides to the step) and the
  machinery the tasks share; :mod:`~electroloc_gym.core.worlds` — grouping envs by world, cached values;
* one module per task: :mod:`~electroloc_gym.core.localize` (one target), :mod:`~electroloc_gym.core.global_task`
  (the mapped tank), :mod:`~electroloc_gym.core.unknown` (the unknown target: position, radius, contrast);
  ElectroLoc-v0's task :mod:`~electroloc_gym.core.electroloc` is the localize task with its two variants,
  :mod:`~electroloc_gym.core.array` (a sensor array) and :mod:`~electroloc_gym.core.distractors`;
* :mod:`~electroloc_gym.core.step` — reset and step of N envs, through the task interface.

The core imports nothing from :mod:`electroloc_gym.envs` (the adapters import the core).
"""
