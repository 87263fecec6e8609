"""SB3 training for electroloc-gym: ``python -m electroloc_gym.train`` / ``electroloc train``.

Modules: ``config`` (the project's strict YAML hyper-parameter files), ``validation`` (value, policy
and env checks before training), ``runplan`` / ``rundir`` (new, resumed or forced runs; one run per
folder; segment records), ``wrappers`` (frame stack, potential shaping), ``native_vec`` (SB3 adapter
of the native batched vector env), ``callbacks`` (seeded evaluation, checkpoints, atomic saves),
``policy_format`` (the pickle-free ``policy.json`` + ``policy.safetensors``), ``policy``
(``load_policy``: a saved model as a benchmark agent), ``resume`` (continuing a run without
unpickling), ``export`` (converting a trusted SB3 model). Importing this package does not import torch.
"""

__all__: list[str] = []
