r"""The rl-zoo3 hook: ``--gym-packages electroloc_gym.train.zoo`` trains on the native vector env.

Importing this module registers the envs (``import electroloc_gym``) and sets rl-zoo3's
``ExperimentManager.default_vec_env_cls`` to :func:`electroloc_gym.train.native_vec.zoo_vec_env`,
rl-zoo3's own hook for batched simulators, and pins every numeric library to one thread
(:func:`electroloc_gym.utils.runtime.pin_threads`). ``rl_zoo3.train`` imports ``--gym-packages`` before it
builds its ExperimentManager; ``rl_zoo3.enjoy`` and ``record_video`` read the same attribute::

    python -m rl_zoo3.train --algo ppo --env ElectroLoc-v0 --gym-packages electroloc_gym.train.zoo \\
        --conf-file electroloc_gym/train/hyperparams/ppo.yml --seed 3000 --log-folder logs

``--gym-packages electroloc_gym`` alone trains the same hyper-parameters on rl-zoo3's default
``DummyVecEnv`` (benchmarks/train_fps.py compares the two).
"""

from __future__ import annotations

from rl_zoo3.exp_manager import ExperimentManager

from electroloc_gym.train.native_vec import zoo_vec_env
from electroloc_gym.utils.runtime import pin_threads

# staticmethod: rl-zoo3 reads it through an instance (self.default_vec_env_cls) and through the class (enjoy).
ExperimentManager.default_vec_env_cls = staticmethod(zoo_vec_env)  # type: ignore[assignment]
pin_threads()  # one thread per numeric library (torch included: rl-zoo3 imported it before this module)


def main(argv: list[str] | None = None) -> int:
    """``python -m electroloc_gym.train.zoo SCRIPT ARGS…``: an rl-zoo3 script run with this hook installed.

    For the rl-zoo3 scripts without ``--gym-packages`` (``record_video``, ``record_training``); the
    others take ``--gym-packages electroloc_gym.train.zoo`` directly.
    """
    import importlib.util
    import runpy
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    scripts = ("train", "enjoy", "record_video", "record_training")
    if not args or args[0] not in scripts:
        print(f"error: SCRIPT must be one of {list(scripts)}, got {args[0] if args else None!r}", file=sys.stderr)
        return 2
    module = f"rl_zoo3.{args[0]}"
    if importlib.util.find_spec(module) is None:  # pragma: no cover - every rl-zoo3 2.x has them
        print(f"error: this rl-zoo3 has no {module}", file=sys.stderr)
        return 2
    sys.argv = [module, *args[1:]]
    runpy.run_module(module, run_name="__main__", alter_sys=True)
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main())
