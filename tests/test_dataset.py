"""Minari datasets of the benchmark's agents: build, load, recover the env, replay; the seed protocol; bad input."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

minari = pytest.importorskip("minari")  # the dev extra installs it; the numpy lower-bound session deselects these

from cli_inproc import run_cli  # noqa: E402  (the command in this process)

from electroloc_gym.bench.config import MAP_CONDITIONS, trial_seeds  # noqa: E402
from electroloc_gym.dataset import (  # noqa: E402
    DatasetRequest,
    build_dataset,
    dataset_id,
    episode_seeds,
    evaluation_overlap,
    reference_scores,
)
from electroloc_gym.world.conditions import PRESET_NAMES  # noqa: E402

pytestmark = pytest.mark.minari

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "experiments" / "learned" / "results" / "ElectroLoc-v0" / "_baselines" / "bench"


@pytest.fixture()
def store(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return tmp_path / "minari"


def _replay(ds) -> int:
    """Replay every episode's stored actions in the recovered env; return the steps compared."""
    env = ds.recover_environment()
    steps = 0
    for ep, meta in zip(ds.iterate_episodes(), ds.storage.get_episode_metadata(range(ds.total_episodes))):
        obs, _ = env.reset(seed=int(meta["seed"]))
        np.testing.assert_array_equal(obs, ep.observations[0])
        for t, action in enumerate(ep.actions):
            obs, reward, terminated, truncated, _ = env.step(action)
            np.testing.assert_array_equal(obs, ep.observations[t + 1])
            assert reward == ep.rewards[t]
            assert (terminated, truncated) == (ep.terminations[t], ep.truncations[t])
            steps += 1
        assert terminated or truncated
    return steps


def test_tiny_dataset_loads_recovers_and_replays(store):
    ds = build_dataset(DatasetRequest("ElectroLoc-v0", "min-var", 3, reference=REFERENCE), progress=False)
    assert ds.spec.dataset_id == "electroloc/ElectroLoc-v0/min-var-v0"
    loaded = minari.load_dataset("electroloc/ElectroLoc-v0/min-var-v0")
    assert (store / "electroloc" / "ElectroLoc-v0" / "min-var-v0" / "data").is_dir()  # MINARI_DATASETS_PATH
    assert loaded.total_episodes == 3 and loaded.total_steps == _replay(loaded)
    meta = loaded.storage.metadata
    block = meta["electroloc"]
    assert block["complete"] and block["agent"] == "min-var" and block["env_kwargs"] == {"condition": "random"}
    assert meta["dataset_size"] == type(loaded.storage).get_size(loaded.storage)  # counted once, at the end
    # the reference scores: 1 − readings of rnd-wlk and of the best planner on the benchmark's trials
    refs = reference_scores(REFERENCE, "ElectroLoc-v0")
    assert meta["ref_min_score"] == pytest.approx(1 - refs["rnd_readings"])
    assert meta["ref_max_score"] == pytest.approx(1 - refs["best_readings"])
    ep = next(loaded.iterate_episodes())
    # return = 1 − readings (the reset's reading unrewarded), the scale the reference scores use
    assert ep.rewards.sum() == 1 - ep.infos["n_observations"][-1]
    assert minari.get_normalized_score(loaded, np.array([meta["ref_max_score"]]))[0] == pytest.approx(1.0)
    # the infos: belief summary and truth, one row per observation
    n = len(ep.observations)
    assert ep.infos["truth_mm"].shape == (n, 2) and ep.infos["covariance_mm2"].shape == (n, 3)
    err = np.hypot(*(ep.infos["estimate_mm"][-1] - ep.infos["truth_mm"][-1]))
    assert err == pytest.approx(ep.infos["error_mm"][-1])
    assert np.all(ep.infos["condition_index"] >= 0)


def test_global_env_dataset_replays_and_holds_the_robots_true_position(store):
    ds = build_dataset(DatasetRequest("ElectroLocGlobal-v0", "rnd-wlk", 2), progress=False)
    assert _replay(ds) == ds.total_steps
    ep = next(ds.iterate_episodes())
    assert np.all(ep.infos["condition_index"] == -1)
    assert "ref_min_score" not in ds.storage.metadata  # no reference given


