"""The two engines' episode lengths in distribution, with the power to see a 2 % shift of the mean.

Uniform random moves on ``ElectroLoc-v0`` with ``condition="random"`` (one of the paper's eight presets
drawn per episode) and the default options, on the numba engine and on the torch engine (eager, CPU). Each
engine steps ``N_ENVS`` envs with autoreset and keeps the first ``EPISODES_PER_ENV`` episodes of every
env: a fixed count per env, so that short episodes are not over-represented (the first episodes to end
across many envs are the short ones). The length of an episode is its readings (a failure counts as the
35-reading cap, where it is truncated).

The two engines draw different streams, so the episodes differ one by one; the test is Welch's two-sample
t-test of the mean length at α = 0.05 (two-sided). Its power is computed from the observed spread (a
normal approximation: the standard error of the difference from the two samples' variances): with about
17 000 episodes per engine it detects a 2 % shift of the mean (about 0.36 readings on a mean of about 18
and a standard deviation of about 12) with probability ≥ 0.8, and the test asserts that power before it
asserts the equality, so a change that made episodes more variable could not pass it by weakening it.
Fixed seeds: the check is deterministic. It takes minutes (the torch engine's eager CPU step), so it
carries the marker ``slow``; the 400-seed comparisons of tests/test_torch_episodes.py run in the default
suite.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

torch = pytest.importorskip("torch")

import electroloc_gym  # noqa: E402, F401

pytestmark = pytest.mark.slow

N_ENVS = 512
EPISODES_PER_ENV = 33  # 16 896 episodes per engine
SHIFT = 0.02  # the relative shift of the mean length the test must see
ALPHA, POWER = 0.05, 0.8


def _episode_lengths(backend: str) -> np.ndarray:
    """The first ``EPISODES_PER_ENV`` episodes' lengths (readings) of each of ``N_ENVS`` envs, random moves."""
    kw = {"backend": "torch", "device": "cpu"} if backend == "torch" else {}
    env = gym.make_vec(
        "ElectroLoc-v0", num_envs=N_ENVS, vectorization_mode="vector_entry_point", condition="random", **kw
    )
    env.reset(seed=20_081_205)
    host = (lambda x: x.cpu().numpy()) if backend == "torch" else np.asarray
    moves = np.random.default_rng(11)
    lengths = np.zeros((N_ENVS, EPISODES_PER_ENV))
    ended = np.zeros(N_ENVS, dtype=np.int64)
    while ended.min() < EPISODES_PER_ENV:
        action = moves.uniform(-1.0, 1.0, (N_ENVS, 2)).astype(np.float32)
        _, _, term, trunc, info = env.step(torch.as_tensor(action) if backend == "torch" else action)
        for k in np.flatnonzero((host(term) | host(trunc)) & (ended < EPISODES_PER_ENV)):
            lengths[k, ended[k]] = host(info["n_observations"])[k]
            ended[k] += 1
    env.close()
    return lengths.ravel()


def test_mean_episode_length_is_the_same_on_both_engines_with_power_for_a_two_percent_shift() -> None:
    numba, torch_ = _episode_lengths("numba"), _episode_lengths("torch")
    se = float(np.sqrt(numba.var(ddof=1) / numba.size + torch_.var(ddof=1) / torch_.size))
    shift = SHIFT * float(numba.mean())
    z = stats.norm.ppf(1 - ALPHA / 2)
    power = float(stats.norm.cdf(shift / se - z) + stats.norm.cdf(-shift / se - z))
    test = stats.ttest_ind(numba, torch_, equal_var=False)
    print(
        f"\nnumba {numba.mean():.3f} ± {numba.std():.2f} readings, torch {torch_.mean():.3f} ± {torch_.std():.2f}"
        f" ({numba.size} episodes each); Welch p = {test.pvalue:.3f}; power for a {SHIFT:.0%} shift"
        f" ({shift:.2f} readings) at α = {ALPHA}: {power:.3f}"
    )
    assert power >= POWER, power
    assert test.pvalue >= ALPHA, (numba.mean(), torch_.mean(), test.pvalue)
