"""Gymnasium environments of electroloc-gym.

The env classes load on first access, so that the core can import :mod:`.observation` without
importing the adapters (which import the core).
"""

from __future__ import annotations

from typing import Any

__all__ = ["ElectroLocEnv", "GlobalLocalizationEnv", "UnknownTargetEnv"]

_WHERE = {"ElectroLocEnv": "localize", "GlobalLocalizationEnv": "self_localize", "UnknownTargetEnv": "unknown_target"}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"electroloc_gym.envs.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'electroloc_gym.envs' has no attribute {name!r}")
