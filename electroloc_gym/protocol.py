"""The localisation protocol's constants, declared once (paper §4.1.3, §5.4).

Every layer reads these names: the core's parameters (:mod:`electroloc_gym.contract.params`), the
benchmark, the agents, the demo and the training wrappers. The benchmark fixes them for every trial
(an agent's ``env_kwargs`` may not change them); an env takes them as keyword arguments.

This module is data: it imports nothing of the package, so every layer may read it.
"""

from __future__ import annotations

__all__ = ["MAX_OBSERVATIONS", "N_PARTICLES", "SUCCESS_SPREAD_MM", "MAX_STEP_MM", "FAR_ERROR_MM", "HIST_BINS"]

#: Readings per episode before truncation (paper §5.4: 35).
MAX_OBSERVATIONS = 35
#: Particles of the belief per env (paper: 2500).
N_PARTICLES = 2500
#: An episode succeeds when the belief's spread √trace Σ is at most this, mm (paper: 10 mm).
SUCCESS_SPREAD_MM = 10.0
#: Largest move per axis per step, mm (paper §4.1.3).
MAX_STEP_MM = 10.0
#: A *far success*: the trial succeeded (the belief is tight) but its estimate is more than this from the
#: target, mm: 1.5 × the success criterion, so the tight cloud does not hold the target — a belief locked on
#: the wrong object (a distractor, or a wrong mode of the target's own map).
FAR_ERROR_MM = 15.0
#: Cells per axis of the belief observation's egocentric particle histogram (8×8 entries, layout:
#: :mod:`electroloc_gym.contract.observation`); the compiled kernels and the torch engine read it too.
HIST_BINS = 8
