"""RLlib sampling throughput with 1 and 2 env runners, the native env for reference, and a runner's start-up.

Measured in one run, on one machine:

* **native**: the native vector env of ``--num-envs`` tanks stepped in this process with random actions
  (no RLlib): the ceiling of one runner.
* **RLlib, k runners**: one PPO algorithm with 2 remote env runners, each stepping its own native vector
  env of ``--num-envs`` tanks through RLlib's sampling loop (module inference, connectors, episodes);
  env steps/s of runner 1 alone, then of runners 1 and 2 sampling at once (``foreach_env_runner``).
  On a cluster the total is per-runner throughput × runners while the learner keeps up.
* **start-up**: a fresh process that imports the package and builds, resets and steps the env (what a
  runner's ``make_env`` does), with an empty numba cache (``NUMBA_CACHE_DIR`` a new folder: every
  kernel compiled) and again with that cache warm (kernels loaded).

Usage::

    python benchmarks/rllib_sampling.py [--num-envs 16] [--seconds 10] [--out results.json]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import gymnasium as gym
import numpy as np

import electroloc_gym.train.rllib as erl
from electroloc_gym.registry import PAPER_ENV_ID
from electroloc_gym.utils.fileio import check_output_options, write_json_atomic
from electroloc_gym.utils.markdown import markdown_table
from electroloc_gym.utils.runtime import pin_threads

STARTUP_CODE = """
import time
t0 = time.perf_counter()
from electroloc_gym.train.rllib import make_env
from electroloc_gym.registry import PAPER_ENV_ID
env = make_env({"num_envs": %d})
env.reset(seed=0)
env.step(env.action_space.sample())
print(time.perf_counter() - t0)
"""


def native_steps_per_s(num_envs: int, seconds: float) -> float:
    env = gym.make_vec(PAPER_ENV_ID, num_envs=num_envs, vectorization_mode="vector_entry_point")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    env.step(rng.uniform(-1, 1, (num_envs, 2)).astype(np.float32))
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        env.step(rng.uniform(-1, 1, (num_envs, 2)).astype(np.float32))
        steps += num_envs
    return steps / (time.perf_counter() - t0)


def startup_s(num_envs: int, cache_dir: str) -> float:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir, **erl.runner_env_vars()}
    out = subprocess.run(
        [sys.executable, "-c", STARTUP_CODE % num_envs], env=env, check=True, capture_output=True, text=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def rllib_steps_per_s(num_envs: int, seconds: float) -> dict[str, float]:
    import ray
    from ray.rllib.algorithms.ppo import PPOConfig

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": erl.runner_env_vars()})
    try:
        t0 = time.perf_counter()
        algo = (
            PPOConfig()
            .environment(erl.register(), env_config={})
            .env_runners(
                num_env_runners=2,
                num_envs_per_env_runner=num_envs,
                gym_env_vectorize_mode="vector_entry_point",
                rollout_fragment_length=64,
            )
            .debugging(seed=0)
            .build_algo()
        )
        build_s = time.perf_counter() - t0
        group = algo.env_runner_group
        chunk = 64 * num_envs

        def sample(runner) -> int:
            return sum(len(ep) for ep in runner.sample(num_timesteps=chunk, explore=True))

        out: dict[str, float] = {"algo_build_s_2_runners_warm_cache": build_s}
        group.foreach_env_runner(sample, local_env_runner=False)  # warm-up (first reset, module)
        for ids in ([1], [1, 2]):
            steps, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                steps += sum(group.foreach_env_runner(sample, local_env_runner=False, remote_worker_ids=ids))
            out[f"rllib_{len(ids)}_runner_steps_per_s"] = steps / (time.perf_counter() - t0)
        algo.stop()
        return out
    finally:
        ray.shutdown()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--num-envs", type=int, default=16, help="tanks per runner (and in the native reference)")
    p.add_argument("--seconds", type=float, default=10.0, help="measuring time per row")
    p.add_argument("--out", default=None, help="also write the numbers to this JSON file")
    args = p.parse_args()
    check_output_options(p, files={"--out": args.out})
    pin_threads()
    erl.warm_kernels({})
    res: dict[str, float | int | str] = {
        "num_envs_per_runner": args.num_envs,
        "cpus": os.cpu_count() or 0,
        "load_average_1min_before": os.getloadavg()[0],
    }
    with tempfile.TemporaryDirectory() as cache:
        res["startup_s_cold_cache"] = startup_s(args.num_envs, cache)
        res["startup_s_warm_cache"] = startup_s(args.num_envs, cache)
    res["native_steps_per_s"] = native_steps_per_s(args.num_envs, args.seconds)
    res.update(rllib_steps_per_s(args.num_envs, args.seconds))
    res["load_average_1min_after"] = os.getloadavg()[0]
    for line in markdown_table(
        (f"sampler ({args.num_envs} tanks per runner)", "env steps/s"),
        [
            ("native vector env, this process (no RLlib)", f"{res['native_steps_per_s']:,.0f}"),
            ("RLlib, 1 env runner", f"{res['rllib_1_runner_steps_per_s']:,.0f}"),
            ("RLlib, 2 env runners at once", f"{res['rllib_2_runner_steps_per_s']:,.0f}"),
        ],
    ):
        print(line)
    print(
        f"\nrunner env start-up (fresh process: import, build, reset, step): cold numba cache "
        f"{res['startup_s_cold_cache']:.1f} s, warm {res['startup_s_warm_cache']:.1f} s; "
        f"PPO build with 2 runners (warm cache) {res['algo_build_s_2_runners_warm_cache']:.1f} s; "
        f"1-min load average {res['load_average_1min_before']:.1f} before, "
        f"{res['load_average_1min_after']:.1f} after "
        f"(on {res['cpus']} CPUs; above that, others share the cores)"
    )
    if args.out:
        write_json_atomic(args.out, res)


if __name__ == "__main__":
    main()
