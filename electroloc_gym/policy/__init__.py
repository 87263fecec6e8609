"""Learned policies in the pickle-free format: ``policy.json`` + ``policy.safetensors``.

``format`` (the files, read and written without pickle), ``networks`` (the deterministic action in
numpy), ``load`` (:func:`load_policy`: a shipped policy by name or a policy folder as a benchmark agent;
:func:`shipped_policies`: the shipped ones with the env each was trained for), ``sb3`` (from a live
or trusted SB3 model; needs the ``train`` extra). Running a shipped policy needs the core
dependencies only; stochastic actions and SB3 zips need torch and SB3.
"""

from electroloc_gym.policy.format import PolicyFormatError
from electroloc_gym.policy.load import LearnedAgent, ShippedPolicy, load_policy, shipped_policies

__all__ = ["LearnedAgent", "PolicyFormatError", "ShippedPolicy", "load_policy", "shipped_policies"]
