"""The speed figures side by side in one run, each against its target (docs/performance.md).

Runs, one after the other on this machine (each measurement in fresh processes, numeric libraries on
one thread):

1. ``benchmarks/vector_env.py``: single env, SyncVectorEnv and the native vector env at N = 16 and 64
   (belief observation, calibrated model, 2500 particles);
2. ``benchmarks/train_fps.py``: rl-zoo3 PPO training fps, DummyVecEnv vs the native adapter, N = 16 and
   64 (the current code only: ``--before`` compares the env rows, since a previous checkout's ``electroloc_gym/train/``
   is not importable beside this one's editable install);
3. unless ``--skip-table4``: the Table-4 reproduction, ``electroloc bench --agents
   rnd-wlk,min-var,zero-crossing`` (8 conditions × 3 agents × 50 trials, 2 workers), wall time.

and prints one table: figure, measured value, target, met or not. ``--json`` also writes it.

    python benchmarks/speed_report.py [--skip-table4] [--trials 50] [--before DIR] [--json out.json]

Takes about 2 minutes, plus about 4 for the Table-4 run. The machine may be shared: the env and fps
ratios are per CPU-second, best of several rounds (see the two scripts).
"""

from __future__ import annotations

from electroloc_gym.utils.runtime import pin_threads

pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import train_fps  # noqa: E402
import vector_env  # noqa: E402

from electroloc_gym.baselines.agent import PAPER_AGENTS  # noqa: E402
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options  # noqa: E402

TABLE4_AGENTS = ",".join(PAPER_AGENTS)


def table4_wall_s(trials: int, workers: int = 2) -> float:
    """Wall seconds of ``electroloc bench`` on the three baselines, all 8 conditions (a temp output dir)."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable,
            "-m",
            "electroloc_gym.cli",
            "bench",
            "--agents",
            TABLE4_AGENTS,
            "--trials",
            str(trials),
            "--workers",
            str(workers),
            "--out",
            out,
        ]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--skip-table4", action="store_true", help="do not time the Table-4 benchmark")
    ap.add_argument("--trials", type=int, default=50, help="trials per condition and agent in the Table-4 run")
    ap.add_argument("--json", default=None, help="also write the report here")
    ap.add_argument(
        "--before",
        default=None,
        metavar="DIR",
        help="a checkout of the previous code: its env rows are measured interleaved with these, and "
        "the single env's and the native env's steps/s must be at least its",
    )
    args = ap.parse_args(argv)
    check_output_options(ap, files={"--json": args.json})

    print("== env steps/s (benchmarks/vector_env.py)", flush=True)
    env = vector_env.main(["--n-envs", "16", "64"] + (["--before", args.before] if args.before else []))
    fps = {}
    for n in (16, 64):
        print(f"== PPO training fps, N = {n} (benchmarks/train_fps.py)", flush=True)
        fps[n] = train_fps.main(["--n-envs", str(n)])  # the current code only: see the module docstring

    rows: list[dict[str, Any]] = []

    def add(figure: str, value: float, unit: str, target: float | None, higher_is_better: bool = True) -> None:
        met = None if target is None else (value >= target if higher_is_better else value <= target)
        rows.append({"figure": figure, "value": value, "unit": unit, "target": target, "met": met})

    by = {(r["backend"], r["n_envs"]): r["steps_per_s_cpu"] for r in env["rows"] if r["code"] == "now"}
    before = {(r["backend"], r["n_envs"]): r["steps_per_s_cpu"] for r in env["rows"] if r["code"] == "before"}
    if before:
        add("single env steps/s, previous code", before[("single", 1)], "steps/s", None)
    add("single env steps/s", by[("single", 1)], "steps/s", before.get(("single", 1)))
    for n in (16, 64):
        add(f"SyncVectorEnv steps/s, N={n}", by[("sync", n)], "steps/s", None)
        if before:
            add(f"native vector env steps/s, N={n}, previous code", before[("native", n)], "steps/s", None)
        add(f"native vector env steps/s, N={n}", by[("native", n)], "steps/s", before.get(("native", n)))
        add(f"native / sync, N={n}", by[("native", n)] / by[("sync", n)], "x", 10.0 if n == 16 else None)
    for n in (16, 64):
        d = {kind: r["fps"] for kind, r in fps[n]["rows"].items()}
        add(f"PPO fps DummyVecEnv, N={n}", d["dummy"], "fps", None)
        add(f"PPO fps native adapter, N={n}", d["native"], "fps", None)
        add(f"PPO native / dummy, N={n}", d["native"] / d["dummy"], "x", 3.0)
    if not args.skip_table4:
        print(f"== Table-4 reproduction: electroloc bench --agents {TABLE4_AGENTS} --trials {args.trials}", flush=True)
        add(
            f"Table-4 benchmark (8 x 3 x {args.trials} trials) wall time",
            table4_wall_s(args.trials) / 60.0,
            "min",
            10.0,
            higher_is_better=False,
        )

    print("\n== targets")
    print(f"{'figure':<48} {'measured':>10}  {'target':>8}  met")
    for r in rows:
        tgt = "" if r["target"] is None else (f"≥ {r['target']:g}" if r["unit"] != "min" else f"≤ {r['target']:g}")
        met = "" if r["met"] is None else ("yes" if r["met"] else "NO")
        print(f"{r['figure']:<48} {r['value']:>10.2f}  {tgt:>8}  {met}")
    report = {"rows": rows, "vector_env": env, "train_fps": fps}
    if args.json:
        atomic_write_text(args.json, json.dumps(report, indent=2))
    return report


if __name__ == "__main__":
    main()
