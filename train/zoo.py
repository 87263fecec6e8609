r"""The rl-zoo3 hook: ``--gym-packages electroloc_gym.train.zoo`` trains on the native vector env.

Importing this module registers the envs (``import electroloc_gym``) and sets rl-zoo3's
``ExperimentManager.default_vec_env_cls`` to :func:`electroloc_gym.train.native_vec.zoo_vec_env`,
rl-zoo3's own hook for batched simulators, and pins every numeric library to one thread
(:func:`electroloc_gym.runtime.pin_threads`). ``rl_zoo3.train`` imports ``--gym-packages`` before it
builds its ExperimentManager; ``rl_zoo3.enjoy`` and ``record_video`` read the same attribute::

    python -m rl_zoo3.train --algo ppo --env ElectroLoc-v0 --gym-packages electroloc_gym.train.zoo \\
        --conf-file train/hyperparams/ppo.yml --seed 3000 --log-folder logs

``--gym-packages electroloc_gym`` alone trains the same hyper-parameters on rl-zoo3's default
``DummyVecEnv`` (benchmarks/train_fps.py compares the two).
"""

from __future__ import annotations

from rl_zoo3.exp_manager import ExperimentManager

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.runtime import pin_threads
from electroloc_gym.train.native_vec import zoo_vec_env

# staticmethod: rl-zoo3 reads it through an instance (self.default_vec_env_cls) and through the class (enjoy).
ExperimentManager.default_vec_env_cls = staticmethod(zoo_vec_env)  # type: ignore[assignment]
pin_threads()  # one thread per numeric library (torch included: rl-zoo3 imported it before this module)