def test_resume_continues_with_the_same_episodes(store, monkeypatch):
    full = build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 3, dataset_id="test/full-v0"), progress=False)
    part = build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1, dataset_id="test/part-v0"), progress=False)
    part.storage.update_metadata({"electroloc": {**part.storage.metadata["electroloc"], "complete": False}})
    with pytest.raises(ValueError, match="resume=True"):
        build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 3, dataset_id="test/part-v0"), progress=False)
    with pytest.raises(ValueError, match="other settings"):
        build_dataset(
            DatasetRequest("ElectroLoc-v0", "rnd-wlk", 3, seed=2, dataset_id="test/part-v0"),
            resume=True,
            progress=False,
        )
    resumed = build_dataset(
        DatasetRequest("ElectroLoc-v0", "rnd-wlk", 3, dataset_id="test/part-v0"), resume=True, progress=False
    )
    assert resumed.total_episodes == 3 and resumed.storage.metadata["electroloc"]["complete"]
    for a, b in zip(full.iterate_episodes(), resumed.iterate_episodes()):
        np.testing.assert_array_equal(a.observations, b.observations)
        np.testing.assert_array_equal(a.actions, b.actions)


def test_a_build_without_notify_says_its_notes_on_stderr(store, capsys):
    """``notify`` left out: a note (here, a resume with nothing to collect) is one line on stderr, named by the
    package."""
    build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1), progress=False)
    capsys.readouterr()
    build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1), resume=True, progress=False)
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "electroloc_gym.dataset: electroloc/ElectroLoc-v0/rnd-wlk-v0: complete; all 1 episodes match their "
        "checksums and read back: nothing to collect"
    ], err


def test_existing_id_refused_unless_forced(store):
    build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1), progress=False)
    with pytest.raises(ValueError, match="force=True"):
        build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 1), progress=False)
    ds = build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 2), force=True, progress=False)
    assert ds.total_episodes == 2


def test_dataset_seeds_are_disjoint_from_the_evaluation_seeds():
    seeds = [episode_seeds(1, k)[0] for k in range(5000)]
    assert evaluation_overlap(seeds) == []
    assert len(set(seeds)) == len(seeds)
    evaluation = [trial_seeds(0, c, k)[0] for c in (*PRESET_NAMES, *MAP_CONDITIONS) for k in range(3)]
    assert evaluation_overlap(evaluation) == sorted(set(evaluation))  # the check can fail


def test_dataset_ids():
    assert dataset_id("ElectroLoc-v0", "lookahead") == "electroloc/ElectroLoc-v0/lookahead-v0"
    assert dataset_id("ElectroLoc-v0", "min-var[n_voters=500]", 2) == "electroloc/ElectroLoc-v0/min-var_n_voters_500-v2"
    assert dataset_id("ElectroLoc-v0", "/x/runs/bc-seed1/") == "electroloc/ElectroLoc-v0/bc-seed1-v0"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"env_id": "Nope-v0"}, "env_id must be one of"),
        ({"episodes": 0}, r"episodes must be an integer in \[1, "),
        ({"episodes": True}, "episodes must be"),
        ({"seed": 0}, "evaluation seed"),
        ({"seed": -3}, "seed must be"),
        ({"version": -1}, "version must be"),
        ({"condition": "mud"}, "condition must be 'random' or one of"),
        ({"agent": " "}, "agent must be"),
        ({"dataset_id": "no namespace"}, "dataset id must be"),
    ],
)
def test_bad_requests_one_line(kwargs, match):
    args = {"env_id": "ElectroLoc-v0", "agent": "rnd-wlk", "episodes": 1, **kwargs}
    with pytest.raises(ValueError, match=match) as info:
        DatasetRequest(**args)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--agent", "nope", "--episodes", "1"], "unknown agent 'nope'"),
        (["--agent", "zero-crossing", "--episodes", "1"], "ends episodes itself"),
        (["--agent", "ppo-belief", "--episodes", "1", "--env", "ElectroLocGlobal-v0"], "trained on ElectroLoc-v0"),
        (  # a policy named by its policy.json is read as loading it reads it
            [
                "--agent",
                str(ROOT / "electroloc_gym/models/ppo-belief/policy.json"),
                "--episodes",
                "1",
                "--env",
                "ElectroLocGlobal-v0",
            ],
            "trained on ElectroLoc-v0",
        ),
        (["--agent", "rnd-wlk", "--episodes", "1", "--reference", "/no/such/bench"], "reference must be"),
        (["--agent", "rnd-wlk", "--episodes", "1", "--resume", "--force"], "exclude each other"),
    ],
)
def test_cli_bad_input_is_one_line(store, argv, match):
    proc = run_cli("dataset", "--no-progress", *argv)
    assert proc.returncode == 2
    err = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(err) == 1 and match in err[0] and "Traceback" not in proc.stderr
    assert not any(store.rglob("metadata.json"))  # nothing half-written


