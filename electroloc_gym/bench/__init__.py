"""The benchmark: the paper's controllers and learned policies on seeded trials (Tables 1, 2 and 4).

Modules, in the order a run uses them:

* :mod:`~electroloc_gym.bench.config` — what a run is (:class:`BenchConfig`), its trials and their seeds;
* :mod:`~electroloc_gym.bench.agents` — agent specs → agents (controllers, shipped models, paths);
* :mod:`~electroloc_gym.bench.default_run` — the agents of a run without ``--agents``, and why any is skipped;
* :mod:`~electroloc_gym.bench.schema` — the trial record (:class:`~electroloc_gym.bench.schema.TrialRecord`),
  the one declaration of what a line of trials.jsonl holds and how it is checked;
* :mod:`~electroloc_gym.bench.records` — the output folder: checked, locked, records parsed within bounds,
  keyed and validated against the run;
* :mod:`~electroloc_gym.bench.backends` (and :mod:`~electroloc_gym.bench.ray_backend`) — where trials run;
* :mod:`~electroloc_gym.bench.trials` and :mod:`~electroloc_gym.baselines.rollout` — one trial, one episode;
* :mod:`~electroloc_gym.bench.runner` — :func:`run_benchmark`, which ties them together;
* :mod:`~electroloc_gym.bench.stats`, :mod:`~electroloc_gym.bench.tables`, :mod:`~electroloc_gym.bench.plots`
  — Appendix-B statistics, the paper's table layouts, Fig. 12;
* :mod:`~electroloc_gym.bench.bench_command` — ``electroloc bench``; :mod:`~electroloc_gym.bench.api` — :func:`run`, the
  same from Python, with agent objects as well as specs.

Heavy modules (matplotlib, learned policies with torch) load lazily.
"""

from electroloc_gym.baselines.rollout import Episode, run_episode
from electroloc_gym.bench import ray_backend as _ray_backend  # noqa: F401  (registers "ray"; imports Ray lazily)
from electroloc_gym.bench.api import BenchResult, run
from electroloc_gym.bench.backends import BACKENDS, Backend, make_backend, register_backend
from electroloc_gym.bench.config import BenchConfig, TrialSpec, trial_seeds
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.bench.stats import summarize
from electroloc_gym.bench.trials import run_trial

__all__ = [
    "run",
    "BenchResult",
    "BACKENDS",
    "Backend",
    "make_backend",
    "register_backend",
    "BenchConfig",
    "TrialSpec",
    "run_benchmark",
    "run_trial",
    "run_episode",
    "Episode",
    "trial_seeds",
    "summarize",
]
