"""Env steps and wall time to reach min-var's validation level: on synthetic eval.csv files (the first evaluation at
min-var's score or better, "not within the budget" where none is, an old log without wall times or without the
task's score column) and min-var's level computed once through the training evaluation and cached."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import learned_level as lv  # noqa: E402

TRACK = "ElectroLocTrack-v0"
HEAD = "timesteps,wall_time_s,episodes,success_rate,mean_readings,median_readings,median_error_mm,mean_error_mm"


def _run(results: Path, env_id: str, label: str, seed: int, csv_text: str, val_kwargs=None, *, summary) -> Path:
    """A finished, benchmarked rl-zoo3 run folder as the suite lays it out, with this eval.csv."""
    seed_dir = results / env_id / label / f"seed-{seed}"
    run = seed_dir / "zoo" / label / f"{env_id}_1"
    (run / env_id).mkdir(parents=True)
    (run / "eval.csv").write_text(csv_text)
    validation = {"episodes": 2, "first_seed": 100000, "env_kwargs": val_kwargs or {"randomize_target": False}}
    summary(run / "summary.json", env_id, validation)
    kwargs = "{condition: random, observation: belief, randomize_target: true, n_particles: 300}"
    (run / env_id / "config.yml").write_text(f"env_kwargs: {kwargs}\n")
    (seed_dir / "bench").mkdir(parents=True)
    (seed_dir / "bench" / "summary.json").write_text("{}")
    return run


def _track_csv(errors, walls=True):
    head = HEAD + ",mean_return,mean_tracking_error_mm,median_tracking_error_mm,capture_rate"
    if not walls:
        head = head.replace("wall_time_s,", "")
    rows = []
    for i, e in enumerate(errors):
        wall = f"{10.0 * (i + 1)}," if walls else ""
        rows.append(f"{i * 1000},{wall}2,0,70,70,5,5,-100,{e},{e},0.5")
    return "\n".join([head, *rows]) + "\n"


def _cache(results: Path, env_id: str, score: dict) -> None:
    """Min-var's cached level for the runs' validation setting (so these tests run no episode)."""
    kwargs = {"condition": "random", "randomize_target": False, "n_particles": 300}
    entry = {"env_id": env_id, "env_kwargs": kwargs, "first_seed": 100000, "episodes": 2, "row": score}
    path = results / env_id / "_baselines" / lv.CACHE
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps([entry]))


def test_first_reach_finds_the_first_evaluation_at_the_level():
    cols = {"timesteps": [0, 1000, 2000, 3000], "wall_time_s": [1.0, 9.0, 20.0, 31.0], "m": [9.0, 3.0, 1.5, 1.0]}
    assert lv.first_reach(cols, "m", 1.6, True) == (2000, 20.0)
    assert lv.first_reach(cols, "m", 1.5, True) == (2000, 20.0)  # equal to the level counts as reached
    assert lv.first_reach(cols, "m", 0.5, True) is None
    assert lv.first_reach(cols, "m", 8.0, False) == (0, 1.0)  # larger is better
    del cols["wall_time_s"]  # an eval.csv written without wall times: steps only
    assert lv.first_reach(cols, "m", 1.6, True) == (2000, None)


def test_the_report_section_on_synthetic_logs(tmp_path, train_summary_json):
    results = tmp_path / "results"
    w = train_summary_json
    _run(results, TRACK, "sac", 1, _track_csv([9.0, 4.0, 1.5, 1.2]), summary=w)
    _run(results, TRACK, "sac", 2, _track_csv([9.0, 4.0, 3.0, 2.0]), summary=w)  # never at min-var's level
    _run(results, TRACK, "sac", 3, _track_csv([9.0, 1.0], walls=False), summary=w)  # an old log without wall times
    old = HEAD + ",mean_return\n0,1.0,2,0,70,70,5,5,-100\n"
    _run(results, TRACK, "ppo", 1, old, summary=w)  # written before the task's score column
    _cache(results, TRACK, {"mean_tracking_error_mm": 1.6})
    rows = lv.reach(results, TRACK)
    by = {r["label"]: r for r in rows}
    assert [(s["seed"], s["reached"], s["timesteps"], s["wall_time_s"]) for s in by["sac"]["seeds"]] == [
        ("1", True, 2000, 30.0),
        ("2", False, None, None),
        ("3", True, 1000, None),
    ]
    assert by["ppo"]["seeds"][0]["reached"] is None
    text = lv.reach_table({TRACK: rows})
    print(text)
    assert "| ElectroLocTrack-v0 | sac | mean_tracking_error_mm 1.6 | 2 of 3 |" in text
    assert "seed 1: 2 000; seed 2: not within the budget (3 000); seed 3: 1 000" in text
    assert "seed 1: 30; seed 2: not within the budget; seed 3: –" in text
    assert "| ElectroLocTrack-v0 | ppo | mean_tracking_error_mm – | 0 of 1 | seed 1: no score column |" in text
    (results / TRACK / "_baselines" / lv.CACHE).unlink()  # not cached, not computed: said, nothing run
    text = lv.reach_table({TRACK: lv.reach(results, TRACK, compute=False)})
    assert "seed 1: min-var's level not computed (--min-var-level)" in text


def test_min_var_level_is_computed_once_through_the_training_evaluation_and_cached(
    tmp_path, monkeypatch, train_summary_json
):
    results = tmp_path / "results"
    run = _run(
        results,
        "ElectroLoc-v0",
        "crossq",
        1,
        "\n".join([HEAD + ",mean_return", "0,1.0,2,1,4,4,2,2,-3"]),
        summary=train_summary_json,
    )
    env_id, kwargs, first, episodes = lv.validation_settings(run)
    assert (env_id, first, episodes) == ("ElectroLoc-v0", 100000, 2)
    assert kwargs == {"condition": "random", "randomize_target": False, "n_particles": 300}  # no observation
    seen = []
    from electroloc_gym.train import callbacks

    real = callbacks.evaluate_agent

    def spy(agent, env_id, env_kwargs, seeds):
        seen.append((type(agent).__name__, env_id, dict(env_kwargs), list(seeds)))
        return real(agent, env_id, env_kwargs, seeds)

    monkeypatch.setattr(callbacks, "evaluate_agent", spy)
    baselines = results / "ElectroLoc-v0" / "_baselines"
    row = lv.level(baselines, env_id, kwargs, first, episodes)
    assert seen == [("MinVarianceAgent", "ElectroLoc-v0", kwargs, [100000, 100001])]
    assert row["episodes"] == 2 and row["mean_readings"] >= 1
    cached = json.loads((baselines / lv.CACHE).read_text())
    assert len(cached) == 1 and cached[0]["row"] == row and cached[0]["agent"] == "min-var"
    assert lv.level(baselines, env_id, kwargs, first, episodes) == row and len(seen) == 1  # from the cache
    assert lv.level(baselines, env_id, kwargs, first, 1, compute=False) is None and len(seen) == 1
    lv.level(baselines, env_id, kwargs, first, 1)  # another validation setting: a second entry
    assert len(seen) == 2 and len(json.loads((baselines / lv.CACHE).read_text())) == 2


def test_a_damaged_cache_is_one_error(tmp_path):
    path = tmp_path / lv.CACHE
    path.parent.mkdir(parents=True)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not a readable cache"):
        lv.level(tmp_path, "ElectroLoc-v0", {}, 100000, 2)
