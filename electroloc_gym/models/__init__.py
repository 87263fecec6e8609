"""The shipped learned policies, one folder each (``models/NAME/``), installed as package data.

:func:`shipped_models` names them (``electroloc bench --agents ppo-belief``,
``electroloc_gym.policy.load_policy("ppo-belief")``, ``electroloc_gym.baselines.make_agent("ppo-belief")``);
:func:`electroloc_gym.policy.shipped_policies` lists each with the env it was trained for.
"""

from pathlib import Path

#: The folder holding the shipped model folders.
MODELS_DIR = Path(__file__).resolve().parent

__all__ = ["MODELS_DIR", "shipped_models"]


def shipped_models() -> dict[str, Path]:
    """Name → folder of every shipped learned policy (a folder of this package that holds files)."""
    return {
        p.name: p
        for p in sorted(MODELS_DIR.iterdir())
        if p.is_dir() and not p.name.startswith((".", "_")) and any(p.iterdir())
    }
