"""An asymmetric actor-critic in one file: the critic sees the true target, the actor only the belief.

``PrivilegedInfo`` (:mod:`electroloc_gym.envs.privileged`) adds the hidden target position to ``info``; the
critic V(observation, truth) uses it to judge how far the belief is from localising, the Gaussian actor
π(a | observation) never sees it, so the trained actor is an ordinary policy of ``ElectroLoc-v0``.
The update is advantage actor-critic with generalised advantage estimation (A2C with GAE) on one env.

    python examples/asymmetric_critic.py --updates 200
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np
import torch
from torch import nn

import electroloc_gym  # noqa: F401  (registers the envs)
from electroloc_gym.envs.privileged import PrivilegedInfo
from electroloc_gym.protocol import N_PARTICLES
from electroloc_gym.utils.runtime import pin_threads

#: The truth is given to the critic in units of this, mm (the tank's scale).
TRUTH_SCALE_MM = 100.0


def mlp(d_in: int, d_out: int, hidden: int = 64) -> nn.Sequential:
    """Two tanh hidden layers."""
    return nn.Sequential(
        nn.Linear(d_in, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(), nn.Linear(hidden, d_out)
    )


def train(
    updates: int = 200,
    n_steps: int = 128,
    n_particles: int = N_PARTICLES,
    seed: int = 0,
    gamma: float = 0.99,
    lam: float = 0.95,
    lr: float = 7e-4,
) -> dict[str, float]:
    """Train; returns the input sizes of actor and critic, the last losses and the mean episode length."""
    torch.manual_seed(seed)
    pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise
    env = PrivilegedInfo(gym.make("ElectroLoc-v0", condition="random", randomize_target=True, n_particles=n_particles))
    obs_dim, act_dim = env.observation_space.shape[0], env.action_space.shape[0]
    priv_dim = env.privileged_space.shape[0]
    actor, critic = mlp(obs_dim, act_dim), mlp(obs_dim + priv_dim, 1)  # the critic's input adds the truth
    log_std = nn.Parameter(torch.full((act_dim,), -0.5))
    optim = torch.optim.Adam([*actor.parameters(), *critic.parameters(), log_std], lr=lr)
    obs, info = env.reset(seed=seed)
    lengths, value_loss, policy_loss, episode = [], float("nan"), float("nan"), 0
    for _ in range(updates):
        rows = []
        for _ in range(n_steps):
            o = torch.as_tensor(obs, dtype=torch.float32)
            dist = torch.distributions.Normal(actor(o), log_std.exp())
            action = dist.sample()
            truth = torch.as_tensor(info["privileged"] / TRUTH_SCALE_MM, dtype=torch.float32)
            obs, reward, terminated, truncated, info = env.step(action.clamp(-1, 1).numpy())
            rows.append((o, truth, action, float(reward), bool(terminated), bool(terminated or truncated)))
            episode += 1
            if terminated or truncated:
                lengths.append(episode)
                episode = 0
                obs, info = env.reset()
        # V of every visited state and of the state after the last one (the critic alone sees the truth)
        o_all = torch.stack([r[0] for r in rows])
        t_all = torch.stack([r[1] for r in rows])
        values = critic(torch.cat([o_all, t_all], 1)).squeeze(1)
        with torch.no_grad():
            o_next = torch.as_tensor(obs, dtype=torch.float32)[None]
            t_next = torch.as_tensor(info["privileged"] / TRUTH_SCALE_MM, dtype=torch.float32)[None]
            last = critic(torch.cat([o_next, t_next], 1)).squeeze()
            adv, gae, nxt = torch.zeros(len(rows)), 0.0, last
            for k in reversed(range(len(rows))):
                _, _, _, r, term, done = rows[k]
                delta = r + gamma * nxt * (1.0 - term) - values[k]
                gae = delta + gamma * lam * (1.0 - done) * gae
                adv[k], nxt = gae, values[k]
            returns = adv + values.detach()
        logp = torch.distributions.Normal(actor(o_all), log_std.exp()).log_prob(torch.stack([r[2] for r in rows]))
        pl = -(logp.sum(1) * adv).mean()
        vl = 0.5 * ((values - returns) ** 2).mean()
        optim.zero_grad()
        (pl + 0.5 * vl).backward()
        nn.utils.clip_grad_norm_([*actor.parameters(), *critic.parameters()], 0.5)
        optim.step()
        value_loss, policy_loss = vl.item(), pl.item()
    return {
        "actor_input_dim": obs_dim,
        "critic_input_dim": obs_dim + priv_dim,
        "value_loss": value_loss,
        "policy_loss": policy_loss,
        "mean_episode_steps": float(np.mean(lengths)) if lengths else float("nan"),
    }


def main(argv: list[str] | None = None) -> int:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--updates", type=int, default=200, help="updates of n-steps steps each (≥ 1)")
    parser.add_argument("--n-steps", type=int, default=128, help="env steps per update (≥ 1)")
    parser.add_argument("--seed", type=int, default=0, help="seed (≥ 0)")
    args = parser.parse_args(argv)
    for name in ("updates", "n_steps"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be ≥ 1, got {getattr(args, name)}")
    if args.seed < 0:
        parser.error(f"--seed must be ≥ 0, got {args.seed}")
    print(train(updates=args.updates, n_steps=args.n_steps, seed=args.seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
