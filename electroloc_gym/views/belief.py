"""The belief an agent may read: a read-only view of one env's particle cloud (paper §4.1).

The particle filter itself — weights from the sensor model's likelihood of each reading, systematic
resampling, jitter N(0, 1 mm²) per axis, the clip to the allowed box, the cloud's mean and
covariance — is the simulation core's (:mod:`electroloc_gym.engines.numba_core.step`, kernels in
:mod:`electroloc_gym.kernels.filter`), for N envs at once. It keeps the clouds of all envs in one
(N, 2, M) float32 array; every update ends with a resampling, so the weights are always uniform.
:class:`BeliefView` shows one env's cloud as ``env.unwrapped.belief``.

Robustness of the update: weights are normalised in the log domain (the largest log-weight is
subtracted before ``exp``), so a reading that makes every particle's likelihood underflow in linear
space still gives a valid distribution concentrated on the least-unlikely particles; if every
log-likelihood is −inf the weights stay uniform; a NaN log-likelihood is an error.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["BeliefView"]


class BeliefView:
    """Read-only view of one env's particle belief in the simulation core (``env.unwrapped.belief``).

    Args:
        state: the core's :class:`~electroloc_gym.engines.numba_core.state.State`.
        index: the env's row.
    """

    def __init__(self, state: Any, index: int) -> None:
        self._state = state
        self._index = int(index)
        self.n_particles = int(state.n_particles)
        w = np.full(self.n_particles, 1.0 / self.n_particles)
        w.flags.writeable = False
        self._weights = w

    @property
    def particles(self) -> NDArray[np.float32]:
        """Particle positions (M, 2) float32, mm (a read-only view of the live cloud); in the
        unknown-target env (M, 4) hypotheses (x mm, y mm, radius mm, χ), a read-only copy.
        """
        s, i = self._state, self._index
        if s.shape_particles.shape[1] == 0:
            v = s.particles_mm[i].T
        else:
            c = np.concatenate([s.particles_mm[i], s.shape_particles[i]])
            c.flags.writeable = False  # the copy too: nothing under the returned array can be written
            v = c.T
        v.flags.writeable = False
        return v

    @property
    def weights(self) -> NDArray[np.float64]:
        """The weights (M,): uniform, 1/M (every update ends with a resampling)."""
        return self._weights

    @property
    def uniform_weights(self) -> bool:
        """True: the weights are uniform after every update."""
        return True

    def mean(self) -> NDArray[np.float64]:
        """Estimate: the particle mean (2,), mm."""
        return self._state.mean_mm[self._index].copy()

    def covariance(self) -> NDArray[np.float64]:
        """Population covariance Σ (2, 2), mm²."""
        return self._state.cov_mm2[self._index].copy()

    def spread(self) -> float:
        """√trace Σ, mm (the paper's success measure, §5.4)."""
        c = self._state.cov_mm2[self._index]
        return float(np.sqrt(max(c[0, 0] + c[1, 1], 0.0)))
