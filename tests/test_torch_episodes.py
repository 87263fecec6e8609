"""The torch backend episode by episode in distribution: the benchmark's 400 trial seeds (8 conditions × 50,
seed 0, the paper's fixed target) run on both backends by two observation-only agents — uniform random
moves and the shipped ppo-belief (the agents that read the single env's accessors, min-var among them,
need the accessors the torch vector env does not have). The two backends draw different streams, so the
episodes differ one by one; the torch backend's success rate must lie inside the numba core's 95 % Wilson
interval and its mean readings (a failure counts as the 35-reading cap) inside the numba core's 95 %
t-interval. Fixed seeds: the check is deterministic."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402, F401
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.conditions import PRESET_NAMES  # noqa: E402
from electroloc_gym.protocol import MAX_OBSERVATIONS  # noqa: E402

TRIALS = 50


def _first_episodes(backend: str, condition: str, policy) -> tuple[np.ndarray, np.ndarray]:
    """(success, readings) of each sub-env's first episode, sub-env k on trial k's env seed."""
    kw = {"backend": "torch", "device": "cpu"} if backend == "torch" else {}
    env = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=TRIALS,
        vectorization_mode="vector_entry_point",
        condition=condition,
        randomize_target=False,
        **kw,
    )
    obs, _ = env.reset(seed=[trial_seeds(0, condition, k)[0] for k in range(TRIALS)])
    done, success, readings = np.zeros(TRIALS, bool), np.zeros(TRIALS, bool), np.zeros(TRIALS)
    rng = np.random.default_rng(7)
    host = (lambda x: x.cpu().numpy()) if backend == "torch" else np.asarray
    while not done.all():
        o = host(obs)
        action = policy.predict(o)[0] if policy is not None else rng.uniform(-1, 1, (TRIALS, 2)).astype(np.float32)
        obs, _, term, trunc, info = env.step(torch.as_tensor(action) if backend == "torch" else action)
        new = (host(term) | host(trunc)) & ~done
        success[new], readings[new] = host(info["success"])[new], host(info["n_observations"])[new]
        done |= new
    env.close()
    return success, np.where(success, readings, MAX_OBSERVATIONS)


@pytest.fixture(scope="module")
def ppo_belief():
    from electroloc_gym.bench.agents import cached_agent

    return cached_agent("ppo-belief")


@pytest.mark.parametrize("agent", ["random", "ppo-belief"])
def test_the_torch_backend_localises_as_the_numba_core_does(agent, request) -> None:
    policy = request.getfixturevalue("ppo_belief") if agent == "ppo-belief" else None
    runs = {b: [_first_episodes(b, c, policy) for c in PRESET_NAMES] for b in ("numba", "torch")}
    success = {b: np.concatenate([s for s, _ in r]) for b, r in runs.items()}
    readings = {b: np.concatenate([x for _, x in r]) for b, r in runs.items()}
    n = len(success["numba"])
    assert n == 8 * TRIALS
    ci = stats.binomtest(int(success["numba"].sum()), n).proportion_ci(0.95, method="wilson")
    assert ci.low <= success["torch"].mean() <= ci.high, (agent, success["torch"].mean(), ci)
    r = readings["numba"]
    half = stats.t.ppf(0.975, n - 1) * r.std(ddof=1) / np.sqrt(n)
    assert abs(readings["torch"].mean() - r.mean()) <= half, (agent, readings["torch"].mean(), r.mean(), half)
