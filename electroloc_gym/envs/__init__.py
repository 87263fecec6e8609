"""Gymnasium environments of electroloc-gym."""

from electroloc_gym.envs.localize import ElectroLocEnv

__all__ = ["ElectroLocEnv"]
