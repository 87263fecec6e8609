"""Training throughput of the rl-zoo3 path: PPO with the native vector env vs rl-zoo3's default DummyVecEnv.

Both rows are the same command of :func:`electroloc_gym.train.run.zoo_argv` — ``python -m rl_zoo3.train
--algo ppo --env ElectroLoc-v0 --conf-file electroloc_gym/train/hyperparams/ppo.yml`` with the same seed, budget and
hyper-parameters — once with ``--gym-packages electroloc_gym.train.zoo`` (the native batched env behind
SB3's VecEnv) and once with ``--gym-packages electroloc_gym`` (rl-zoo3's DummyVecEnv). Each row is a
fresh rl-zoo3 process; its env steps per second of training (rollouts *and* gradient updates, the
validation episodes excluded) come from the run's own ``summary.json``. The host's speed drifts, so
the rows run in ``--passes`` interleaved passes (dummy, native, dummy, ...) and each row keeps its
best pass.

    python benchmarks/train_fps.py [--n-envs 16] [--timesteps 16384] [--passes 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from electroloc_gym.registry import PAPER_ENV_ID
from electroloc_gym.train.run import zoo_argv
from electroloc_gym.train.summary import read_summary
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options
from electroloc_gym.utils.runtime import thread_env

#: One validation episode at the start and the end only: the timing is of training.
CALLBACK = "callback:[{'electroloc_gym.train.callbacks.BenchEvalCallback':{'eval_freq':10**9,'n_episodes':1}}]"


def one_run(native: bool, timesteps: int, log_folder: Path, n_envs: int = 16) -> dict[str, Any]:
    """Run rl-zoo3 once in a fresh log folder; its summary.json's timing (read by
    :func:`~electroloc_gym.train.summary.read_summary`).
    """
    argv = zoo_argv("ppo", PAPER_ENV_ID, 0, timesteps=timesteps, log_folder=log_folder, native=native)
    env = {**os.environ, **thread_env()}
    subprocess.run(
        [sys.executable, *argv, "--hyperparams", CALLBACK, f"n_envs:{n_envs}"],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    (summary,) = Path(log_folder).glob("ppo/ElectroLoc-v0_*/summary.json")  # the folder is this run's alone
    s = read_summary(summary)  # its one schema
    return {"timesteps": s.timesteps, "fps": s.fps_training_only, "wall_time_s": s.wall_time_s}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-envs", type=int, default=16, help="the vector env's N (the file's n_envs: 16)")
    ap.add_argument("--timesteps", type=int, default=16384, help="env steps per run (16 envs x 256 = 4096 a rollout)")
    ap.add_argument("--passes", type=int, default=2, help="interleaved passes over the two rows (the best is kept)")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    check_output_options(ap, files={"--json": a.json})
    print(
        f"rl-zoo3 PPO on ElectroLoc-v0 (electroloc_gym/train/hyperparams/ppo.yml: n_steps 256, 10 epochs, 128x128; "
        f"{a.n_envs} envs), "
        f"{a.timesteps} steps per run, torch 1 thread, {a.passes} interleaved passes",
        flush=True,
    )
    best: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for p in range(a.passes):
            for kind in ("dummy", "native"):
                r = one_run(kind == "native", a.timesteps, Path(tmp) / f"{p}-{kind}", a.n_envs)
                print(f"  pass {p + 1} {kind:<7} {r['fps']:8.0f} steps/s", flush=True)
                if kind not in best or r["fps"] > best[kind]["fps"]:
                    best[kind] = r
    ratio = best["native"]["fps"] / best["dummy"]["fps"]
    print(f"{'vec env':<26} {'fps (training)':>15}")
    print(f"{'DummyVecEnv (rl-zoo3)':<26} {best['dummy']['fps']:>15.0f}")
    print(f"{'native (electroloc hook)':<26} {best['native']['fps']:>15.0f}")
    print(f"native / dummy: {ratio:.2f}x")
    res = {
        "n_envs": a.n_envs,
        "timesteps": a.timesteps,
        "passes": a.passes,
        "rows": best,
        "ratio_native_vs_dummy": ratio,
    }
    if a.json:
        atomic_write_text(a.json, json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