def test_reference_refuses_a_run_without_a_planner(tmp_path):
    rows = [
        {
            "agent": "rnd-wlk",
            "condition": "c",
            "observations": 9,
            "success": True,
            "max_observations": 35,
            "env_id": "ElectroLoc-v0",
        }
    ]
    (tmp_path / "trials.jsonl").write_text("\n".join(json.dumps(r) for r in rows), encoding="utf-8")
    with pytest.raises(ValueError, match="must hold rnd-wlk and one of"):
        reference_scores(tmp_path, "ElectroLoc-v0")


TRACK_REFERENCE = ROOT / "experiments" / "learned" / "results" / "ElectroLocTrack-v0" / "_baselines" / "bench"


def _track_bench(folder: Path, errors_mm: dict[str, float]) -> Path:
    """A small moving-target benchmark folder: the committed baseline run's rnd-wlk and min-var trials 0–1 on
    two conditions, every trial's tracking error set to its agent's value in ``errors_mm`` (the readings all
    tie at the cap, as on every moving-target trial).
    """
    from electroloc_gym.bench.records import read_trials, stored_trials

    rows = read_trials(stored_trials(TRACK_REFERENCE / "trials.jsonl"))
    conditions = sorted({r["condition"] for r in rows})[:2]
    keep = [r for r in rows if r["agent"] in errors_mm and r["condition"] in conditions and r["trial"] < 2]
    for r in keep:
        r["shape"] = {**r["shape"], "tracking_error_mm": errors_mm[r["agent"]]}
    folder.mkdir()
    (folder / "trials.jsonl").write_text("".join(json.dumps(r) + "\n" for r in keep), encoding="utf-8")
    return folder


def test_a_moving_target_reference_compares_by_the_tracking_error(tmp_path):
    """The readings tie at 70 on every moving-target trial: rnd-wlk and the planners are compared by their
    tracking error, and the reference scores are −(mean tracking error, mm)."""
    refs = reference_scores(_track_bench(tmp_path / "good", {"rnd-wlk": 6.7, "min-var": 1.6}), "ElectroLocTrack-v0")
    assert refs["score"] == "tracking_error_mm" and refs["best_planner"] == "min-var"
    assert refs["ref_min_score"] == pytest.approx(-6.7) and refs["ref_max_score"] == pytest.approx(-1.6)
    assert (refs["rnd_tracking_error_mm"], refs["best_tracking_error_mm"]) == pytest.approx((6.7, 1.6))
    with pytest.raises(ValueError, match="rnd-wlk is not worse than the best planner by the env's own score") as info:
        reference_scores(_track_bench(tmp_path / "bad", {"rnd-wlk": 1.6, "min-var": 6.7}), "ElectroLocTrack-v0")
    assert "\n" not in str(info.value) and "tracking_error_mm (rnd-wlk 1.6, min-var 6.7" in str(info.value)
    committed = reference_scores(TRACK_REFERENCE, "ElectroLocTrack-v0")  # the folder the command's note names
    assert committed["best_planner"] == "min-var" and committed["ref_max_score"] > committed["ref_min_score"]


