"""Training on rl-zoo3 with the project's additions (needs the ``zoo`` extra).

``zoo`` (the ``--gym-packages`` hook: the native vector env under rl-zoo3), ``native_vec`` (SB3
``VecEnv`` of the native batched env), ``wrappers`` (potential-based shaping), ``callbacks``
(the benchmark's metrics on validation episodes, the chosen checkpoint exported pickle-free),
``export`` (an rl-zoo3 run folder → a policy folder), ``run`` (one call or command from algorithm,
env, seed and budget to run folder and export), ``curves`` (learning curves, the one reader of
``eval.csv``). Hyper-parameter files, one per algorithm in rl-zoo3's format: ``hyperparams/``. Loading a policy lives in
:mod:`electroloc_gym.policy`. Importing this package imports nothing heavy.
"""

__all__: list[str] = []
