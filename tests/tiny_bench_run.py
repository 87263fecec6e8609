"""The tiny benchmark run the output-folder tests share: its settings, its command line and a run of it.

Two agents on two conditions, two trials each (eight records), with a small filter and a short cap: small
enough for a test to run it several times. :data:`TINY_CLI` is the same run as ``electroloc bench`` arguments.
"""

from __future__ import annotations

import os
from pathlib import Path

from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.bench.schema import TIMING_KEYS

TINY = dict(
    conditions=("fresh-steel-12.7", "salt-delrin-38.1"),
    trials=2,
    seed=3,
    n_particles=300,
    max_observations=6,
    sensor_model="analytic",
)
AGENTS = ("rnd-wlk", "zero-crossing[max_observations=60]")
TINY_CLI = [
    "--agents",
    "rnd-wlk,zero-crossing[max_observations=60]",
    "--conditions",
    "fresh-steel-12.7,salt-delrin-38.1",
    "--trials",
    "2",
    "--seed",
    "3",
    "--n-particles",
    "300",
    "--max-observations",
    "6",
    "--sensor-model",
    "analytic",
    "--no-progress",
]
ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def strip_timing(records) -> dict:
    """The records keyed by (condition, agent, trial), without their timing keys: what two runs must agree on."""
    return {
        (r["condition"], r["agent"], r["trial"]): {k: v for k, v in r.items() if k not in TIMING_KEYS} for r in records
    }


def run_tiny(out: Path, **kw):
    """Run the tiny benchmark into ``out`` on the serial backend, quietly; ``kw`` goes to ``run_benchmark``."""
    return run_benchmark(BenchConfig(agents=AGENTS, **TINY), out, backend="serial", progress=False, log=None, **kw)
