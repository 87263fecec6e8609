"""Benchmark runner: the paper's controllers and learned policies on seeded trials (Tables 1 and 4).

See :func:`electroloc_gym.bench.runner.run_benchmark` and the ``electroloc bench`` command
(:mod:`electroloc_gym.bench.cli`). Heavy modules (matplotlib, agents, policies) load lazily.
"""

from electroloc_gym.bench import ray_backend as _ray_backend  # noqa: F401  (registers "ray"; imports Ray lazily)
from electroloc_gym.bench.backends import BACKENDS, Backend, make_backend, register_backend
from electroloc_gym.bench.runner import BenchConfig, TrialSpec, run_benchmark, run_trial, trial_seeds
from electroloc_gym.bench.stats import summarize

__all__ = [
    "BACKENDS",
    "Backend",
    "make_backend",
    "register_backend",
    "BenchConfig",
    "TrialSpec",
    "run_benchmark",
    "run_trial",
    "trial_seeds",
    "summarize",
]
