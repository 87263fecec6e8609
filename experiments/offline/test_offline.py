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


# ---- the checkpoint on the moving target -------------------------------------------------------------------------
TRACK_ID = "electroloc/ElectroLocTrack-v0/rnd-wlk-v0"


@pytest.fixture()
def track_data(tmp_path, monkeypatch):
    """A two-episode rnd-wlk dataset on the moving target (every episode runs its 70 readings)."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    from electroloc_gym.dataset import DatasetRequest, build_dataset

    build_dataset(DatasetRequest("ElectroLocTrack-v0", "rnd-wlk", 2), progress=False)
    return TRACK_ID


def test_the_checkpoint_is_chosen_by_the_envs_own_score(offline):
    """On the moving target every validation episode reads its 70 readings: the tracking error decides."""
    common, _ = offline
    assert common.checkpoint_score("ElectroLocTrack-v0") == ("tracking_error_mm", "lower")
    assert common.checkpoint_score("ElectroLoc-v0") == ("readings", "lower")
    track = [{"step": s, "readings": 70.0, "success": 0.0, "tracking_error_mm": e} for s, e in ((1, 9.0), (2, 4.0))]
    assert common.improves(track[1], track[0], ("tracking_error_mm", "lower"))
    assert not common.improves(track[0], track[1], ("tracking_error_mm", "lower"))
    # the localisation envs as before: fewer readings, the first of equals kept
    loc = [{"readings": 9.0}, {"readings": 9.0}, {"readings": 8.5}]
    score = ("readings", "lower")
    assert common.improves(loc[0], None, score) and not common.improves(loc[1], loc[0], score)
    assert common.improves(loc[2], loc[0], score)


@pytest.mark.parametrize("trainer", ["bc", "td3_bc"])
def test_a_tracking_trainer_keeps_a_later_checkpoint_when_it_tracks_better(
    offline, track_data, tmp_path, monkeypatch, trainer
):
    """Validation results where the readings tie (70) and the tracking errors differ: the best tracker is
    exported, not the first checkpoint."""
    common, _ = offline
    import importlib

    from electroloc_gym.policy.format import read_export

    module = importlib.import_module(trainer)
    errors = iter([9.0, 3.0, 5.0])

    def fake(*args, **kwargs):  # the readings tie, the tracking errors differ
        return {"readings": 70.0, "success": 0.0, "decision_ms": 0.1, "tracking_error_mm": next(errors), "capture": 0.0}

    monkeypatch.setattr(common, "validate", fake)
    out = tmp_path / trainer
    result = module.train(
        module.TrainConfig(
            datasets=track_data, env_id="ElectroLocTrack-v0", steps=3, eval_every=1, eval_episodes=1, out=str(out)
        )
    )
    assert [r["tracking_error_mm"] for r in result["curve"]] == [9.0, 3.0, 5.0]
    assert result["best"]["step"] == 2
    meta = read_export(out / "policy").meta  # the policy.json its one reader accepts
    assert (
        meta["evaluation"]["tracking_error_mm"] == 3.0
        and "tracking error" in meta["provenance"]["checkpoint_chosen_by"]
    )


def test_a_tiny_tracking_run_validates_by_tracking_error_and_capture(offline, track_data, tmp_path):
    common, bc = offline
    result = bc.train(
        bc.TrainConfig(
            datasets=track_data,
            env_id="ElectroLocTrack-v0",
            steps=2,
            eval_every=1,
            eval_episodes=1,
            out=str(tmp_path / "bc"),
        )
    )
    curve = result["curve"]
    assert all(r["readings"] == 70 and 0 <= r["capture"] <= 1 and r["tracking_error_mm"] >= 0 for r in curve)
    assert result["best"] == min(curve, key=lambda r: r["tracking_error_mm"])


def test_the_report_says_its_progress_and_every_file_it_wrote_into_out(tmp_path, capsys):
    """The report of the committed runs into ``--out``: a progress line per env on stderr, then one ``wrote:``
    line per file, every file in ``--out``; the committed report beside the runs is left as it is.
    """
    sys.path.insert(0, str(ROOT / "experiments" / "offline"))
    try:
        import report
    finally:
        sys.path.remove(str(ROOT / "experiments" / "offline"))
    results = ROOT / "experiments" / "offline" / "results"
    kept = (results / "report.md").read_bytes()
    out = tmp_path / "report"
    assert report.main([str(results), "--reps", "100", "--out", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert sum(line.startswith("offline report: [") and "bootstrap" in line for line in err) == 2, err
    wrote = [Path(line.removeprefix("wrote: ")) for line in err if line.startswith("wrote: ")]
    assert {p.name for p in wrote} >= {"report.md", "report.json"} and all(p.parent == out for p in wrote)
    assert sorted(wrote) == sorted(out.iterdir()) and (results / "report.md").read_bytes() == kept
