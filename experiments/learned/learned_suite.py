"""The learned-baseline suite: several algorithms × training seeds, trained, exported and benchmarked.

One command trains every (env, algorithm, seed) of :data:`SUITE` through the project's one training
path (rl-zoo3 with the native vector env, :func:`electroloc_gym.train.run.train`), exports each run to
the pickle-free policy format, runs ``electroloc bench`` on the export (the benchmark's own protocol:
8 conditions × 50 trials, seed 0 — the same trials as the paper's controllers), benchmarks the
non-learned agents once per env, and hands the records to ``experiments/learned/learned_report.py`` (rliable).
It is resumable: a finished training run is found again by its exact rl-zoo3 command, an export
already made from it is kept, a benchmark with a ``summary.json`` is not rerun (an unfinished one
resumes with ``--resume``), so re-running the command only does what is missing.

Layout (what is kept in git: configs, args, evaluations, summaries and trial records — checkpoints,
monitors and exports are ignored by the folder's .gitignore, except the export of the seed the docs name)::

    RESULTS/<env-id>/<algo>/seed-<k>/zoo/<algo>/<env-id>_1/   rl-zoo3's run folder (config.yml, args.yml,
                                                              eval.csv, summary.json; checkpoints ignored)
    RESULTS/<env-id>/<algo>/seed-<k>/policy/                  the export (policy.json + policy.safetensors)
    RESULTS/<env-id>/<algo>/seed-<k>/bench/                   summary.json, trials.jsonl, table.md
    RESULTS/<env-id>/_baselines/bench/                        the non-learned agents on the same trials

Run (the full suite; hours on a 2-core machine — ``--only`` picks a part, ``--list`` prints the plan)::

    python experiments/learned/learned_suite.py --out experiments/learned/results
    python experiments/learned/learned_report.py experiments/learned/results

Invocations with disjoint ``--only`` sets may run side by side on one results folder (one per core):
each trains its own runs, the shared ``suite.json`` is updated under a lock, and a baseline benchmark
another invocation is running is left to it.

Hyper-parameters are the repository's files (electroloc_gym/train/hyperparams/, chosen on validation episodes,
reset seeds 100000+, never the benchmark's seed 0); every run shares one env-step budget
(``--timesteps``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from electroloc_gym.baselines.agent import RANDOM_AGENT, belief_agents
from electroloc_gym.baselines.infotaxis import InfotaxisAgent
from electroloc_gym.baselines.lookahead import LookaheadAgent
from electroloc_gym.baselines.min_variance import MinVarianceAgent
from electroloc_gym.registry import PAPER_ENV_ID, env_entry, task_entry
from electroloc_gym.train.summary import read_summary
from electroloc_gym.utils.agentspec import parse_options
from electroloc_gym.utils.runtime import thread_env

#: Training seeds of every configuration (disjoint from the benchmark's trial seeds by construction:
#: they seed the training envs and networks, not benchmark trials).
SEEDS = (1, 2, 3, 4, 5)
#: The env-step budget every configuration shares.
TIMESTEPS = 300_000
#: Checkpoints and other bulky run files the results folder does not keep in git.
GITIGNORE = (
    "*.zip\n*.pkl\n*.npz\nbest/\n*.log\n*.lock\n*.monitor.csv\nsteps.png\n**/tb/\nevents.out.tfevents.*\n"
    "# exports: only the seed the docs name is kept (a '!<env-id>/<label>/seed-<k>/policy/' line)\n"
    "policy/\n"
)


@dataclass(frozen=True)
class Config:
    """One learned configuration of the suite.

    Attributes:
        env_id: the registered env id.
        label: the results folder's name for it (``<results>/<env-id>/<label>/``).
        algo: the rl-zoo3 algorithm (its hyper-parameter file in electroloc_gym/train/hyperparams/).
        env_kwargs: env kwargs replacing the file's (rl-zoo3's ``--env-kwargs`` rule), or None.
        hyperparams: single hyper-parameter overrides, or None.
        note: what the configuration tests.
    """

    env_id: str
    label: str
    algo: str
    env_kwargs: Mapping[str, Any] | None = None
    hyperparams: Mapping[str, Any] | None = None
    note: str = ""


_RAW = {"condition": "random", "observation": "raw", "randomize_target": True}
_GLOBAL, _UNKNOWN, _TRACK = (task_entry(t).env_id for t in ("global", "unknown", "track"))

SUITE: tuple[Config, ...] = (
    Config(PAPER_ENV_ID, "ppo", "ppo", note="belief observation, continuous moves"),
    Config(PAPER_ENV_ID, "sac", "sac", note="belief observation, continuous moves"),
    Config(PAPER_ENV_ID, "a2c", "a2c", note="belief observation, continuous moves"),
    Config(PAPER_ENV_ID, "qrdqn", "qrdqn", note="belief observation, the discrete action mode (9 moves)"),
    Config(PAPER_ENV_ID, "crossq", "crossq", note="CrossQ (sb3-contrib): off-policy, batch renorm, no target network"),
    Config(
        PAPER_ENV_ID,
        "ppo_lstm-raw",
        "ppo_lstm",
        env_kwargs=_RAW,
        note="RecurrentPPO on the raw reading: memory instead of the belief",
    ),
    Config(
        PAPER_ENV_ID,
        "ppo-framestack-raw",
        "ppo",
        env_kwargs=_RAW,
        hyperparams={"frame_stack": 16, "n_envs": 8},
        note="PPO on the last 16 raw readings",
    ),
    Config(_GLOBAL, "ppo", "ppo", note="self-localisation in the mapped tank"),
    Config(_UNKNOWN, "ppo", "ppo", note="a sphere of unknown size and material"),
    Config(_TRACK, "ppo", "ppo", note="a target that swims: belief observation (the filter told a random walk)"),
    Config(
        _TRACK,
        "ppo-framestack-raw",
        "ppo",
        env_kwargs={"condition": "random", "observation": "raw", "randomize_target": True},
        hyperparams={"frame_stack": 16, "n_envs": 8},
        note="a target that swims: PPO on the last 16 raw readings",
    ),
    Config(_TRACK, "sac", "sac", note="a target that swims: SAC on the belief observation"),
    Config(_TRACK, "crossq", "crossq", note="a target that swims: CrossQ (sb3-contrib) on the belief observation"),
)

#: ``electroloc bench --env`` of each env id, and the non-learned agents benchmarked beside the learned ones.
BENCH_ENV = {c.env_id: env_entry(c.env_id).bench[0].name for c in SUITE}
BASELINE_AGENTS = {
    PAPER_ENV_ID: ",".join(belief_agents()),
    _GLOBAL: ",".join((RANDOM_AGENT, MinVarianceAgent.name, LookaheadAgent.name)),
    _UNKNOWN: ",".join((RANDOM_AGENT, MinVarianceAgent.name, InfotaxisAgent.name)),
    # the track's bench agents (rnd-wlk, min-var, pursuit), then the searchers and the hybrid, each that can with
    # the velocity belief too (the off-policy rows train with it); look-ahead plans over positions only
    _TRACK: ",".join(
        (
            RANDOM_AGENT,
            "pursuit",
            "pursuit[motion_model=swimmer]",
            MinVarianceAgent.name,
            f"{MinVarianceAgent.name}[motion_model=swimmer]",
            "hybrid",
            "hybrid[motion_model=swimmer]",
            InfotaxisAgent.name,
            f"{InfotaxisAgent.name}[motion_model=swimmer]",
            LookaheadAgent.name,
        )
    ),
}


@dataclass
class Plan:
    """What one invocation runs (the CLI's options)."""

    out: Path
    seeds: tuple[int, ...] = SEEDS
    timesteps: int = TIMESTEPS
    only: tuple[str, ...] = ()
    conditions: str | None = None
    trials: int = 50
    workers: int | None = None
    extra_hyperparams: dict[str, Any] = field(default_factory=dict)

    def configs(self) -> list[Config]:
        if not self.only:
            return list(SUITE)
        picked = [c for c in SUITE if f"{c.env_id}/{c.label}" in self.only or c.label in self.only]
        unknown = [o for o in self.only if not any(o in (c.label, f"{c.env_id}/{c.label}") for c in SUITE)]
        if unknown:
            raise ValueError(
                f"--only names no configuration: {unknown}; choose from "
                f"{sorted({c.label for c in SUITE} | {f'{c.env_id}/{c.label}' for c in SUITE})}"
            )
        return picked


def _bench(plan: Plan, env_id: str, agents: str, out: Path) -> None:
    """``electroloc bench`` into ``out`` (skipped when finished, resumed when started, left to the other
    invocation when another one is benchmarking it now).
    """
    if (out / "summary.json").is_file():
        return
    argv = [
        sys.executable,
        "-m",
        "electroloc_gym.cli",
        "bench",
        "--env",
        BENCH_ENV[env_id],
        "--agents",
        agents,
        "--trials",
        str(plan.trials),
        "--seed",
        "0",
        "--out",
        str(out),
        "--no-progress",
    ]
    if plan.conditions and env_entry(env_id).takes("condition"):
        argv += ["--conditions", plan.conditions]
    if plan.workers is not None:
        argv += ["--workers", str(plan.workers)]
    if (out / "trials.jsonl").is_file():
        argv.append("--resume")
    env = {**os.environ, **thread_env()}
    proc = subprocess.run(argv, env=env, capture_output=True, text=True)
    if proc.returncode != 0 and "in use by another electroloc bench run" in proc.stderr:
        print(f"{out} is being benchmarked by another invocation; it finishes it", flush=True)
        return
    if proc.returncode != 0:
        raise RuntimeError(f"electroloc bench failed for {out}: {proc.stderr.strip().splitlines()[-1:]}")


def run_config(plan: Plan, cfg: Config, seed: int) -> dict[str, Any]:
    """Train, export and benchmark one (configuration, seed); returns its line of ``suite.json``."""
    from electroloc_gym.train.run import train

    folder = plan.out / cfg.env_id / cfg.label / f"seed-{seed}"
    hyper = {**(cfg.hyperparams or {}), **plan.extra_hyperparams} or None
    t0 = time.time()
    run = train(
        cfg.algo,
        cfg.env_id,
        seed,
        timesteps=plan.timesteps,
        log_folder=folder / "zoo",
        out=folder / "policy",
        env_kwargs=cfg.env_kwargs,
        hyperparams=hyper,
        quiet=True,
    )
    trained = time.time() - t0
    _bench(plan, cfg.env_id, str(folder / "policy"), folder / "bench")
    summary = read_summary(run / "summary.json")
    return {
        "env_id": cfg.env_id,
        "label": cfg.label,
        "algo": cfg.algo,
        "seed": seed,
        "run": str(run),
        "train_wall_time_s": summary.wall_time_s,
        "fps_training_only": summary.fps_training_only,
        "this_call_s": round(trained, 1),
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("experiments/learned/results"), help="the results folder")
    parser.add_argument("--seeds", default=",".join(map(str, SEEDS)), help="comma-separated training seeds (≥ 0)")
    parser.add_argument("--timesteps", type=int, default=TIMESTEPS, help="the env-step budget of every run (≥ 1)")
    parser.add_argument("--only", default="", help="comma-separated labels (or env-id/label) to run; default all")
    parser.add_argument("--conditions", default=None, help="benchmark conditions (default: the paper's eight)")
    parser.add_argument("--trials", type=int, default=50, help="benchmark trials per condition (paper: 50)")
    parser.add_argument("--workers", type=int, default=None, help="benchmark worker processes")
    parser.add_argument(
        "--hyperparams",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="extra overrides for every run, as `electroloc train` takes them (e.g. a smaller "
        "n_envs or eval_freq for a smoke test)",
    )
    parser.add_argument("--list", action="store_true", help="print the plan and exit")
    args = parser.parse_args(argv)
    from electroloc_gym.utils.fileio import check_output_options

    check_output_options(parser, folders={"--out": args.out})
    try:
        seeds = tuple(int(s) for s in args.seeds.split(",") if s.strip())
    except ValueError:
        parser.error(f"--seeds must be comma-separated integers, got {args.seeds!r}")
    if not seeds or any(s < 0 for s in seeds):
        parser.error(f"--seeds must name at least one integer ≥ 0, got {args.seeds!r}")
    if args.timesteps < 1:
        parser.error(f"--timesteps must be ≥ 1, got {args.timesteps}")
    if args.trials < 1:
        parser.error(f"--trials must be ≥ 1, got {args.trials}")
    try:
        extra = parse_options(args.hyperparams, "--hyperparams")
    except ValueError as exc:
        parser.error(str(exc))
    plan = Plan(
        out=args.out,
        seeds=seeds,
        timesteps=args.timesteps,
        only=tuple(s.strip() for s in args.only.split(",") if s.strip()),
        conditions=args.conditions,
        trials=args.trials,
        workers=args.workers,
        extra_hyperparams=extra,
    )
    try:
        configs = plan.configs()
    except ValueError as exc:
        parser.error(str(exc))
    if args.list:
        for c in configs:
            print(f"{c.env_id:28s} {c.label:20s} {c.algo:9s} seeds {list(plan.seeds)}  {c.note}")
        return 0
    plan.out.mkdir(parents=True, exist_ok=True)
    if not (plan.out / ".gitignore").exists():
        (plan.out / ".gitignore").write_text(GITIGNORE, encoding="utf-8")
    from filelock import FileLock
    from tqdm import tqdm

    from electroloc_gym.utils.fileio import write_json_atomic

    log_path = plan.out / "suite.json"
    jobs = [(c, s) for c in configs for s in plan.seeds]
    for cfg, seed in tqdm(jobs, desc="learned suite", unit="run"):
        try:
            line = run_config(plan, cfg, seed)
        except (ValueError, RuntimeError, OSError) as exc:  # a failed training run or benchmark: one line
            text = str(exc).strip().splitlines()
            print(
                f"learned_suite: {cfg.env_id}/{cfg.label} seed {seed} failed: {text[0] if text else exc!r}",
                file=sys.stderr,
            )
            return 2
        with FileLock(str(log_path) + ".lock", timeout=600):  # invocations on disjoint --only share the log
            done = json.loads(log_path.read_text(encoding="utf-8")) if log_path.is_file() else []
            done = [d for d in done if (d["env_id"], d["label"], d["seed"]) != (cfg.env_id, cfg.label, seed)]
            write_json_atomic(log_path, done + [line])
    for env_id in sorted({c.env_id for c in configs}):
        _bench(plan, env_id, BASELINE_AGENTS[env_id], plan.out / env_id / "_baselines" / "bench")
    print(f"done: {len(jobs)} runs; the report: python experiments/learned/learned_report.py {plan.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
