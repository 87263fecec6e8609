"""electroloc bench: the paper's controllers (and the shipped learned policies) on the paper's conditions."""

from __future__ import annotations

import argparse
import re
import sys
from typing import Any

from electroloc_gym.baselines.agent import PAPER_AGENTS
from electroloc_gym.bench.agents import (
    agent_kind,
    cached_agent,
    policy_meta,
    shipped_model_env,
    shipped_models,
)
from electroloc_gym.bench.backends import BACKENDS, default_workers
from electroloc_gym.bench.config import (
    DEFAULT_ENV,
    ENV_CHOICES,
    ENV_N_PARTICLES,
    MAX_READINGS,
    SENSOR_MODELS,
    SIGNALS,
    BenchConfig,
    SettingError,
)
from electroloc_gym.bench.default_run import default_agents
from electroloc_gym.bench.ray_backend import check_ray_address
from electroloc_gym.bench.runner import MAX_PLANNED_TRIALS, run_benchmark
from electroloc_gym.contract.params import MIN_OBSERVATION_CAP
from electroloc_gym.protocol import MAX_OBSERVATIONS, N_PARTICLES
from electroloc_gym.registry import BENCH_ENVS, PAPER_ENV_ID, BenchEnv, bench_env, resolve_env_name
from electroloc_gym.utils.agentspec import split_specs
from electroloc_gym.utils.fileio import check_output_folder
from electroloc_gym.world.conditions import DEFAULT_SIGNAL
from electroloc_gym.world.distractors import MAX_DISTRACTORS
from electroloc_gym.world.sensor_array import LAYOUT_NAMES

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

#: Bounds of the numeric options: far beyond the paper (50 trials, 2500 particles), short of what cannot run
#: (the plan is held in memory: at most MAX_PLANNED_TRIALS trials in all). The cap of readings is a run
#: setting, checked by the settings object (:data:`~electroloc_gym.bench.config.MAX_READINGS`).
MAX_TRIALS = 100_000
MAX_WORKERS = 1024
MAX_PARTICLES = 1_000_000

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


_ASCII_INT = re.compile(r"-?[0-9]+")


