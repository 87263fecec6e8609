"""Minari datasets of the benchmark's agents: collection, seed protocol, reference scores and the command.

Minari is the optional ``minari`` extra; importing this package does not import it.
"""

from electroloc_gym.dataset.collect import build_dataset, dataset_env_kwargs, step_infos
from electroloc_gym.dataset.request import DatasetRequest, dataset_id
from electroloc_gym.dataset.seed_protocol import episode_seeds, evaluation_overlap, reference_scores

__all__ = [
    "DatasetRequest",
    "build_dataset",
    "dataset_env_kwargs",
    "dataset_id",
    "step_infos",
    "episode_seeds",
    "evaluation_overlap",
    "reference_scores",
]
