"""Train, export and benchmark the offline baselines over seeds; resumable (a finished step is kept).

    python experiments/offline/run_suite.py --out experiments/offline/results [--only bc-lookahead] [--seeds 1,2,3,4,5]

Per (method, seed): ``bc.py`` or ``td3_bc.py`` into ``OUT/<env-id>/<label>/seed-<k>/`` (policy/, curve.json),
then ``electroloc bench --agents <policy> --trials T --seed 0`` into its ``bench/``: the benchmark's
evaluation trials (the first T of each of the eight conditions; all 50 by default, the trials of the
learned suite's table), never seen in training. The shipped policy of the mixed data (ppo-belief) is
benched once on the same trials into ``OUT/<env-id>/_sources/bench``; the controllers' runs are the
learned suite's (``experiments/learned/results/<env-id>/_baselines/bench``). The reference datasets
(``make_datasets.py``) must exist under ``MINARI_DATASETS_PATH``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ENV = "ElectroLoc-v0"
#: label → (trainer, its options)
SUITE = {
    "bc-lookahead": (
        "bc.py",
        ["--datasets", f"electroloc/{ENV}/lookahead-v0", "--steps", "10000", "--eval-every", "2000"],
    ),
    "bc-min-var": ("bc.py", ["--datasets", f"electroloc/{ENV}/min-var-v0", "--steps", "10000", "--eval-every", "2000"]),
    "td3bc-mixed": ("td3_bc.py", ["--steps", "20000", "--eval-every", "4000"]),
}
THREADS = {v: "1" for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def _bench(agent: str, out: Path, trials: int) -> None:
    """``electroloc bench`` of ``agent`` into ``out``: kept when finished with ``trials``, resumed, or (finished
    with another trial count) run again from nothing.
    """
    config = out / "config.json"
    if config.is_file() and json.loads(config.read_text(encoding="utf-8")).get("trials") != trials:
        print(f"{out}: its benchmark ran another number of trials; running it again with {trials}", flush=True)
        shutil.rmtree(out)
    if (out / "summary.json").is_file():
        return
    argv = [
        sys.executable,
        "-m",
        "electroloc_gym.cli",
        "bench",
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


def main(argv: list[str] | None = None) -> int:
    """Run the plan."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=HERE / "results")
    parser.add_argument("--only", default="", help="comma-separated labels; default all")
    parser.add_argument("--seeds", default="1,2,3,4,5")
    parser.add_argument("--trials", type=int, default=50, help="trials per condition (1 … 50)")
    args = parser.parse_args(argv)
    if not 1 <= args.trials <= 50:
        parser.error(f"--trials must be in [1, 50], got {args.trials}")
    labels = [s.strip() for s in args.only.split(",") if s.strip()] or list(SUITE)
    bad = [x for x in labels if x not in SUITE]
    if bad:
        parser.error(f"--only names {bad}; choose from {list(SUITE)}")
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    _bench("ppo-belief", args.out / ENV / "_sources" / "bench", args.trials)
    for label in labels:
        trainer, opts = SUITE[label]
        for seed in seeds:
            folder = args.out / ENV / label / f"seed-{seed}"
            if not (folder / "policy" / "policy.json").is_file():
                subprocess.run(
                    [sys.executable, str(HERE / trainer), *opts, "--seed", str(seed), "--out", str(folder)],
                    check=True,
                    env={**os.environ, **THREADS},
                )
            _bench(str(folder / "policy"), folder / "bench", args.trials)
            print(f"{label} seed {seed}: done", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
