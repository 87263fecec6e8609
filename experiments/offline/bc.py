"""Behaviour cloning of a planner from its Minari dataset, single file in the style of CORL's ``any_percent_bc``.

The actor (:class:`common.Actor`, 81 → 256 → 256 → 2, ReLU, tanh) regresses the dataset's actions on the
standardised belief observation (mean-squared error, Adam). Every ``eval_every`` steps it runs the
validation episodes (reset seeds 100000+, never the benchmark's seed 0); the checkpoint with the best
validation score — the env's own (:func:`common.checkpoint_score`): the fewest mean readings, on the moving
target the lowest mean tracking error — is exported to the pickle-free policy format, so
``electroloc bench --agents OUT/policy`` runs it like a shipped policy. The learning curve is ``OUT/curve.json``.

    python experiments/offline/bc.py --datasets electroloc/ElectroLoc-v0/lookahead-v0 --seed 1 \
        --out experiments/offline/results/ElectroLoc-v0/bc-lookahead/seed-1
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common  # noqa: E402

from electroloc_gym.baselines.lookahead import LookaheadAgent  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402


@dataclass
class TrainConfig:
    """BC's settings (every one a command-line option of the same name)."""

    datasets: str = f"electroloc/{PAPER_ENV_ID}/{LookaheadAgent.name}-v0"  # comma-separated Minari ids
    env_id: str = PAPER_ENV_ID
    seed: int = 1
    out: str = f"experiments/offline/results/{PAPER_ENV_ID}/bc-{LookaheadAgent.name}/seed-1"
    steps: int = 20_000
    batch_size: int = 256
    lr: float = 3e-4
    eval_every: int = 2_000
    eval_episodes: int = 32


def train(config: TrainConfig) -> dict:
    """Train, validate, export the best checkpoint; returns its validation row and the curve.

    Raises:
        common.ArgumentError: a setting or a dataset that cannot be used (:func:`common.prepare`), before
            anything is trained or written.
    """
    ids, data, env = common.prepare(config)
    common.seed_everything(config.seed)
    norm = common.Normalizer.fit(data["observations"])
    obs = torch.as_tensor(norm(data["observations"]))
    act = torch.as_tensor(data["actions"])
    actor = common.Actor(obs.shape[1], act.shape[1])
    optim = torch.optim.Adam(actor.parameters(), lr=config.lr)
    rng = np.random.default_rng(config.seed)
    curve, best, best_state = [], None, None
    score = common.checkpoint_score(config.env_id)
    t0 = common.timer()
    for step in range(1, config.steps + 1):
        idx = torch.as_tensor(rng.integers(0, len(obs), config.batch_size))
        loss = F.mse_loss(actor(obs[idx]), act[idx])
        optim.zero_grad()
        loss.backward()
        optim.step()
        if step % config.eval_every == 0 or step == config.steps:
            v = common.validate(actor, norm, env, config.eval_episodes)
            curve.append({"step": step, "loss": loss.item(), **v, "wall_s": round(common.timer() - t0, 1)})
            print(
                f"step {step}: loss {loss.item():.4f} {common.describe(v)}",
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
        algo="bc",
        trainer="experiments/offline/bc.py",
        datasets=ids,
        transitions=len(obs),
        t0=t0,
    )


main = common.main_of(TrainConfig, train, __doc__)


if __name__ == "__main__":
    sys.exit(main())
