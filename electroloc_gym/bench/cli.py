"""``electroloc bench``: the paper's controllers (and shipped learned policies) on the paper's conditions.

Example (the full Table-4 / Table-1 reproduction)::

    electroloc bench --trials 50 --out bench_full
    electroloc bench --agents rnd-wlk,min-var --conditions fresh-steel-12.7,salt-delrin-38.1 --trials 10
    electroloc bench --agents min-var,models/ppo_belief --out bench_learned --resume
    electroloc bench --env global --trials 50 --out bench_global     # Table 2 (ElectroLocGlobal-v0)
"""

from __future__ import annotations

import argparse
import sys

from electroloc_gym.bench.backends import BACKENDS, default_workers
from electroloc_gym.bench.runner import (
    DEFAULT_AGENTS,
    GLOBAL_CONDITION,
    GLOBAL_ENV_ID,
    SENSOR_MODELS,
    SIGNALS,
    BenchConfig,
    discover_models,
    resolve_conditions,
    run_benchmark,
)

__all__ = ["add_arguments", "run", "default_agent_list"]


def default_agent_list() -> list[str]:
    """rnd-wlk, min-var, zero-crossing, plus any shipped learned policy (``models/*/model.zip``)."""
    return [*DEFAULT_AGENTS, *discover_models()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bench`` options to ``parser``."""
    parser.add_argument("--agents", default=None,
                        help="comma-separated agents: rnd-wlk, min-var, zero-crossing, NAME[key=value,...] "
                             "(e.g. min-var[n_voters=2500]), or a policy PATH.zip / directory with model.zip "
                             "(default: the three baselines plus models/*/model.zip if present)")
    parser.add_argument("--conditions", default="all", help="'all' or comma-separated preset names")
    parser.add_argument("--env", default="target", choices=["target", "global"],
                        help="target: ElectroLoc-v0 on the presets (Table 4/1); global: ElectroLocGlobal-v0, "
                             "self-localisation among six cylinders (Table 2; default agents rnd-wlk,min-var; "
                             "--conditions and --signal do not apply)")
    parser.add_argument("--trials", type=int, default=50, help="trials per condition and agent (paper: 50)")
    parser.add_argument("--seed", type=int, default=0, help="root seed of the per-trial seeds")
    parser.add_argument("--workers", type=int, default=None,
                        help=f"parallel worker processes (default: all cores = {default_workers()})")
    parser.add_argument("--backend", default="process", choices=sorted(BACKENDS),
                        help="where trials run (default: a local process pool)")
    parser.add_argument("--address", default=None,
                        help="cluster address for a distributed backend (e.g. --backend ray --address auto)")
    parser.add_argument("--sensor-model", default="calibrated", choices=list(SENSOR_MODELS),
                        help="the particle filter's sensor model (paper: calibrated)")
    parser.add_argument("--signal", default="fitted", choices=list(SIGNALS),
                        help="signal scale of the presets: fitted to Table 3's measured detection distances, "
                             "the paper's equations (scale 1), or coverage (fitted × ≈10, matching §6.3's 78%% of "
                             "starts inside the detection region)")
    parser.add_argument("--max-observations", type=int, default=35, help="observation cap of a trial (paper: 35)")
    parser.add_argument("--n-particles", type=int, default=2500, help="particles of the belief (paper: 2500)")
    parser.add_argument("--out", default="bench_out", help="output directory")
    parser.add_argument("--resume", action="store_true", help="skip trials already in OUT/trials.jsonl")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark described by ``args``; print table.md; 0 on success, 2 on bad input."""
    try:
        is_global = getattr(args, "env", "target") == "global"
        agents = [a.strip() for a in args.agents.split(",") if a.strip()] if args.agents else (
            ["rnd-wlk", "min-var"] if is_global else default_agent_list())
        conditions = (GLOBAL_CONDITION,) if is_global else tuple(resolve_conditions(args.conditions))
        if is_global:  # zero-crossing looks for one sphere; it has no meaning on the six-cylinder map
            from electroloc_gym.baselines.agent import make_agent

            bad = [a for a in agents if getattr(make_agent(a), "layout", "table4") != "table4"]
            if bad:
                raise ValueError(f"--env global runs particle-filter agents (Table 2); not applicable: {bad}")
        config = BenchConfig(agents=tuple(agents), conditions=conditions,
                             trials=args.trials, seed=args.seed, sensor_model=args.sensor_model, signal=args.signal,
                             max_observations=args.max_observations, n_particles=args.n_particles,
                             env_id=GLOBAL_ENV_ID if is_global else "ElectroLoc-v0")
        options = {} if args.address is None else {"address": args.address}
        run_benchmark(config, args.out, workers=args.workers, backend=args.backend, resume=args.resume,
                      progress=not args.no_progress, backend_options=options)
    except ValueError as exc:
        print(f"electroloc bench: error: {exc}", file=sys.stderr)
        return 2
    with open(f"{args.out}/table.md", encoding="utf-8") as f:
        print(f.read())
    return 0
