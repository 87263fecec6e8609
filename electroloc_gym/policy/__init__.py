"""Learned policies in the pickle-free format: ``policy.json`` + ``policy.safetensors``.

Running a shipped policy (:func:`load_policy`, :func:`shipped_policies`) needs the core dependencies only;
stochastic actions and SB3 zips need torch and SB3 (the ``train`` extra, :mod:`electroloc_gym.policy.sb3`).
"""

from electroloc_gym.policy.format import PolicyFormatError
from electroloc_gym.policy.load import LearnedAgent, ShippedPolicy, load_policy, shipped_policies

__all__ = ["LearnedAgent", "PolicyFormatError", "ShippedPolicy", "load_policy", "shipped_policies"]
