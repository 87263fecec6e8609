"""SB3 training for electroloc-gym: ``python -m train`` / ``electroloc train`` (DESIGN §9.10).

Modules: ``config`` (strict rl-zoo3-style YAML hyper-parameters), ``wrappers`` (frame stack, potential
shaping), ``callbacks`` (seeded evaluation, checkpoints, atomic saves), ``policy`` (``load_policy``: a
saved model as a benchmark agent). Importing this package does not import torch.
"""

__all__: list[str] = []
