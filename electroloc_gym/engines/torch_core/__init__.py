"""The simulation core of ElectroLoc-v0 as batched torch operations on one ``torch.device``.

A second engine beside :mod:`electroloc_gym.engines.numba_core` (the reference) for thousands of tanks per step (on a
GPU; on the CPU it
runs, and is tested against the numba core, but does not beat it). torch is imported only by the
modules of this package, never by the base package: ``gym.make_vec("ElectroLoc-v0", num_envs=N,
vectorization_mode="vector_entry_point", backend="torch", device="cuda")`` imports it on demand
(:mod:`.vector_env`).

* :mod:`.rng` — the counter-based generator (a hash of seed, env, episode, reading, stream, index);
* :mod:`.consts` — the per-condition constants and the episode's parameters as tensors;
* :mod:`.belief_update` — the reading, the likelihoods, the resampling, the statistics, the observation;
* :mod:`.calibration` — the per-episode calibration as tensor operations;
* :mod:`.sim` — reset and step (the state as a dict of tensors; no host synchronisation in a step);
* :mod:`.vector_env` — the Gymnasium ``VectorEnv``; :mod:`.sb3_vec_env` — the SB3 ``VecEnv`` adapter.
"""

__all__: list[str] = []
