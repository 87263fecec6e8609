"""The reference engine: N envs of every task as numpy arrays, stepped by compiled numba kernels.

* :mod:`~electroloc_gym.engines.numba_core.state` — the explicit state arrays of N envs;
* :mod:`~electroloc_gym.engines.numba_core.task` — the task interface (what a task provides to the step) and the
  machinery the tasks share; :mod:`~electroloc_gym.engines.numba_core.worlds` — grouping envs by world, cached values;
* one module per task: :mod:`~electroloc_gym.engines.numba_core.localize_task` (one target),
:mod:`~electroloc_gym.engines.numba_core.global_task`
  (the mapped tank), :mod:`~electroloc_gym.engines.numba_core.unknown` (the unknown target: position, radius, contrast);
  ElectroLoc-v0's task :mod:`~electroloc_gym.engines.numba_core.electroloc` is the localize task with its two variants,
  :mod:`~electroloc_gym.engines.numba_core.array` (a sensor array) and
  :mod:`~electroloc_gym.engines.numba_core.distractor_task`;
* :mod:`~electroloc_gym.engines.numba_core.step` — reset and step of N envs, through the task interface.

It keeps :mod:`electroloc_gym.contract` (parameters, layouts, shared rules) and imports nothing from
:mod:`electroloc_gym.envs` (the adapters import the engine).
"""