def ascii_int(text: str) -> int:
    """An integer written in ASCII digits (``int`` also takes other scripts' digits, ``_`` and spaces)."""
    if not isinstance(text, str) or not _ASCII_INT.fullmatch(text) or len(text) > 40:
        raise argparse.ArgumentTypeError(f"must be an integer in ASCII digits, got {text!r}")
    return int(text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bench`` options to ``parser``."""
    parser.add_argument(
        "--agents",
        default=None,
        help=f"comma-separated agents: {', '.join(PAPER_AGENTS)}, NAME[key=value,...] "
        "(e.g. min-var[n_voters=2500]), a shipped model by name (e.g. ppo-belief), or a "
        "path to a model folder, or package.module:factory[key=value,...] (a factory of your "
        "own, imported like any module: it runs your code) (default: the three controllers "
        "plus every shipped model that runs here; the run says which and why one is skipped)",
    )
    parser.add_argument("--conditions", default="all", help="'all' or comma-separated preset names")
    parser.add_argument(
        "--env",
        default=DEFAULT_ENV,
        help="; ".join(f"{name}: {entry.env_id} {row.summary}".rstrip() for name, (entry, row) in BENCH_ENVS.items())
        + "; or package.module:NAME, a bench name your own module registers (a task of your own, "
        "electroloc_gym.tasks): imported like any module, it runs your code (default: %(default)s)",
    )
    parser.add_argument(
        "--trials",
        type=ascii_int,
        default=50,
        help=f"trials per condition and agent (paper: 50; at most {MAX_TRIALS:,}, and {MAX_PLANNED_TRIALS:,} in all)",
    )
    parser.add_argument("--seed", type=ascii_int, default=0, help="root seed of the per-trial seeds")
    parser.add_argument(
        "--workers",
        type=ascii_int,
        default=None,
        help=f"parallel worker processes (default: all cores, here {default_workers()})",
    )
    parser.add_argument(
        "--backend",
        default="process",
        choices=sorted(BACKENDS),
        help="where trials run: a local process pool, in-process (serial), or Ray",
    )
    parser.add_argument(
        "--address", default=None, help="cluster address for a distributed backend (e.g. --backend ray --address auto)"
    )
    parser.add_argument(
        "--sensor-model",
        default=None,
        choices=list(SENSOR_MODELS),
        help="the particle filter's sensor model (default: calibrated, the paper's; "
        "unknown-target: analytic, the theoretical EEV, or interpolated)",
    )
    parser.add_argument(
        "--signal",
        default=DEFAULT_SIGNAL,
        choices=list(SIGNALS),
        help="signal scale of the presets: fitted to Table 3's measured detection distances, "
        "coverage (fitted × one factor matching §6.3's 78%% of starts inside the detection "
        "region), or the paper's equations (scale 1); docs/fidelity.md compares them",
    )
    parser.add_argument(
        "--sensor-layout",
        default=None,
        choices=list(LAYOUT_NAMES),
        help=f"{PAPER_ENV_ID}'s sensing pairs (§7; observations = snapshots, K readings each)",
    )
    parser.add_argument(
        "--distractors",
        type=ascii_int,
        default=0,
        help=f"D objects that are not the target drawn per trial in the tank (ElectroLoc-v0's "
        f"distractors=D, 0–{MAX_DISTRACTORS}; in the true reading only; default 0)",
    )
    parser.add_argument(
        "--max-observations",
        type=ascii_int,
        default=None,
        help=f"the cap of readings of a trial, the reset's included: {MIN_OBSERVATION_CAP}–{MAX_READINGS} "
        f"(default: the env's, {MAX_OBSERVATIONS} as the paper)",
    )
    parser.add_argument(
        "--n-particles",
        type=ascii_int,
        default=None,
        help=f"particles of the belief (default: the env's, {N_PARTICLES} as the paper; unknown-target: "
        f"{ENV_N_PARTICLES[ENV_CHOICES['unknown-target']]})",
    )
    parser.add_argument("--out", default="bench_out", help="output folder (locked while the run writes to it)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out: run only the trials not yet in its trials.jsonl (each "
        "record's seeds and settings are checked; damaged lines are set aside and re-run)",
    )
    parser.add_argument(
        "--trust-pickle",
        action="store_true",
        help="also load learned policies stored as a bare SB3 .zip, which unpickles code from "
        "the file: only for files you trust",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _runs_on_map_env(spec: str, env_id: str) -> bool:
    """On an env of one fixed map: a particle-filter controller, a user's factory agent, or a policy (shipped
    or a path) trained on that env.
    """
    kind = agent_kind(spec)
    if kind == "baseline":
        return getattr(cached_agent(spec), "table_layout", "table4") == "table4"
    if kind == "shipped":
        return shipped_model_env(shipped_models()[spec]) == (env_id, None)
    if kind == "path":
        meta = policy_meta(spec) or {}
        obs_entry = meta.get("observation")
        obs: dict[str, Any] = obs_entry if isinstance(obs_entry, dict) else {}
        return bool(obs.get("env_id") == env_id)
    return kind in ("factory", "object")


def _agents(args: argparse.Namespace, env_id: str, row: BenchEnv) -> tuple[list[str], list[str]]:
    """The run's agent specs (``--agents``, else the bench row's defaults), and the notes a default list
    prints once the run's settings are valid: what it skipped and why.
    """
    if args.agents is not None:
        try:
            specs = split_specs(args.agents)
        except ValueError as exc:
            raise ValueError(f"--agents: {exc}") from None
        if not any(specs):
            raise ValueError(f"--agents names no agent (got {args.agents!r}); leave it out for the default set")
        if not all(specs):
            raise ValueError(f"--agents has an empty item in {args.agents!r}")
        for spec in specs:
            try:
                agent_kind(spec)
            except ValueError as exc:
                raise ValueError(f"--agents: {exc}") from None
        return specs, []
    choices = default_agents(
        names=row.agents,
        trust_pickle=args.trust_pickle,
        env_id=env_id,
        gain_levels=row.env_kwargs.get("gain_levels"),
        sensor_layout=args.sensor_layout,
    )
    notes = []
    elsewhere = [f"{c.spec} ({c.runs_with})" for c in choices if c.skipped and c.runs_with]
    if elsewhere:  # expected, not a warning: the policy belongs to another run
        notes.append(
            f"electroloc bench: the shipped policies trained for other settings run there: {', '.join(elsewhere)}"
        )
    notes += [f"electroloc bench: skipping {c.spec}: {c.skipped}" for c in choices if c.skipped and not c.runs_with]
    return [c.spec for c in choices if not c.skipped], notes


def _print_notes(notes: list[str]) -> None:
    for note in notes:
        print(note, file=sys.stderr)


def _check_ranges(args: argparse.Namespace) -> None:
    """Every numeric option in its range (one line naming the option)."""
    for option, value, low, high in (
        ("--trials", args.trials, 1, MAX_TRIALS),
        ("--seed", args.seed, 0, 2**63 - 1),
        ("--workers", args.workers, 1, MAX_WORKERS),
        ("--distractors", getattr(args, "distractors", 0), 0, MAX_DISTRACTORS),
        ("--n-particles", args.n_particles, 2, MAX_PARTICLES),
    ):
        if value is not None and not low <= value <= high:
            raise ValueError(f"{option} must be an integer in [{low}, {high}], got {value}")
    if args.address is not None and args.backend != "ray":
        raise ValueError(f"--address applies to --backend ray only (got --backend {args.backend})")
    check_output_folder("--out", args.out)  # the rule of every command's outputs, before any work


def _config(args: argparse.Namespace, env_name: str, agents: list[str]) -> BenchConfig:
    """The run's settings from the options (:meth:`BenchConfig.build`, as the Python API builds them); a
    setting out of its range is reported under its option's name.
    """
    try:
        return BenchConfig.build(
            agents,
            env=env_name,
            conditions=args.conditions,
            trials=args.trials,
            seed=args.seed,
            sensor_model=args.sensor_model,
            signal=args.signal,
            max_observations=args.max_observations,
            n_particles=args.n_particles,
            sensor_layout=args.sensor_layout,
            distractors=getattr(args, "distractors", 0),
        )
    except SettingError as exc:
        raise ValueError(f"--{exc.setting.replace('_', '-')} must be {exc.allowed}, got {exc.got}") from None


def run(args: argparse.Namespace) -> int:
    """Run the benchmark described by ``args``; print table.md; 0 on success, 2 on bad input."""
    try:
        _check_ranges(args)
        if args.backend == "ray":  # Ray installed and the cluster reachable, before --out is touched
            check_ray_address(args.address)
        env_name = resolve_env_name(getattr(args, "env", DEFAULT_ENV), "--env")  # MODULE:NAME imports MODULE
        entry, row = bench_env(env_name)
        env_id = entry.env_id
        agents, notes = _agents(args, env_id, row)
        if not agents:  # every default skipped: the notes say why
            _print_notes(notes)
            raise ValueError("--agents names no agent")
        layout_rows = [n for n, (e, r) in BENCH_ENVS.items() if e.takes("sensor_layout") and not r.env_kwargs]
        if args.sensor_layout is not None and env_name not in layout_rows:
            raise ValueError(f"--sensor-layout applies to --env {' or '.join(layout_rows)}, got --env {env_name}")
        config = _config(args, env_name, agents)
        _print_notes(notes)
        if entry.map_condition is not None:  # zero-crossing looks for one sphere; a policy must know the map
            bad = [a for a in agents if not _runs_on_map_env(a, env_id)]
            if bad:
                raise ValueError(
                    f"--env {env_name} runs the particle-filter controllers (Table 2), policies "
                    f"trained on {env_id} and users' factory agents; not applicable: {bad}"
                )
        options = {} if args.address is None else {"address": args.address}
        run_benchmark(
            config,
            args.out,
            workers=args.workers,
            backend=args.backend,
            resume=args.resume,
            progress=not args.no_progress,
            backend_options=options,
            trust_pickle=args.trust_pickle,
        )
    except ValueError as exc:
        print(f"electroloc bench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"electroloc bench: interrupted; the finished trials are in {args.out}/trials.jsonl (--resume continues)",
            file=sys.stderr,
        )
        return 130
    with open(f"{args.out}/table.md", encoding="utf-8") as f:
        print(f.read())
    return 0
