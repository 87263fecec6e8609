r"""Export an rl-zoo3 run folder to a shipped policy folder (pickle-free), with its provenance.

    python -m electroloc_gym.train.export logs/ppo/ElectroLoc-v0_1 --out electroloc_gym/models/ppo-belief
    python -m electroloc_gym.train.export logs/ppo/ElectroLoc-v0_1 --out /tmp/last --trust-pickle \
        --zip logs/ppo/ElectroLoc-v0_1/ElectroLoc-v0.zip

The default path reads only plain files: ``<run>/best/policy.json`` + ``policy.safetensors`` (the
checkpoint :class:`~electroloc_gym.train.callbacks.BenchEvalCallback` chose on the validation
episodes), ``summary.json``, ``eval.csv`` and rl-zoo3's ``config.yml`` / ``args.yml`` (YAML read
with a loader that builds nothing but plain data and ``OrderedDict``). No pickle in the run folder
is ever opened. ``--trust-pickle --zip Z`` converts an SB3 zip of the run instead (it *unpickles*
the zip and ``vecnormalize.pkl``: only for your own runs) and checks that the exported numpy policy
acts as SB3's ``predict`` on sampled observations.

The output folder gets ``policy.json`` (provenance: the exact rl-zoo3 command, seed, timesteps,
wall time, how the checkpoint was chosen), ``policy.safetensors``, ``eval.csv``, ``summary.json``,
``config.yml`` and ``command.txt``, each written atomically.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import yaml

from electroloc_gym.policy.format import read_export, read_weights, write_export
from electroloc_gym.policy.load import agent_from_export
from electroloc_gym.train.summary import TrainSummary, read_summary, write_summary
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options

__all__ = ["export_run", "main"]


def _run_files(run: Path) -> tuple[TrainSummary, dict[str, Any], dict[str, Any]]:
    """(summary.json, config.yml, args.yml) of an rl-zoo3 run folder made through the project's hook."""
    from electroloc_gym.policy.sb3 import read_zoo_yaml

    if not run.is_dir():
        raise ValueError(f"run folder {str(run)!r} does not exist")
    summary_path = run / "summary.json"
    if not summary_path.is_file():
        raise ValueError(f"run folder {run} has no summary.json (not trained with BenchEvalCallback)")
    summary = read_summary(summary_path)
    env_dirs = [d for d in run.iterdir() if d.is_dir() and (d / "config.yml").is_file()]
    if len(env_dirs) != 1:
        raise ValueError(f"run folder {run} must hold exactly one <env>/config.yml (rl-zoo3's layout)")
    args = read_zoo_yaml(env_dirs[0] / "args.yml") if (env_dirs[0] / "args.yml").is_file() else {}
    return summary, read_zoo_yaml(env_dirs[0] / "config.yml"), args


def _sample_observations(env_id: str, env_kwargs: dict[str, Any], n: int = 64, seed: int = 0) -> np.ndarray:
    import gymnasium as gym

    env = gym.make(env_id, **env_kwargs)
    env.action_space.seed(seed)
    out, (obs, _) = [], env.reset(seed=seed)
    while len(out) < n:
        out.append(np.asarray(obs, dtype=np.float32))
        obs, _, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            obs, _ = env.reset(seed=seed + len(out))
    env.close()
    return np.stack(out)


def _from_zip(zip_path: Path, out: Path, summary: TrainSummary) -> dict[str, Any]:
    """Convert a TRUSTED SB3 zip (unpickles) and check the numpy policy against SB3's predict."""
    from electroloc_gym.policy.sb3 import export_meta, load_zoo_run, model_weights

    model, vn, run = load_zoo_run(zip_path)
    cfg, args = run["config"], run["args"]
    env_id = str(args.get("env", summary.env_id))
    env_kwargs = dict(args.get("env_kwargs") or cfg.get("env_kwargs") or {})
    stack = int(cfg.get("frame_stack") or 1)
    meta = export_meta(
        model,
        env_id=env_id,
        env_kwargs=env_kwargs,
        frame_stack=stack,
        vecnormalize=vn,
        provenance={"timesteps": int(model.num_timesteps), "converted_from": zip_path.name},
    )
    write_export(out, meta, model_weights(model))
    agent = agent_from_export(read_export(out))
    frames = _sample_observations(env_id, {**env_kwargs, **agent.env_kwargs}, 64 * stack)
    x = frames.reshape(64, -1)
    if vn is not None and vn.norm_obs:  # rl-zoo3: VecNormalize inside VecFrameStack, per frame
        x = vn.normalize_obs(frames).reshape(64, -1).astype(np.float32)
    expected, _ = model.predict(x, deterministic=True)
    got, _ = agent.actor(x, None, np.ones(64, dtype=bool))
    if not np.allclose(np.asarray(got, float), np.asarray(expected, float), atol=1e-5):
        raise ValueError(
            f"{out}: the exported policy's actions differ from SB3's predict (max |Δ| "
            f"{np.abs(np.asarray(got, float) - np.asarray(expected, float)).max():.3g})"
        )
    print(f"{out}: actions match SB3's predict on 64 observations (|Δ| ≤ 1e-5)")
    return meta