def test_dataset_reference_on_the_moving_target_is_accepted_or_refused_by_tracking(store, tmp_path, capsys):
    from electroloc_gym.cli import main

    argv = ["dataset", "--no-progress", "--env", "ElectroLocTrack-v0", "--agent", "rnd-wlk", "--episodes", "1"]
    bad = _track_bench(tmp_path / "bad", {"rnd-wlk": 1.6, "min-var": 6.7})
    assert main([*argv, "--reference", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not worse than the best planner by the env's own score" in err[0]
    assert not any(store.rglob("metadata.json"))  # nothing written
    good = _track_bench(tmp_path / "good", {"rnd-wlk": 6.7, "min-var": 1.6})
    assert main([*argv, "--reference", str(good)]) == 0
    ds = minari.load_dataset("electroloc/ElectroLocTrack-v0/rnd-wlk-v0")
    meta = ds.storage.metadata
    assert (meta["ref_min_score"], meta["ref_max_score"]) == pytest.approx((-6.7, -1.6))
    assert meta["electroloc"]["reference"]["score"] == "tracking_error_mm"
    # an episode's score on that scale: −(its mean error over the scored second half), the env's tracking error
    ep = next(ds.iterate_episodes())
    n, err_mm = ep.infos["n_observations"], ep.infos["error_mm"]
    env = ds.recover_environment()
    env.reset(seed=int(next(iter(ds.storage.get_episode_metadata([0])))["seed"]))
    for action in ep.actions:
        *_, info = env.step(action)
    assert np.mean(err_mm[n > n[-1] // 2]) == pytest.approx(info["tracking_error_mm"])


def test_the_files_are_minaris_own(store):
    """The episode files equal those minari.create_dataset_from_buffers writes for the same episodes (each
    episode's metadata with its two checksums added), and the header its header (but for the counts, the
    size and the electroloc block).
    """
    import gymnasium as gym

    from electroloc_gym.bench.agents import make_bench_agent
    from electroloc_gym.dataset.collect import _episode_buffer, dataset_env_kwargs
    from electroloc_gym.dataset.store import settings_digest

    ours = build_dataset(DatasetRequest("ElectroLoc-v0", "rnd-wlk", 2, reference=REFERENCE), progress=False)
    refs = reference_scores(REFERENCE, "ElectroLoc-v0")
    agent = make_bench_agent("rnd-wlk")
    env = gym.make("ElectroLoc-v0", **dataset_env_kwargs("ElectroLoc-v0", agent))
    buffers = [_episode_buffer(env, agent, k, 1) for k in range(2)]
    with pytest.warns(UserWarning):  # Minari's reminder that no eval_env is given
        theirs = minari.create_dataset_from_buffers(
            "test/theirs-v0",
            buffers,
            env=env.spec,
            algorithm_name="rnd-wlk",
            description="rnd-wlk on ElectroLoc-v0 (electroloc-gym), episodes on training seeds",
            author="electroloc-gym",
            author_email="none",
            code_permalink="electroloc_gym/dataset/collect.py",
            data_format="arrow",
            requirements=["electroloc-gym"],
            ref_min_score=refs["ref_min_score"],
            ref_max_score=refs["ref_max_score"],
        )
    a, b = ours.storage.data_path, theirs.storage.data_path
    settings = ours.storage.metadata["electroloc"]
    digest = settings_digest({key: settings[key] for key in ("agent", "env_id", "env_kwargs", "seed")})
    for k in range(2):
        arrow = (a / str(k) / "part-0.arrow").read_bytes()
        assert arrow == (b / str(k) / "part-0.arrow").read_bytes()
        meta = json.loads((a / str(k) / "metadata.json").read_text(encoding="utf-8"))
        theirs_meta = json.loads((b / str(k) / "metadata.json").read_text(encoding="utf-8"))
        # Minari's episode metadata, with what makes each episode say what it is
        assert meta == {**theirs_meta, "sha256": hashlib.sha256(arrow).hexdigest(), "settings_sha256": digest}
    skip = {"dataset_id", "dataset_size", "electroloc", "num_episodes_average_score"}
    mine = json.loads((a / "metadata.json").read_text(encoding="utf-8"))
    minaris = json.loads((b / "metadata.json").read_text(encoding="utf-8"))
    assert {k: v for k, v in mine.items() if k not in skip} == {k: v for k, v in minaris.items() if k not in skip}
    assert set(minaris) - set(mine) == {"num_episodes_average_score"}  # Minari's default 100: not how ours are made


def test_default_ids_of_agents_with_options_are_valid_ids():
    from electroloc_gym.dataset.store import check_dataset_id

    for spec in ("min-var[sigma=0.5]", "lookahead[depth=2,objective='a.b']", "/x/runs/bc.seed1/", "pkg.mod:make"):
        ds_id = dataset_id("ElectroLoc-v0", spec)
        assert check_dataset_id(ds_id) == ds_id
    assert dataset_id("ElectroLoc-v0", "min-var[sigma=0.5]") == "electroloc/ElectroLoc-v0/min-var_sigma_0_5-v0"


def test_a_default_id_too_long_names_the_setting_that_shortens_it(store, tmp_path, capsys):
    """A policy folder whose name makes the default id longer than an id may be: one line saying so and naming the
    id setting as the front end spells it (``dataset_id`` from Python, ``--id`` on the command line)."""
    import shutil

    from electroloc_gym.bench.agents import shipped_models
    from electroloc_gym.cli import main

    folder = tmp_path / ("p" * 200)
    shutil.copytree(shipped_models()["ppo-belief"], folder)
    with pytest.raises(ValueError, match=r"^the default dataset id .*; pass a shorter dataset_id$"):
        build_dataset(DatasetRequest("ElectroLoc-v0", str(folder), 1))
    assert main(["dataset", "--agent", str(folder), "--episodes", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("; pass a shorter --id"), err
    assert not store.exists() or not any(store.rglob("*.arrow"))
