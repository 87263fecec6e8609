"""PPO on ElectroLoc-v0 with RLlib's current API stack, on this machine or on a Ray cluster.

``--num-env-runners`` env runners (Ray actors) each step one native vector env of
``--num-envs-per-env-runner`` tanks (``gym_env_vectorize_mode="vector_entry_point"``: one batched core
per runner); the learner runs in this process. Ray starts locally unless ``--address`` names a running
cluster (``ray start --head`` there; docs/benchmark.md). At the end the policy is exported to the
project's pickle-free format (``OUT/model``), which ``electroloc bench --agents OUT/model`` runs::

    pip install -c constraints.txt -e ".[rllib]"
    python examples/rllib_ppo.py --timesteps 300000 --out runs/rllib-ppo
    python examples/rllib_ppo.py --address auto --num-env-runners 16 --timesteps 2000000 --out runs/rllib-ppo
    electroloc bench --agents runs/rllib-ppo/model --trials 50 --out bench_rllib

The network and PPO settings follow electroloc_gym/train/hyperparams/ppo.yml (SB3's run): a tanh MLP 128-128 for the
policy and another for the value, observations normalised by running statistics, 2048 steps per update
in minibatches of 256 for 10 epochs. ``OUT/progress.csv`` logs the return, length and success rate of the
training episodes per iteration, ``OUT/learning_curve.png`` plots it.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import sys
import time
from pathlib import Path

import electroloc_gym.train.rllib as erl
from electroloc_gym.bench.ray_backend import ray_missing
from electroloc_gym.utils.fileio import check_output_options
from electroloc_gym.utils.runtime import pin_threads

ENV_ID = "ElectroLoc-v0"
ENV_KWARGS = {"condition": "random", "observation": "belief", "randomize_target": True}
HIDDEN = [128, 128]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (every count checked ≥ 1, runners ≥ 0)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--timesteps", type=int, default=300_000, help="env steps to train for")
    p.add_argument("--time-limit", type=float, default=None, help="also stop after this many seconds of training")
    p.add_argument("--num-env-runners", type=int, default=1, help="Ray env-runner actors (0: sample in this process)")
    p.add_argument("--num-envs-per-env-runner", type=int, default=8, help="tanks in each runner's native vector env")
    p.add_argument("--train-batch", type=int, default=2048, help="env steps per PPO update")
    p.add_argument("--seed", type=int, default=1, help="runner k's vector env is reset with seed + k")
    p.add_argument("--address", default=None, help="a running Ray cluster ('auto', 'host:6379'); default: local Ray")
    p.add_argument("--n-particles", type=int, default=None, help="belief particles (default: the env's, 2500)")
    p.add_argument("--out", default="runs/rllib-ppo", help="folder for progress.csv and the exported model/")
    args = p.parse_args(argv)
    for name in ("timesteps", "num_envs_per_env_runner", "train_batch"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be ≥ 1, got {getattr(args, name)}")
    if args.num_env_runners < 0:
        p.error(f"--num-env-runners must be ≥ 0, got {args.num_env_runners}")
    check_output_options(p, folders={"--out": args.out})
    if importlib.util.find_spec("ray") is None:  # before any work: one line, as `electroloc bench --backend ray`
        p.error(ray_missing("examples/rllib_ppo.py", extra="rllib"))
    return args


def env_config(args: argparse.Namespace) -> dict:
    """What the creator (electroloc_gym.train.rllib.make_env) receives in every runner, plus RLlib's num_envs."""
    extra = {} if args.n_particles is None else {"n_particles": args.n_particles}
    return {"env_id": ENV_ID, **ENV_KWARGS, **extra}


