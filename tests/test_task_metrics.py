"""What a task declares of its metrics is what every layer reports (electroloc_gym/contract/task_spec.py): the
training evaluation, its checkpoint rule and command line, the learning curves, the episode pictures and the
minimal PPO report the moving target's tracking error and capture on ElectroLocTrack-v0, the localisation
metrics elsewhere; the declaration types check what they are given."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest

import electroloc_gym  # noqa: F401  (registers the env ids)
from electroloc_gym.contract.task_spec import Column, RecordField, Score
from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
from electroloc_gym.engines.numba_core.track_task import TRACK_METRICS
from electroloc_gym.registry import env_entry

TRACK = "ElectroLocTrack-v0"
PAPER = "ElectroLoc-v0"


def test_record_fields_columns_and_scores_check_what_they_get() -> None:
    f = RecordField("d_mm", "a distance", "mm", low=0.0, high=10.0, nullable=True)
    assert f.accepts(3) and f.accepts(None) and not f.accepts(11.0) and not f.accepts(True) and not f.accepts("3")
    assert RecordField("ok", kind="bool").accepts(False) and not RecordField("ok", kind="bool").accepts(None)
    with pytest.raises(ValueError, match="kind must be one of"):
        RecordField("x", kind="int")
    col = Column("rate", "Rate", better="higher", format="{n} ({rate!p:.0f} %)")
    assert col.cell({"n": 3, "rate": 0.25}) == "3 (25 %)" and col.cell({"n": 3, "rate": None}) == "3 (– %)"
    assert Column("e_mm", "E").cell({"e_mm": 1.234}) == "1.2"
    with pytest.raises(ValueError, match="better must be one of"):
        Column("x", "X", better="smaller")
    s = Score("e_mm", "lower", "error", "mm")
    assert s.beats(1.0, 2.0) and not s.beats(2.0, 2.0) and s.of_record({"shape": {"e_mm": 4}}) == 4.0
    assert s.best == "lowest mean error (e_mm, mm)"


def test_each_env_reads_its_own_declaration() -> None:
    assert env_entry(PAPER).task_class.metrics is LOCALIZATION_METRICS
    track = env_entry(TRACK).task_class.metrics
    assert track is TRACK_METRICS and not track.success_criterion
    assert (track.score.key, track.score.better) == ("tracking_error_mm", "lower")
    assert env_entry(TRACK).record_keys == track.record_keys  # the table's keys are the declaration's
    assert LOCALIZATION_METRICS.outcome({"success": True}).startswith("success")
    assert LOCALIZATION_METRICS.outcome({"success": False}) == "failure (observation cap)"
    assert track.outcome({"captured": True, "tracking_error_mm": 2.0}) == "captured, tracking error 2.0 mm"
    assert track.outcome({"captured": False, "tracking_error_mm": 9.0}).startswith("not captured")


def test_training_evaluation_reports_and_selects_by_the_tasks_score() -> None:
    pytest.importorskip("stable_baselines3")
    from electroloc_gym.baselines import make_agent
    from electroloc_gym.train.callbacks import EVAL_FIELDS, eval_fields, evaluate_agent, score_column

    assert eval_fields(PAPER) == EVAL_FIELDS and score_column(PAPER) == ("mean_readings", True)
    assert score_column(TRACK) == ("mean_tracking_error_mm", True)
    assert {"mean_tracking_error_mm", "capture_rate"} <= set(eval_fields(TRACK)) - set(EVAL_FIELDS)
    row = evaluate_agent(make_agent("rnd-wlk", seed=0), TRACK, {"max_observations": 6}, [100_000, 100_001])
    assert row["mean_tracking_error_mm"] > 0 and 0.0 <= row["capture_rate"] <= 1.0
    assert set(eval_fields(TRACK)) - {"timesteps", "wall_time_s"} == set(row)


def test_learning_curves_take_the_runs_env_and_its_panels(tmp_path: Path, train_summary_json) -> None:
    pytest.importorskip("matplotlib")
    from electroloc_gym.train import curves

    run = tmp_path / "run"
    run.mkdir()
    validation = {"episodes": 1, "first_seed": 1, "env_kwargs": {}}
    train_summary_json(run / "summary.json", TRACK, validation)
    (run / "eval.csv").write_text("timesteps,success_rate,mean_readings,median_readings\n0,0,70,70\n")
    assert curves.run_env_id(run) == TRACK and curves.run_env_id(run / "eval.csv") == TRACK
    assert [p.key for p in curves._panels([TRACK])] == ["capture_rate", "mean_tracking_error_mm"]
    with pytest.raises(ValueError, match="capture_rate"):  # an older log without the task's columns: said
        curves.plot_learning_curves([run], None, tmp_path / "c.png")
    (run / "eval.csv").write_text(
        "timesteps,success_rate,mean_readings,median_readings,mean_tracking_error_mm,capture_rate\n"
        "0,0,70,70,9.5,0.1\n100,0,70,70,7.5,0.3\n"
    )
    assert curves.plot_learning_curves([run], None, tmp_path / "c.png").stat().st_size > 1000


def test_episode_pictures_say_how_a_track_episode_ended() -> None:
    from electroloc_gym.demo import record_episode

    env = gym.make(TRACK, max_observations=4)
    episode = record_episode(env, seed=0)
    env.close()
    words = episode.outcome(episode.final_info)
    assert "captured" in words and "tracking error" in words and "failure" not in words


def test_ppo_minimal_reports_the_tasks_score_on_the_track_env(capsys) -> None:
    pytest.importorskip("torch")
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "ppo_minimal", Path(__file__).resolve().parents[1] / "examples" / "ppo_minimal.py"
    )
    ppo = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(ppo)
    argv = ["--env-id", TRACK, "--total-timesteps", "256", "--num-steps", "32", "--num-envs", "4"]
    result = ppo.main([*argv, "--update-epochs", "1", "--eval-episodes", "2"])
    assert set(result) == {"capture_rate", "mean_tracking_error_mm", "median_observations"}
    assert "capture_rate" in capsys.readouterr().out
