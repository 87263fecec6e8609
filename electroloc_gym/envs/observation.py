"""The observation layouts, as the envs' public names (declared in :mod:`electroloc_gym.core.observation`)."""

from electroloc_gym.core.observation import (
    BELIEF_OBS_DIM,
    HIST_BINS,
    INFO_KEYS,
    OBSERVATION_MODES,
    RAW_OBS_DIM,
    belief_observation,
    condition_descriptor,
    raw_observation,
)

__all__ = ["BELIEF_OBS_DIM", "RAW_OBS_DIM", "OBSERVATION_MODES", "HIST_BINS", "INFO_KEYS", "condition_descriptor",
           "belief_observation", "raw_observation"]
