"""PPO with the rollouts on the env's device: ElectroLoc-v0's torch backend, CleanRL style.

    python examples/ppo_torch.py --device cuda --num-envs 4096 --total-timesteps 20000000
    python examples/ppo_torch.py --device cpu --num-envs 64 --total-timesteps 200000

The env is ``gym.make_vec("ElectroLoc-v0", num_envs=N, vectorization_mode="vector_entry_point",
backend="torch", device=...)``: observations, rewards and flags come back as tensors on ``device`` and
the actions go in as tensors there, so a rollout never leaves the device (no numpy round trip, no
``.cpu()`` inside the loop; the episode statistics are summed on the device and read once an update).
The network, the advantage estimation and the clipped-PPO update are the CPU example's
(:mod:`ppo_minimal`, imported from beside this file), run on the same device. Autoreset is Gymnasium's
``NEXT_STEP`` as there: the reset step after an episode's end is masked out of the loss.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import gymnasium as gym
import torch

import electroloc_gym  # noqa: F401  (registers ElectroLoc-v0)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ppo_minimal import Agent, ppo_update  # noqa: E402  (the network and the update, on any device)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line options (CleanRL's names, plus the device)."""
    p = argparse.ArgumentParser(
        description=__doc__.split("\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    p.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    p.add_argument("--compile", action="store_true", help="torch.compile the env's step (fullgraph)")
    p.add_argument("--condition", default="random", help="a preset name, or 'random' (all eight)")
    p.add_argument("--num-envs", type=int, default=256)
    p.add_argument("--total-timesteps", type=int, default=2_000_000)
    p.add_argument("--num-steps", type=int, default=64, help="steps per env per rollout")
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--num-minibatches", type=int, default=8)
    p.add_argument("--update-epochs", type=int, default=4)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--eval-episodes", type=int, default=256)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--save", default=None, help="write the policy's state_dict here (torch.save)")
    args = p.parse_args(argv)
    if args.num_envs < 1 or args.num_steps < 1 or args.total_timesteps < args.num_envs * args.num_steps:
        p.error("need num_envs ≥ 1, num_steps ≥ 1 and total_timesteps ≥ num_envs × num_steps")
    return args


def make_envs(args: argparse.Namespace, num_envs: int, randomize_target: bool) -> gym.vector.VectorEnv:
    """The torch backend: ``num_envs`` tanks and particle filters as tensors on ``args.device``."""
    return gym.make_vec(
        "ElectroLoc-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        backend="torch",
        device=args.device,
        compile=args.compile,
        condition=args.condition,
        randomize_target=randomize_target,
    )


def train(args: argparse.Namespace) -> Agent:
    """Collect ``num_steps`` × ``num_envs`` transitions on the device, update with clipped PPO, repeat."""
    torch.manual_seed(args.seed)
    dev = torch.device(args.device)
    envs = make_envs(args, args.num_envs, randomize_target=True)
    obs_dim, act_dim = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    agent = Agent(obs_dim, act_dim).to(dev)
    optim = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    T, N = args.num_steps, args.num_envs
    obs_buf = torch.zeros((T, N, obs_dim), device=dev)
    act_buf = torch.zeros((T, N, act_dim), device=dev)
    logp_buf, rew_buf, done_buf, val_buf, valid_buf = (torch.zeros((T, N), device=dev) for _ in range(5))
    next_obs, _ = envs.reset(seed=args.seed)
    next_done = torch.zeros(N, device=dev)
    n_updates = args.total_timesteps // (T * N)
    t0 = time.time()
    for update in range(1, n_updates + 1):
        for g in optim.param_groups:  # linear learning-rate decay
            g["lr"] = args.learning_rate * (1.0 - (update - 1) / n_updates)
        ended = successes = readings = torch.zeros((), device=dev)  # this rollout's episodes, summed on device
        for t in range(T):
            obs_buf[t], valid_buf[t] = next_obs, 1.0 - next_done
            with torch.no_grad():
                action, logp, _, value = agent.act(next_obs)
            act_buf[t], logp_buf[t], val_buf[t] = action, logp, value
            next_obs, reward, term, trunc, info = envs.step(action.clamp(-1.0, 1.0))
            done = (term | trunc).float()
            rew_buf[t], done_buf[t] = reward.float(), done
            just = done * (1.0 - next_done)  # episodes that ended at this step (not the reset step after one)
            ended = ended + just.sum()
            successes = successes + (just * info["success"].float()).sum()
            readings = readings + (just * info["n_observations"].float()).sum()
            next_done = done
        with torch.no_grad():
            next_value = agent.value(next_obs)
        ppo_update(agent, optim, args, obs_buf, act_buf, logp_buf, rew_buf, done_buf, val_buf, valid_buf, next_value)
        if update % 10 == 0 or update == n_updates:  # one host read per report, outside the rollout
            n_ep = max(float(ended), 1.0)
            print(
                f"update {update}/{n_updates}  steps {update * T * N}  episodes {int(ended)}  "
                f"success {float(successes) / n_ep:.2f}  mean readings {float(readings) / n_ep:.1f}  "
                f"{update * T * N / (time.time() - t0):.0f} steps/s",
                flush=True,
            )
    envs.close()
    return agent


def evaluate(agent: Agent, args: argparse.Namespace) -> dict[str, float]:
    """Success rate and mean readings of the mean action: each sub-env's first episode, on fresh seeds."""
    n = args.eval_episodes
    envs = make_envs(args, n, randomize_target=False)
    obs, _ = envs.reset(seed=10_000 + args.seed)  # seeds disjoint from training's
    first_done = torch.zeros(n, dtype=torch.bool, device=obs.device)
    success = torch.zeros(n, dtype=torch.bool, device=obs.device)
    readings = torch.zeros(n, device=obs.device)
    while not bool(first_done.all()):  # at most 35 steps: every episode ends by the cap
        with torch.no_grad():
            obs, _, term, trunc, info = envs.step(agent.actor_mean(obs).clamp(-1.0, 1.0))
        new = (term | trunc) & ~first_done
        success = torch.where(new, info["success"], success)
        readings = torch.where(new, info["n_observations"].float(), readings)
        first_done |= new
    envs.close()
    return {"success_rate": float(success.float().mean()), "mean_readings": float(readings.mean())}


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Train, evaluate, optionally save; returns the evaluation figures."""
    args = parse_args(argv)
    if torch.device(args.device).type == "cpu":
        torch.set_num_threads(1)  # small networks on a CPU: one thread, the other cores left free
    agent = train(args)
    result = evaluate(agent, args)
    print(
        f"evaluation ({args.eval_episodes} episodes, mean action): success {result['success_rate']:.2f}, "
        f"mean readings {result['mean_readings']:.1f}"
    )
    if args.save:
        torch.save(agent.state_dict(), args.save)  # reload with torch.load(path, weights_only=True)
        print(f"wrote {args.save}")
    return result


if __name__ == "__main__":
    main()