def export_run(
    run: str | Path, out: str | Path, *, zip_path: str | Path | None = None, trust_pickle: bool = False
) -> Path:
    """Export ``run``'s chosen checkpoint (``best/``) — or, trusted, an SB3 zip of it — to ``out``.

    Raises:
        ValueError: not a run folder of this path, no ``best/`` export, a zip without ``trust_pickle``,
            or an export that does not load.
    """
    run, dest = Path(run), Path(out)
    summary, config, args = _run_files(run)
    if zip_path is not None and not trust_pickle:
        raise ValueError("--zip unpickles an SB3 file: pass --trust-pickle for a run you trust")
    dest.mkdir(parents=True, exist_ok=True)
    if zip_path is not None:
        _from_zip(Path(zip_path), dest, summary)
        chosen = f"the SB3 zip {Path(zip_path).name} (converted with --trust-pickle)"
    else:
        best = read_export(run / "best")
        write_export(
            dest,
            {k: v for k, v in best.meta.items() if k not in ("format", "format_version", "weights")},
            read_weights(best),
        )
        chosen = summary.chosen_by
    export = read_export(dest)
    meta = {k: v for k, v in export.meta.items() if k not in ("format", "format_version", "weights")}
    argv = summary.argv or shlex.split(summary.command)[1:]  # without the interpreter
    command = shlex.join(["python", *argv]) if argv else ""
    meta["provenance"] = {
        **dict(meta.get("provenance") or {}),
        "command": command,
        "seed": summary.seed,
        "run_timesteps": summary.timesteps,
        "wall_time_s": summary.wall_time_s,
        "evaluation_time_s": summary.evaluation_time_s,
        "fps_training_only": summary.fps_training_only,
        "checkpoint_chosen_by": chosen,
        "validation": msgspec.to_builtins(summary.validation),
    }
    write_export(dest, meta, read_weights(export))
    agent_from_export(read_export(dest))  # loads as the benchmark loads it
    if (run / "eval.csv").is_file():
        atomic_write_text(dest / "eval.csv", (run / "eval.csv").read_text(encoding="utf-8"))
    write_summary(dest / "summary.json", summary)
    atomic_write_text(
        dest / "config.yml", yaml.safe_dump({"args": _plain(args), "hyperparams": _plain(config)}, sort_keys=False)
    )
    best_row = summary.best or {}
    atomic_write_text(
        dest / "command.txt",
        (
            f"# {dest.name}: {meta['algo']} on {meta['observation']['env_id']} ({meta['observation']['mode']} "
            f"observation), trained by rl-zoo3 through electroloc_gym.train.zoo. Exact command (repository root):\n"
            f"{command}\n"
            f"# seed: {summary.seed}; {summary.timesteps} env steps in "
            f"{summary.wall_time_s} s wall time ({summary.evaluation_time_s} s of it validation; "
            f"{summary.fps_training_only} steps/s "
            f"training only), CPU, torch 1 thread\n"
            f"# checkpoint: {chosen}: the evaluation at {best_row.get('timesteps')} steps "
            f"({_row_words(best_row, meta['observation']['env_id'])}) on "
            f"{summary.validation.episodes} validation episodes (reset seeds from "
            f"{summary.validation.first_seed}; the benchmark's trials are seed 0's)\n"
        ),
    )
    return dest


def _row_words(row: dict[str, Any], env_id: str) -> str:
    """An evaluation row's metrics in words: the task's own evaluation columns where it declares them
    (``Task.metrics.eval_columns``), else the success rate and readings; then the median error.
    """
    from electroloc_gym.registry import env_entry

    own = list(env_entry(env_id).task_class.metrics.eval_columns)
    if own:
        words = ", ".join(f"{k} {row.get(k)}" for k in own)
    else:
        words = (
            f"{row.get('success_rate')} success rate, {row.get('mean_readings')} mean and "
            f"{row.get('median_readings')} median readings"
        )
    return f"{words}, median error {row.get('median_error_mm')} mm"


def _plain(d: Any) -> Any:
    """rl-zoo3's config/args as plain YAML data (anything else as its string)."""
    if isinstance(d, dict):
        return {str(k): _plain(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_plain(v) for v in d]
    return d if isinstance(d, (str, int, float, bool, type(None))) else str(d)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m electroloc_gym.train.export RUN --out FOLDER``; returns the exit status."""
    p = argparse.ArgumentParser(
        prog="python -m electroloc_gym.train.export",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", help="an rl-zoo3 run folder (logs/<algo>/<env>_<n>)")
    p.add_argument("--out", required=True, help="the policy folder to write")
    p.add_argument("--zip", default=None, help="convert this SB3 zip of the run instead of best/ (unpickles)")
    p.add_argument("--trust-pickle", action="store_true", help="allow --zip (only for runs you trust)")
    a = p.parse_args(argv)
    check_output_options(p, folders={"--out": a.out})
    try:
        dest = export_run(a.run, a.out, zip_path=a.zip, trust_pickle=a.trust_pickle)
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"exported {a.run} → {dest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
