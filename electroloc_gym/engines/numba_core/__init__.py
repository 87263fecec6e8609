"""The reference engine: N envs of every task as numpy arrays, stepped by compiled numba kernels.

* :mod:`~electroloc_gym.engines.numba_core.state` — the explicit state arrays of N envs;
* :mod:`~electroloc_gym.engines.numba_core.task` — the task interface (what a task provides to the step) and the
  machinery the tasks share; :mod:`~electroloc_gym.engines.numba_core.worlds` — grouping envs by world, cached values;
* the localise family's shared task, :mod:`~electroloc_gym.engines.numba_core.localize_task` (one target), and its
  variants :mod:`~electroloc_gym.engines.numba_core.array` (a sensor array) and
  :mod:`~electroloc_gym.engines.numba_core.distractor_task`; then one module per task of the env table, which
  declares everything that is the task's own (:mod:`electroloc_gym.envs.table` names them);
* :mod:`~electroloc_gym.engines.numba_core.step` — reset and step of N envs, through the task interface.

It keeps :mod:`electroloc_gym.contract` (parameters, layouts, shared rules) and imports nothing from
:mod:`electroloc_gym.envs` (the adapters import the engine).
"""
