"""SB3 PPO training throughput on ElectroLoc-v0: DummyVecEnv vs the native batched adapter.

Trains ``PPO("MlpPolicy")`` for a few short rollouts with each vector env at the same N (torch and
numpy on one thread, docs/performance.md) and prints env steps per second of training (rollouts *and*
gradient updates) side by side, per CPU-second of the process and per wall second, and the ratio.
Each configuration runs in a fresh interpreter after one warm-up rollout; the best of ``--rounds``
timed ``learn`` calls is kept. The host's speed drifts by ±20 % over minutes, so the two rows are
measured in ``--passes`` interleaved passes (dummy, native, dummy, native, ...) and each row's best
pass is kept: then both rows see the same phases.

    python benchmarks/train_fps.py [--n-envs 16] [--n-steps 64] [--rollouts 2] [--rounds 2] [--passes 3]
        [--particles 2500] [--before DIR] [--json out.json]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from electroloc_gym.fileio import atomic_write_text  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout: `train` importable


def _make_venv(kind: str, n: int, kwargs: dict[str, Any], seed: int) -> Any:
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    import electroloc_gym  # noqa: F401

    if kind == "native":
        from electroloc_gym.train.native_vec import make_native_vec_env

        return make_native_vec_env("ElectroLoc-v0", n, seed, kwargs)
    venv = DummyVecEnv([lambda: Monitor(gym.make("ElectroLoc-v0", **kwargs)) for _ in range(n)])
    venv.seed(seed)
    return venv


def measure(kind: str, n: int, n_steps: int, rollouts: int, rounds: int, kwargs: dict[str, Any]) -> dict[str, float]:
    """Best-of-``rounds`` training env steps/s (CPU, wall) of PPO on ``kind`` ("dummy" | "native")."""
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    venv = _make_venv(kind, n, kwargs, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=n_steps, batch_size=min(256, n * n_steps), n_epochs=4, seed=0,
                device="cpu", verbose=0)
    model.learn(n * n_steps)  # warm-up rollout + update
    steps = n * n_steps * rollouts
    best_cpu = best_wall = float("inf")
    for _ in range(rounds):
        c0, w0 = time.process_time(), time.perf_counter()
        model.learn(steps, reset_num_timesteps=False)
        best_cpu = min(best_cpu, time.process_time() - c0)
        best_wall = min(best_wall, time.perf_counter() - w0)
    venv.close()
    return {"fps_cpu": steps / best_cpu, "fps_wall": steps / best_wall, "timesteps": steps}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-envs", type=int, default=16)
    ap.add_argument("--n-steps", type=int, default=64, help="PPO n_steps (per env per rollout)")
    ap.add_argument("--rollouts", type=int, default=2, help="rollouts per timed learn() call")
    ap.add_argument("--rounds", type=int, default=2, help="timed learn() calls per process (the best is kept)")
    ap.add_argument("--passes", type=int, default=3, help="interleaved passes over the two rows (the best is kept)")
    ap.add_argument("--particles", type=int, default=2500)
    ap.add_argument("--condition", default="fresh-steel-12.7")
    ap.add_argument("--json", default=None)
    ap.add_argument("--before", default=None, metavar="DIR",
                    help="also measure the code of this checkout, interleaved with the current code's rows")
    ap.add_argument("--_one", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    kwargs = {"n_particles": args.particles, "condition": args.condition}
    if args._one:
        res = measure(args._one, args.n_envs, args.n_steps, args.rollouts, args.rounds, kwargs)
        print(json.dumps(res))
        return res
    print(f"PPO MlpPolicy on ElectroLoc-v0 {kwargs}, N={args.n_envs}, n_steps={args.n_steps}, n_epochs=4, "
          f"torch threads=1; best of {args.rounds} x {args.rollouts} rollouts per process, each row in a fresh "
          f"process, {args.passes} interleaved passes", flush=True)
    results: dict[str, Any] = {"kwargs": kwargs, "n_envs": args.n_envs, "rows": []}
    trees: list[tuple[str, str | None]] = [("now", None)] + ([("before", args.before)] if args.before else [])
    best: dict[tuple[str, str], dict[str, float]] = {}
    for _ in range(args.passes):
        for code, tree in trees:
            for kind in ("dummy", "native"):
                script = __file__ if tree is None else str(Path(tree) / "benchmarks" / "train_fps.py")
                env = None if tree is None else dict(os.environ, PYTHONPATH=str(Path(tree).resolve()))
                cmd = [sys.executable, script, "--_one", kind, "--n-envs", str(args.n_envs), "--n-steps",
                       str(args.n_steps), "--rollouts", str(args.rollouts), "--rounds", str(args.rounds),
                       "--particles", str(args.particles), "--condition", args.condition]
                out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
                r = json.loads(out.strip().splitlines()[-1])
                old = best.get((code, kind))
                if old is None or r["fps_cpu"] > old["fps_cpu"]:
                    best[(code, kind)] = {**r, "fps_wall": max(r["fps_wall"], old["fps_wall"] if old else 0.0)}
                else:
                    old["fps_wall"] = max(old["fps_wall"], r["fps_wall"])
    print(f"{'code':<7} {'vec env':<8} {'fps (CPU)':>10} {'fps (wall)':>11} {'vs dummy':>9}")
    for code, _ in trees:
        base = best[(code, "dummy")]["fps_cpu"]
        for kind in ("dummy", "native"):
            r = best[(code, kind)]
            ratio = r["fps_cpu"] / base
            print(f"{code:<7} {kind:<8} {r['fps_cpu']:>10.0f} {r['fps_wall']:>11.0f} {ratio:>8.2f}x", flush=True)
            results["rows"].append({"code": code, "vec_env": kind, **r, "ratio_vs_dummy_cpu": ratio})
    if args.json:
        atomic_write_text(args.json, json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main()
