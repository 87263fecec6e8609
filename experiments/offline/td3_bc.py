"""TD3+BC (Fujimoto & Gu, NeurIPS 2021) on mixed Minari datasets, single file in the style of CORL's ``td3_bc``.

Offline RL on the belief-state MDP: twin critics Q(s, a) learn the return of the unshaped reward (−1 per
reading, discount ``discount``) from every transition of the datasets; the deterministic actor
(:class:`common.Actor`) maximises ``λ·Q(s, π(s)) − (π(s) − a)²`` with ``λ = alpha / mean|Q|``, target
policy smoothing and delayed actor updates as TD3. States are standardised (:class:`common.Normalizer`).
Every ``eval_every`` steps the actor runs the validation episodes (reset seeds 100000+); the checkpoint
with the best validation score — the env's own (:func:`common.checkpoint_score`): the fewest mean readings,
on the moving target the lowest mean tracking error — is exported to the pickle-free policy format
(``OUT/policy``) and the learning curve written to ``OUT/curve.json``.

    python experiments/offline/td3_bc.py --seed 1 --out experiments/offline/results/ElectroLoc-v0/td3bc-mixed/seed-1
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

from electroloc_gym.baselines.agent import RANDOM_AGENT  # noqa: E402
from electroloc_gym.baselines.infotaxis import InfotaxisAgent  # noqa: E402
from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402

MIXED = ",".join(
    f"electroloc/{PAPER_ENV_ID}/{a}-v0"
    for a in (RANDOM_AGENT, MinVarianceAgent.name, LookaheadAgent.name, InfotaxisAgent.name, "ppo-belief")
)


@dataclass
class TrainConfig:
    """TD3+BC's settings (CORL's defaults; every one a command-line option of the same name)."""

    datasets: str = MIXED  # comma-separated Minari ids
    env_id: str = PAPER_ENV_ID
    seed: int = 1
    out: str = f"experiments/offline/results/{PAPER_ENV_ID}/td3bc-mixed/seed-1"
    steps: int = 30_000
    batch_size: int = 256
    lr: float = 3e-4
    discount: float = 0.99
    tau: float = 0.005
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    policy_freq: int = 2
    alpha: float = 2.5
    eval_every: int = 5_000
    eval_episodes: int = 32


class Critic(nn.Module):
    """Q(s, a): a ReLU MLP on the standardised observation and the action."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: int = 256) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(obs_dim + act_dim, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(), nn.Linear(hidden, 1)
        )

    def forward(self, s: torch.Tensor, a: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([s, a], 1))


def soft_update(target: nn.Module, source: nn.Module, tau: float) -> None:
    """Polyak averaging: target ← (1 − tau)·target + tau·source."""
    for t, s in zip(target.parameters(), source.parameters()):
        t.data.copy_((1 - tau) * t.data + tau * s.data)


def train(config: TrainConfig) -> dict:
    """Train, validate, export the best checkpoint; returns its validation row and the curve.

    Raises:
        common.ArgumentError: a setting or a dataset that cannot be used (:func:`common.prepare`), before
            anything is trained or written.
    """
    ids, data, env = common.prepare(config)
    common.seed_everything(config.seed)
    norm = common.Normalizer.fit(data["observations"])
    s_all, s2_all = torch.as_tensor(norm(data["observations"])), torch.as_tensor(norm(data["next_observations"]))
    a_all = torch.as_tensor(data["actions"])
    r_all = torch.as_tensor(data["rewards"])[:, None]
    d_all = torch.as_tensor(data["terminals"])[:, None]
    obs_dim, act_dim = s_all.shape[1], a_all.shape[1]
    actor = common.Actor(obs_dim, act_dim)
    actor_t = copy.deepcopy(actor)
    q1, q2 = Critic(obs_dim, act_dim), Critic(obs_dim, act_dim)
    q1_t, q2_t = copy.deepcopy(q1), copy.deepcopy(q2)
    a_opt = torch.optim.Adam(actor.parameters(), lr=config.lr)
    q_opt = torch.optim.Adam([*q1.parameters(), *q2.parameters()], lr=config.lr)
    rng = np.random.default_rng(config.seed)
    curve, best, best_state = [], None, None
    score = common.checkpoint_score(config.env_id)
    t0 = common.timer()
    actor_loss = torch.zeros(())
    for step in range(1, config.steps + 1):
        idx = torch.as_tensor(rng.integers(0, len(s_all), config.batch_size))
        s, a, r, s2, d = s_all[idx], a_all[idx], r_all[idx], s2_all[idx], d_all[idx]
        with torch.no_grad():
            noise = (torch.randn_like(a) * config.policy_noise).clamp(-config.noise_clip, config.noise_clip)
            a2 = (actor_t(s2) + noise).clamp(-1.0, 1.0)
            target = r + (1 - d) * config.discount * torch.min(q1_t(s2, a2), q2_t(s2, a2))
        critic_loss = F.mse_loss(q1(s, a), target) + F.mse_loss(q2(s, a), target)
        q_opt.zero_grad()
        critic_loss.backward()
        q_opt.step()
        if step % config.policy_freq == 0:
            pi = actor(s)
            q = q1(s, pi)
            lmbda = config.alpha / q.abs().mean().detach()
            actor_loss = -lmbda * q.mean() + F.mse_loss(pi, a)
            a_opt.zero_grad()
            actor_loss.backward()
            a_opt.step()
            soft_update(q1_t, q1, config.tau)
            soft_update(q2_t, q2, config.tau)
            soft_update(actor_t, actor, config.tau)
        if step % config.eval_every == 0 or step == config.steps:
            v = common.validate(actor, norm, env, config.eval_episodes)
            curve.append(
                {
                    "step": step,
                    "critic_loss": critic_loss.item(),
                    "actor_loss": actor_loss.item(),
                    **v,
                    "wall_s": round(common.timer() - t0, 1),
                }
            )
            print(
                f"step {step}: critic {critic_loss.item():.3f} actor {actor_loss.item():.3f} {common.describe(v)}",
                flush=True,
            )
            if common.improves(v, best, score):
                best, best_state = curve[-1], copy.deepcopy(actor.state_dict())
    return common.finish(
        actor,
        best_state,
        best,
        curve,
        norm=norm,
        config=config,
        algo="td3_bc",
        trainer="experiments/offline/td3_bc.py",
        datasets=ids,
        transitions=len(s_all),
        t0=t0,
    )


main = common.main_of(TrainConfig, train, __doc__)


if __name__ == "__main__":
    sys.exit(main())
