"""The committed small dataset and the offline trainers: load, replay, train briefly, export, run as a policy."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

minari = pytest.importorskip("minari")
pytest.importorskip("torch")

pytestmark = pytest.mark.minari

ROOT = Path(__file__).resolve().parents[2]
SMALL = ROOT / "tests" / "data" / "minari"
SMALL_ID = "electroloc/ElectroLoc-v0/lookahead-v0"


@pytest.fixture()
def small(monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(SMALL))
    return minari.load_dataset(SMALL_ID)


@pytest.fixture()
def offline():
    sys.path.insert(0, str(ROOT / "experiments" / "offline"))
    import bc
    import common

    yield common, bc
    sys.path.remove(str(ROOT / "experiments" / "offline"))


def test_committed_small_dataset_replays_in_its_recovered_env(small):
    assert small.total_episodes == 40 and 100 <= small.total_steps <= 1000
    assert small.storage.metadata["electroloc"]["complete"]
    env = small.recover_environment()
    metas = list(small.storage.get_episode_metadata(range(3)))
    for ep, meta in zip(small.iterate_episodes(range(3)), metas):
        obs, _ = env.reset(seed=int(meta["seed"]))
        np.testing.assert_array_equal(obs, ep.observations[0])
        for t, a in enumerate(ep.actions):
            obs, *_ = env.step(a)
            np.testing.assert_array_equal(obs, ep.observations[t + 1])


def test_transitions_line_up(small, offline):
    common, _ = offline
    data = common.load_transitions([SMALL_ID])
    n = small.total_steps
    assert all(len(v) == n for v in data.values())
    ep = next(small.iterate_episodes())
    k = len(ep.actions)
    np.testing.assert_array_equal(data["next_observations"][: k - 1], data["observations"][1:k])
    assert data["terminals"][:k].sum() == ep.terminations.sum()


def test_bc_trains_exports_and_runs_as_a_policy(small, offline, tmp_path):
    common, bc = offline
    out = tmp_path / "bc"
    result = bc.train(bc.TrainConfig(datasets=SMALL_ID, steps=300, eval_every=300, eval_episodes=2, out=str(out)))
    assert result["best"]["step"] == 300
    from electroloc_gym.bench.agents import make_bench_agent

    agent = make_bench_agent(str(out / "policy"))  # the benchmark's loader: pickle-free files only
    data = common.load_transitions([SMALL_ID])
    action, _ = agent.predict(data["observations"][0])
    assert action.shape == (2,) and np.all(np.abs(action) <= 1)
    # BC fits the planner's actions better than the mean action does
    norm = common.Normalizer(np.asarray(agent.normalization.mean), np.asarray(agent.normalization.var))
    import torch

    actor = common.Actor(81, 2)
    actor.load_state_dict({k.removeprefix("actor."): torch.as_tensor(v) for k, v in agent.weights.items()})
    pred = actor(torch.as_tensor(norm(data["observations"]))).detach().numpy()
    assert np.mean((pred - data["actions"]) ** 2) < np.mean((data["actions"] - data["actions"].mean(0)) ** 2)
