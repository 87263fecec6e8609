"""electroloc bench: the paper's controllers (and the shipped learned policies) on the paper's conditions.

Its options are :data:`~electroloc_gym.bench.config.BENCH_OPTIONS` (flags, help, checks and defaults declared
once, shared with :func:`electroloc_gym.bench.run`); a run is prepared by :func:`~electroloc_gym.bench.api.prepare`,
as the Python API prepares it, with every refused setting named by its flag.
"""

from __future__ import annotations

import argparse
import sys

from electroloc_gym.bench.api import _runs_on_map_env, prepare  # noqa: F401  (the map-env rule, named here too)
from electroloc_gym.bench.config import BENCH_OPTIONS, MAX_PARTICLES, MAX_READINGS, MAX_TRIALS, MAX_WORKERS
from electroloc_gym.bench.runner import run_benchmark
from electroloc_gym.options import add_options, ascii_int
from electroloc_gym.utils.fileio import user_path

__all__ = [
    "add_arguments",
    "run",
    "ascii_int",
    "DESCRIPTION",
    "EPILOG",
    "MAX_TRIALS",
    "MAX_WORKERS",
    "MAX_READINGS",
    "MAX_PARTICLES",
]

DESCRIPTION = (
    "Benchmark agents on the paper's eight conditions (Solberg, Lynch & MacIver 2008, Tables 4 and 1; "
    "--env global: Table 2; --env unknown-target: the eight pairs with the sphere hidden, paper §7) "
    "with seeded trials, and write trials.jsonl, summary.json, table.md and "
    "steps.png to the output folder."
)
EPILOG = """examples:
  electroloc bench --trials 50 --out bench_full                         the full reproduction
  electroloc bench --agents rnd-wlk,min-var --conditions fresh-steel-12.7,salt-delrin-38.1 --trials 10
  electroloc bench --agents min-var,ppo-belief --out bench_learned --resume
  electroloc bench --env global --trials 50 --out bench_global         Table 2 (ElectroLocGlobal-v0)
  electroloc bench --env unknown-target --out bench_unknown            size and material unknown (§7)
  electroloc bench --env dynamic-gain --out bench_gain                 the gain in the action (§7)
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bench`` options to ``parser``."""
    add_options(parser, BENCH_OPTIONS)


def _note(line: str) -> None:
    print(f"electroloc bench: {line}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Run the benchmark described by ``args``; print table.md; 0 on success, 2 on bad input."""
    try:
        config, options = prepare({o.name: getattr(args, o.name) for o in BENCH_OPTIONS}, lambda o: o.option, _note)
        run_benchmark(config, args.out, **options)
    except ValueError as exc:
        print(f"electroloc bench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"electroloc bench: interrupted; the finished trials are in {args.out}/trials.jsonl (--resume continues)",
            file=sys.stderr,
        )
        return 130
    print((user_path(args.out) / "table.md").read_text(encoding="utf-8"))
    return 0