def build_config(args: argparse.Namespace):
    """RLlib's PPOConfig: the native vector env per runner, SB3's network and PPO settings."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.connectors.env_to_module import MeanStdFilter
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    runners = max(args.num_env_runners, 1)
    return (
        PPOConfig()
        .environment(erl.register(), env_config=env_config(args))  # the creator: single env or native vector env
        .env_runners(
            num_env_runners=args.num_env_runners,
            num_envs_per_env_runner=args.num_envs_per_env_runner,
            gym_env_vectorize_mode="vector_entry_point",  # one native vector env per runner
            rollout_fragment_length=max(1, args.train_batch // (runners * args.num_envs_per_env_runner)),
            env_to_module_connector=lambda env, spaces=None, device=None: MeanStdFilter(),  # SB3's VecNormalize
            num_cpus_per_env_runner=1,
            sample_timeout_s=600.0,  # a loaded machine: wait for the runners rather than drop the iteration
        )
        .callbacks(on_episode_end=erl.success_callback)
        .training(
            train_batch_size_per_learner=args.train_batch,
            minibatch_size=min(256, args.train_batch),
            num_epochs=10,
            lr=[[0, 3e-4], [args.timesteps, 1e-6]],  # linear decay, as SB3's lin_3.0e-4
            gamma=0.99,
            lambda_=0.95,
            clip_param=0.2,
            entropy_coeff=0.0,
            vf_loss_coeff=0.5,
            vf_clip_param=1e6,  # no value-loss clipping (SB3 has none)
            use_kl_loss=False,  # SB3's PPO has only the clipped objective
            grad_clip=0.5,
            grad_clip_by="global_norm",
        )
        .rl_module(
            model_config=DefaultModelConfig(
                fcnet_hiddens=HIDDEN,
                fcnet_activation="tanh",
                vf_share_layers=False,
                free_log_std=True,  # SB3's ActorCriticPolicy: exported as one
            )
        )
        .debugging(seed=args.seed)
    )


def main(argv: list[str] | None = None) -> int:
    """Train, log progress.csv, export OUT/model; 0 on success."""
    args = parse_args(argv)
    import ray
    import torch

    pin_threads()  # the learner: one torch/BLAS thread unless $ELECTROLOC_THREADS (the runners: runner_env_vars)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    warm_s = erl.warm_kernels(env_config(args))  # compile the numba kernels once, before the runners load them
    print(f"kernels ready in {warm_s:.1f} s", flush=True)
    ray.init(
        address=args.address,
        runtime_env={"env_vars": erl.runner_env_vars()},
        include_dashboard=False,
        log_to_driver=False,
    )
    algo = build_config(args).build_algo()
    t0, steps = time.perf_counter(), 0
    fields = ["iteration", "env_steps", "wall_s", "episodes", "return_mean", "length_mean", "success_mean"]
    with open(out / "progress.csv", "w", newline="", encoding="utf-8") as f:
        log = csv.DictWriter(f, fieldnames=fields)
        log.writeheader()
        while steps < args.timesteps and (args.time_limit is None or time.perf_counter() - t0 < args.time_limit):
            result = algo.train()
            r = result.get("env_runners", {})
            steps = int(result["num_env_steps_sampled_lifetime"])
            row = {
                "iteration": result["training_iteration"],
                "env_steps": steps,
                "wall_s": round(time.perf_counter() - t0, 2),
                "episodes": int(r.get("num_episodes_lifetime", 0)),
                "return_mean": r.get("episode_return_mean"),
                "length_mean": r.get("episode_len_mean"),
                "success_mean": r.get(erl.SUCCESS_METRIC),
            }
            log.writerow(row)
            f.flush()
            print(json.dumps(row), flush=True)
    erl.export_ppo(
        algo,
        out / "model",
        env_id=ENV_ID,
        env_kwargs=ENV_KWARGS,
        hidden=HIDDEN,
        provenance={
            "commands": ["python examples/rllib_ppo.py " + " ".join(sys.argv[1:] if argv is None else argv)],
            "seed": args.seed,
            "timesteps": steps,
            "num_env_runners": args.num_env_runners,
            "num_envs_per_env_runner": args.num_envs_per_env_runner,
            "versions": {"ray": ray.__version__, "torch": torch.__version__},
        },
    )
    erl.plot_progress(out / "progress.csv", out / "learning_curve.png")
    print(f"exported {out / 'model'}; run it with: electroloc bench --agents {out / 'model'}", flush=True)
    algo.stop()
    ray.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
