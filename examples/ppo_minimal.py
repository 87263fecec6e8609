"""Minimal PPO on the native vector env, CleanRL style: one file, torch only, no Stable-Baselines3.

    python examples/ppo_minimal.py --total-timesteps 300000 --save ppo_minimal.pt

Trains a Gaussian MLP policy on ``gym.make_vec("ElectroLoc-v0", num_envs=8,
vectorization_mode="vector_entry_point")`` — N tanks and N particle filters stepped as arrays — and
evaluates the mean action on fresh seeds at the end. Copy it and change what you like.

Two details of this env that a PPO loop must get right:

* Autoreset is Gymnasium's default ``NEXT_STEP``: the step *after* a sub-env finishes only resets it
  (its action is ignored, reward 0). Those reset transitions are masked out of the loss (``valid``).
* An episode ends at the observation cap (35 readings) and the observation carries the fraction of
  the cap used, so the cap is part of the task: truncation is treated as a terminal state, like
  termination.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np
import torch
import torch.nn as nn
from torch.distributions import Normal

import electroloc_gym  # noqa: F401  (registers ElectroLoc-v0)
from electroloc_gym.cli import HelpFormatter
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import check_output_options
from electroloc_gym.utils.runtime import pin_threads


def build_parser() -> argparse.ArgumentParser:
    """The command line (CleanRL's option names); ``--help`` shows every option's default."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=HelpFormatter)
    p.add_argument("--env-id", default="ElectroLoc-v0", help="a registered id with a native vector env")
    p.add_argument("--condition", default="fresh-steel-12.7", help="a preset name, or 'random' (all eight)")
    p.add_argument(
        "--randomize-target",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="train with the target anywhere in the start box (else the policy can memorise the "
        "paper's centred target); evaluation always uses the paper's fixed target (default: on)",
    )
    p.add_argument("--num-envs", type=int, default=8, help="sub-envs of the native vector env (N ≥ 1)")
    p.add_argument("--total-timesteps", type=int, default=300_000, help="env steps to train for (all sub-envs)")
    p.add_argument("--num-steps", type=int, default=128, help="steps per env per rollout")
    p.add_argument("--learning-rate", type=float, default=3e-4, help="Adam's step size")
    p.add_argument("--gamma", type=float, default=0.99, help="discount factor")
    p.add_argument("--gae-lambda", type=float, default=0.95, help="λ of the generalised advantage estimate")
    p.add_argument("--num-minibatches", type=int, default=8, help="minibatches per rollout")
    p.add_argument("--update-epochs", type=int, default=10, help="passes over each rollout")
    p.add_argument("--clip-coef", type=float, default=0.2, help="PPO's clip range of the probability ratio")
    p.add_argument("--ent-coef", type=float, default=0.0, help="weight of the entropy bonus")
    p.add_argument("--vf-coef", type=float, default=0.5, help="weight of the value loss")
    p.add_argument("--max-grad-norm", type=float, default=0.5, help="gradients clipped to this global norm")
    p.add_argument("--eval-episodes", type=int, default=64, help="evaluation episodes at the end (fresh seeds)")
    p.add_argument("--seed", type=int, default=1, help="seed of the envs, the network and the sampling")
    p.add_argument("--save", default=None, help="write the policy's state_dict here (torch.save)")
    return p


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options of ``argv`` (the command line when None), checked."""
    p = build_parser()
    args = p.parse_args(argv)
    if args.num_envs < 1 or args.num_steps < 1 or args.total_timesteps < args.num_envs * args.num_steps:
        p.error("need num_envs ≥ 1, num_steps ≥ 1 and total_timesteps ≥ num_envs × num_steps")
    check_output_options(p, files={"--save": args.save})  # before training, not after
    return args


def layer(n_in: int, n_out: int, std: float = np.sqrt(2)) -> nn.Linear:
    """A linear layer with orthogonal weights of gain ``std`` and zero bias."""
    lin = nn.Linear(n_in, n_out)
    nn.init.orthogonal_(lin.weight, std)
    nn.init.zeros_(lin.bias)
    return lin


class Agent(nn.Module):
    """Separate actor and critic MLPs (64×64, tanh); state-independent log std."""

    def __init__(self, obs_dim: int, act_dim: int) -> None:
        super().__init__()
        self.critic = nn.Sequential(layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, 1, 1.0))
        self.actor_mean = nn.Sequential(
            layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, act_dim, 0.01)
        )
        self.actor_logstd = nn.Parameter(torch.full((1, act_dim), -0.5))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def act(self, x: torch.Tensor, action: torch.Tensor | None = None):
        mean = self.actor_mean(x)
        dist = Normal(mean, self.actor_logstd.expand_as(mean).exp())
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action).sum(-1), dist.entropy().sum(-1), self.value(x)


def ppo_update(
    agent: Agent,
    optim: torch.optim.Optimizer,
    args: argparse.Namespace,
    obs_buf: torch.Tensor,
    act_buf: torch.Tensor,
    logp_buf: torch.Tensor,
    rew_buf: torch.Tensor,
    done_buf: torch.Tensor,
    val_buf: torch.Tensor,
    valid_buf: torch.Tensor,
    next_value: torch.Tensor,
) -> None:
    """GAE over a (T, N) rollout, then clipped-PPO epochs over its valid transitions (any one device)."""
    T, N = rew_buf.shape
    with torch.no_grad():  # generalised advantage estimation; an ended episode bootstraps nothing
        adv = torch.zeros_like(rew_buf)
        last = torch.zeros_like(next_value)
        for t in reversed(range(T)):
            v_next = next_value if t == T - 1 else val_buf[t + 1]
            nonterminal = 1.0 - done_buf[t]
            delta = rew_buf[t] + args.gamma * v_next * nonterminal - val_buf[t]
            last = delta + args.gamma * args.gae_lambda * nonterminal * last
            adv[t] = last
        ret = adv + val_buf
    keep = valid_buf.reshape(-1).bool()  # drop the reset transitions of NEXT_STEP autoreset
    b_obs, b_act = obs_buf.reshape(T * N, -1)[keep], act_buf.reshape(T * N, -1)[keep]
    b_logp, b_adv = logp_buf.reshape(-1)[keep], adv.reshape(-1)[keep]
    b_ret, b_val = ret.reshape(-1)[keep], val_buf.reshape(-1)[keep]
    n = b_obs.shape[0]
    mb = max(1, n // args.num_minibatches)
    for _ in range(args.update_epochs):
        perm = torch.randperm(n, device=b_obs.device)
        for start in range(0, n, mb):
            idx = perm[start : start + mb]
            _, logp, entropy, value = agent.act(b_obs[idx], b_act[idx])
            ratio = (logp - b_logp[idx]).exp()
            a = b_adv[idx]
            a = (a - a.mean()) / (a.std() + 1e-8) if len(idx) > 1 else a
            pg_loss = torch.max(-a * ratio, -a * ratio.clamp(1 - args.clip_coef, 1 + args.clip_coef)).mean()
            v_clipped = b_val[idx] + (value - b_val[idx]).clamp(-args.clip_coef, args.clip_coef)
            v_loss = 0.5 * torch.max((value - b_ret[idx]) ** 2, (v_clipped - b_ret[idx]) ** 2).mean()
            loss = pg_loss - args.ent_coef * entropy.mean() + args.vf_coef * v_loss
            optim.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
            optim.step()


def make_envs(args: argparse.Namespace, num_envs: int, randomize_target: bool) -> gym.vector.VectorEnv:
    """The native vector env: ``num_envs`` tanks and particle filters stepped as arrays."""
    return gym.make_vec(
        args.env_id,
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        condition=args.condition,
        randomize_target=randomize_target,
    )


def train(args: argparse.Namespace) -> Agent:
    """Collect ``num_steps`` × ``num_envs`` transitions, update with clipped PPO, repeat."""
    torch.manual_seed(args.seed)
    envs = make_envs(args, args.num_envs, args.randomize_target)
    obs_dim, act_dim = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    agent = Agent(obs_dim, act_dim)
    optim = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    T, N = args.num_steps, args.num_envs
    obs_buf = torch.zeros((T, N, obs_dim))
    act_buf = torch.zeros((T, N, act_dim))
    logp_buf, rew_buf, done_buf, val_buf, valid_buf = (torch.zeros((T, N)) for _ in range(5))

    next_obs = torch.as_tensor(envs.reset(seed=args.seed)[0])
    next_done = torch.zeros(N)  # did the previous step end an episode (so this step only resets it)?
    n_updates = args.total_timesteps // (T * N)
    rate = env_entry(args.env_id).task_class.metrics.rate  # the task's rate: success (capture, moving target)
    lengths: list[int] = []
    rates: list[float] = []
    t0 = time.time()
    for update in range(1, n_updates + 1):
        for g in optim.param_groups:  # linear learning-rate decay
            g["lr"] = args.learning_rate * (1.0 - (update - 1) / n_updates)
        for t in range(T):
            obs_buf[t], valid_buf[t] = next_obs, 1.0 - next_done
            with torch.no_grad():
                action, logp, _, value = agent.act(next_obs)
            act_buf[t], logp_buf[t], val_buf[t] = action, logp, value
            obs, reward, term, trunc, info = envs.step(action.clamp(-1.0, 1.0).numpy())
            done = np.logical_or(term, trunc)
            rew_buf[t], done_buf[t] = torch.as_tensor(reward, dtype=torch.float32), torch.as_tensor(done).float()
            for i in np.flatnonzero(done & (next_done.numpy() == 0)):  # episodes that just ended
                lengths.append(int(info["n_observations"][i]))
                rates.append(rate.of_info(final_info(info, i)))
            next_obs, next_done = torch.as_tensor(obs), done_buf[t].clone()

        with torch.no_grad():
            next_value = agent.value(next_obs)
        ppo_update(agent, optim, args, obs_buf, act_buf, logp_buf, rew_buf, done_buf, val_buf, valid_buf, next_value)

        if lengths and (update % 10 == 0 or update == n_updates):
            recent = slice(-100, None)
            print(
                f"update {update}/{n_updates}  steps {update * T * N}  "
                f"episodes {len(lengths)}  last-100 {rate.name} {np.mean(rates[recent]):.2f}  "
                f"median observations {np.median(lengths[recent]):.1f}  "
                f"{update * T * N / (time.time() - t0):.0f} steps/s",
                flush=True,
            )
    envs.close()
    return agent


def final_info(info: dict, i: int) -> dict:
    """Sub-env ``i``'s entries of a vector env's info (its final info on the step that ends its episode)."""
    return {k: v[i] for k, v in info.items() if not k.startswith("_")}


def evaluate(agent: Agent, args: argparse.Namespace) -> dict[str, float]:
    """The task's own rate and score (its declared metrics: success rate and readings; capture rate and
    tracking error on the moving target) and the median observations of the mean action over
    ``eval_episodes`` fresh episodes.
    """
    metrics = env_entry(args.env_id).task_class.metrics
    envs = make_envs(args, min(args.num_envs, args.eval_episodes), randomize_target=False)
    obs, _ = envs.reset(seed=10_000 + args.seed)  # seeds disjoint from training's
    lengths: list[int] = []
    rates: list[float] = []
    scores: list[float] = []
    prev_done = np.zeros(envs.num_envs, dtype=bool)
    while len(lengths) < args.eval_episodes:
        with torch.no_grad():
            action = agent.actor_mean(torch.as_tensor(obs)).clamp(-1.0, 1.0).numpy()
        obs, _, term, trunc, info = envs.step(action)
        done = np.logical_or(term, trunc)
        for i in np.flatnonzero(done & ~prev_done):
            lengths.append(int(info["n_observations"][i]))
            rates.append(metrics.rate.of_info(final_info(info, i)))
            scores.append(metrics.score.of_info(final_info(info, i)))
        prev_done = done
    envs.close()
    n = args.eval_episodes
    return {
        f"{metrics.rate.name}_rate": float(np.mean(rates[:n])),
        f"mean_{metrics.score.key}": float(np.mean(scores[:n])),
        "median_observations": float(np.median(lengths[:n])),
    }


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Train, evaluate, optionally save; returns the evaluation figures."""
    pin_threads()  # small networks: one thread (unless $ELECTROLOC_THREADS) is fastest and leaves the cores free
    args = parse_args(argv)
    agent = train(args)
    result = evaluate(agent, args)
    print(
        f"evaluation ({args.eval_episodes} episodes, mean action): "
        + ", ".join(f"{k} {v:.2f}" for k, v in result.items())
    )
    if args.save:
        torch.save(agent.state_dict(), args.save)  # reload with torch.load(path, weights_only=True)
        print(f"wrote {args.save}")
    return result


if __name__ == "__main__":
    main()
