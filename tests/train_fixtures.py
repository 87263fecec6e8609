"""What the training tests share: a tiny rl-zoo3 run through the project's hook, in-process."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

#: A few-second budget: small filter, small network, tiny rollouts, two validation episodes.
TINY_ENV = {"n_particles": 300}
TINY_HYPER: dict[str, dict[str, Any]] = {
    "ppo": {
        "n_envs": 4,
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": "dict(net_arch=[16], activation_fn=nn.Tanh)",
    },
    "a2c": {"n_envs": 4, "n_steps": 8, "policy_kwargs": "dict(net_arch=[16], activation_fn=nn.Tanh)"},
    "sac": {
        "n_envs": 2,
        "learning_starts": 64,
        "batch_size": 32,
        "buffer_size": 1000,
        "policy_kwargs": "dict(net_arch=[16])",
    },
    "crossq": {
        "n_envs": 2,
        "learning_starts": 64,
        "batch_size": 32,
        "buffer_size": 1000,
        "policy_kwargs": "dict(net_arch=dict(pi=[16], qf=[16]))",
    },
    "ppo_lstm": {
        "n_envs": 4,
        "n_steps": 32,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": "dict(lstm_hidden_size=8, net_arch=[8])",
    },
    "qrdqn": {
        "n_envs": 2,
        "learning_starts": 64,
        "batch_size": 32,
        "buffer_size": 1000,
        "target_update_interval": 100,
        "policy_kwargs": "dict(net_arch=[16], n_quantiles=5)",
    },
}
TINY_CALLBACK = "[{'electroloc_gym.train.callbacks.BenchEvalCallback': {'eval_freq': 100000, 'n_episodes': 2}}]"


def zoo_argv(
    algo: str,
    log_folder: Path,
    *,
    timesteps: int = 256,
    native: bool = True,
    env_kwargs: dict[str, Any] | None = None,
    hyper: dict[str, Any] | None = None,
    env_id: str = "ElectroLoc-v0",
) -> list[str]:
    """The argv of a tiny ``rl_zoo3.train`` run of ``algo``'s shipped file (its ``env_id`` section)."""
    import yaml

    from electroloc_gym.train.run import hyperparams_file
    from electroloc_gym.train.run import zoo_argv as argv_of

    file_kw = yaml.safe_load(hyperparams_file(algo).read_text())[env_id]["env_kwargs"]
    argv = argv_of(
        algo,
        env_id,
        7,
        timesteps=timesteps,
        log_folder=log_folder,
        env_kwargs={**file_kw, **TINY_ENV, **(env_kwargs or {})},
        native=native,
    )
    items = {**TINY_HYPER[algo], **(hyper or {})}.items()
    words = [f"{k}:{v!r}" if not isinstance(v, str) else f"{k}:{v}" for k, v in items]
    return [*argv[2:], "--hyperparams", *words, f"callback:{TINY_CALLBACK}"]


def run_zoo(argv: list[str], monkeypatch) -> Path:
    """Run ``rl_zoo3.train`` in this process with ``argv``; return the run folder it made."""
    from rl_zoo3.train import train

    log_folder = Path(argv[argv.index("--log-folder") + 1])
    before = set(log_folder.glob("*/*_*"))
    monkeypatch.setattr(sys, "argv", ["rl_zoo3.train", *argv])
    train()
    (run,) = [p for p in log_folder.glob("*/*_*") if p.is_dir() and p not in before]
    return run
