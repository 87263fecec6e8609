"""SHA-256 of seeded trajectories of every env (single and native vector), printed one per line.

CI prints these under both of its CPU settings (as is, and with numpy's AVX-512/AVX2 dispatch off and
numba compiling for a generic CPU) and requires the same digests: the simulation's results do not
depend on the SIMD instructions used (docs/design.md, "Results that do not depend on the CPU").
"""

from __future__ import annotations

import hashlib

import gymnasium as gym
import numpy as np

import electroloc_gym  # noqa: F401

CASES = [
    ("ElectroLoc-v0", {"n_particles": 500}),
    (
        "ElectroLoc-v0",
        {"n_particles": 300, "sensor_model": "analytic", "condition": "random", "randomize_target": True},
    ),
    ("ElectroLocGlobal-v0", {"n_particles": 300}),
    ("ElectroLocGlobal-v0", {"n_particles": 200, "sensor_model": "analytic", "layout": "random"}),
    ("ElectroLocUnknownTarget-v0", {"n_particles": 400}),
    ("ElectroLocUnknownTarget-v0", {"n_particles": 300, "sensor_model": "interpolated", "contrast": "continuous"}),
    ("ElectroLocTrack-v0", {"n_particles": 400, "target_speed_mm": 6.0}),
    (
        "ElectroLocTrack-v0",
        {"n_particles": 300, "sensor_model": "analytic", "condition": "random", "target_motion": "random_walk"},
    ),
    ("ElectroLocTrack-v0", {"n_particles": 300, "motion_model": "swimmer", "motion_speed_mm": (0.5, 3.0)}),
]


def digest(env_id: str, kwargs: dict, n_envs: int = 4, n_steps: int = 60) -> str:
    """Digest of a seeded native-vector rollout (observations, rewards, flags, readings, estimates)."""
    env = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point", **kwargs)
    h = hashlib.sha256()
    # explicit per-sub-env seeds: the digest checks the core's trajectories, not how an int seed is spread
    obs, info = env.reset(seed=[123 + i for i in range(n_envs)])
    h.update(obs.tobytes() + info["reading_V"].tobytes())
    rng = np.random.default_rng(0)
    for _ in range(n_steps):
        obs, r, te, tr, info = env.step(rng.uniform(-1, 1, (n_envs, 2)).astype(np.float32))
        for a in (obs, r, te, tr, info["reading_V"], info["estimate_mm"], info["spread_mm"]):
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


if __name__ == "__main__":
    for env_id, kw in CASES:
        print(env_id, sorted(kw.items()), digest(env_id, kw))
