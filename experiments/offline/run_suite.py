"""Train, export and benchmark the offline baselines over seeds; resumable (a finished step is kept).

    python experiments/offline/run_suite.py --out experiments/offline/results [--only bc-lookahead] [--seeds 1,2,3,4,5]

Per (env, method, seed) of :data:`SUITE`: ``bc.py`` or ``td3_bc.py`` into
``OUT/<env-id>/<label>/seed-<k>/`` (policy/, curve.json), then ``electroloc bench --env NAME --agents <policy>
--trials T --seed 0`` into its ``bench/``: the benchmark's evaluation trials (the first T of each of the
env's conditions — eight, or the mapped tank's one; all 50 by default, the trials of the
learned suite's table), never seen in training. The shipped policy of the mixed data (ppo-belief) is
benched once on the same trials into ``OUT/<env-id>/_sources/bench``; the controllers' runs are the
learned suite's (``experiments/learned/results/<env-id>/_baselines/bench``). The reference datasets
(``make_datasets.py``) must exist under ``MINARI_DATASETS_PATH``.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import common  # noqa: E402

from electroloc_gym.bench.stored_run import load_config  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID, task_entry  # noqa: E402

TARGET, GLOBAL = PAPER_ENV_ID, task_entry("global").env_id
BC = ["--steps", "10000", "--eval-every", "2000"]
#: env id → label → (trainer, its options). The global env has the two planners' datasets only (no mix).
SUITE = {
    TARGET: {
        "bc-lookahead": ("bc.py", ["--datasets", f"electroloc/{TARGET}/lookahead-v0", *BC]),
        "bc-min-var": ("bc.py", ["--datasets", f"electroloc/{TARGET}/min-var-v0", *BC]),
        "td3bc-mixed": ("td3_bc.py", ["--steps", "20000", "--eval-every", "4000"]),
    },
    GLOBAL: {
        "bc-lookahead": ("bc.py", ["--env-id", GLOBAL, "--datasets", f"electroloc/{GLOBAL}/lookahead-v0", *BC]),
        "bc-min-var": ("bc.py", ["--env-id", GLOBAL, "--datasets", f"electroloc/{GLOBAL}/min-var-v0", *BC]),
    },
}
THREADS = {v: "1" for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def _bench_name(env_id: str) -> str:
    """The ``electroloc bench --env`` name of ``env_id`` (its row without extra arguments)."""
    from electroloc_gym.registry import BENCH_ENVS

    return next(name for name, (entry, row) in BENCH_ENVS.items() if entry.env_id == env_id and not row.env_kwargs)


def _bench(agent: str, out: Path, trials: int, env_id: str = TARGET) -> None:
    """``electroloc bench`` of ``agent`` into ``out``: kept when finished with ``trials``, resumed, or (finished
    with another trial count, or its ``config.json`` not a run's config: one line says which) run again from
    nothing.
    """
    config = out / "config.json"
    if config.is_file():
        try:
            stored = load_config(config).trials
        except ValueError as exc:  # one line naming the file
            print(f"{exc}; running its benchmark again from nothing", flush=True)
            shutil.rmtree(out)
        else:
            if stored != trials:
                print(f"{out}: its benchmark ran another number of trials; running it again with {trials}", flush=True)
                shutil.rmtree(out)
    if (out / "summary.json").is_file():
        return
    argv = [
        sys.executable,
        "-m",
        "electroloc_gym.cli",
        "bench",
        "--env",
        _bench_name(env_id),
        "--agents",
        agent,
        "--trials",
        str(trials),
        "--seed",
        "0",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-progress",
    ]
    if (out / "trials.jsonl").is_file():
        argv.append("--resume")
    subprocess.run(argv, check=True, env={**os.environ, **THREADS}, capture_output=True, text=True)


def _seeds(parser: argparse.ArgumentParser, text: str) -> list[int]:
    """``--seeds``: comma-separated integers in ASCII digits, each in [0, 2**32 − 1] (the trainers' range),
    at least one, none twice (else argparse's one-line error).
    """
    low, high, _ = common.RANGES["seed"]
    parts = [t.strip() for t in text.split(",")]
    if not all(re.fullmatch(r"[0-9]{1,10}", t) and low <= int(t) <= high for t in parts):
        parser.error(f"--seeds must be comma-separated integers in [{low}, {high}], got {text!r}")
    seeds = [int(t) for t in parts]
    if len(set(seeds)) != len(seeds):
        parser.error(f"--seeds names a seed more than once: {text!r}")
    return seeds


def main(argv: list[str] | None = None) -> int:
    """Run the plan."""
    from electroloc_gym.bench.bench_command import ascii_int

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=HERE / "results")
    parser.add_argument("--only", default="", help="comma-separated labels or env-id/label; default all")
    parser.add_argument("--seeds", default="1,2,3,4,5", help="comma-separated training seeds (0 … 2**32 − 1)")
    parser.add_argument("--trials", type=ascii_int, default=50, help="trials per condition (1 … 50)")
    args = parser.parse_args(argv)
    if not 1 <= args.trials <= 50:
        parser.error(f"--trials must be in [1, 50], got {args.trials}")
    try:
        common.check_folder("--out", args.out)
    except common.ArgumentError as exc:
        parser.error(str(exc))
    seeds = _seeds(parser, args.seeds)
    plan = [(env, label) for env, labels in SUITE.items() for label in labels]
    only = [x.strip() for x in args.only.split(",") if x.strip()]
    known = {label for _, label in plan} | {f"{env}/{label}" for env, label in plan}
    bad = [x for x in only if x not in known]
    if bad:
        parser.error(f"--only names {bad}; choose from {sorted(known)}")
    if only:
        plan = [(env, label) for env, label in plan if label in only or f"{env}/{label}" in only]
    if any(env == TARGET for env, _ in plan):
        _bench("ppo-belief", args.out / TARGET / "_sources" / "bench", args.trials)
    for env, label in plan:
        trainer, opts = SUITE[env][label]
        for seed in seeds:
            folder = args.out / env / label / f"seed-{seed}"
            if not (folder / "policy" / "policy.json").is_file():
                subprocess.run(
                    [sys.executable, str(HERE / trainer), *opts, "--seed", str(seed), "--out", str(folder)],
                    check=True,
                    env={**os.environ, **THREADS},
                )
            _bench(str(folder / "policy"), folder / "bench", args.trials, env)
            print(f"{env} {label} seed {seed}: done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
