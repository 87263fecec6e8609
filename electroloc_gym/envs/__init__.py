"""Gymnasium environments of electroloc-gym."""

from electroloc_gym.envs.localize import ElectroLocEnv
from electroloc_gym.envs.self_localize import GlobalLocalizationEnv

__all__ = ["ElectroLocEnv", "GlobalLocalizationEnv"]
