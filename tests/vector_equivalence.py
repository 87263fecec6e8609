"""The shared check of the native vector env against Gymnasium's SyncVectorEnv of single envs."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from electroloc_gym.envs.vector import sub_env_seeds


def assert_native_equals_sync(
    env_id: str,
    kwargs: dict[str, Any],
    mode: AutoresetMode,
    info_keys: tuple[str, ...],
    *,
    n: int = 3,
    seed: int = 5,
    action_seed: int = 2,
    steps: int = 40,
    min_ended: int = 0,
) -> None:
    """Run ``n`` native envs and ``n`` single envs in a SyncVectorEnv on the same seeds and random actions;
    observations, rewards, terminations and the ``info_keys`` must be bit for bit equal at every step.
    """
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs)
    ref = gym.vector.SyncVectorEnv([lambda: gym.make(env_id, **kwargs) for _ in range(n)], autoreset_mode=mode)
    assert native.action_space == ref.action_space
    o1, _ = native.reset(seed=seed)
    o2, _ = ref.reset(seed=sub_env_seeds(seed, n))
    assert np.array_equal(o1, o2)
    ref.action_space.seed(action_seed)
    ended = 0
    for t in range(steps):
        a = ref.action_space.sample()
        o1, r1, te1, tr1, i1 = native.step(a)
        o2, r2, te2, tr2, i2 = ref.step(a)
        assert np.array_equal(o1, o2), f"step {t}: observations differ"
        assert np.array_equal(te1, te2) and np.array_equal(tr1, tr2) and np.array_equal(r1, r2), f"step {t}"
        for key in info_keys:
            assert np.array_equal(np.asarray(i1[key], dtype=float), np.asarray(i2[key], dtype=float)), (t, key)
        ended += int((te1 | tr1).sum())
    assert ended >= min_ended, "the rollout should cross an autoreset"
