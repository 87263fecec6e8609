"""Where does the robot lose its prey: the tracking error of the controllers against the target's speed.

    python experiments/track/speed_sweep.py --trials 16 --out experiments/track/results/speed_sweep.json \
        --figure docs/track_speed_sweep.png

ElectroLocTrack-v0 (the swimmer, turn std 0.5 rad per reading, the filter told a random walk of the
target's own speed; the eight conditions drawn per episode, ``condition="random"``), each controller over
the same seeded episodes at every speed: the episode's tracking error (the belief mean's distance to the
target, averaged over the second half's 35 readings) and the capture (the carriage within 10 mm of the
target at the end). The robot *loses* its prey at the speed where the median tracking error first exceeds
the capture distance (10 mm): beyond it the belief no longer says where to strike. Per-episode results
are kept in the JSON (``--out``); ``--figure`` draws the medians with their interquartile ranges and the
capture rates. Rerun ``--resume`` to add missing (speed, agent) cells to a kept JSON.

Every option is checked before any work, with the checks ``electroloc bench`` makes of its own (the
package's :mod:`~electroloc_gym.utils.checks`, the bench command's integer parser and ranges, its agent
resolution — an agent it would refuse on ``--env track``, such as a policy trained on another env, is
refused here — the output-path check, and the env's speed range): a bad one is argparse's one line
naming it, exit status 2, nothing run or written. ``--resume`` reads the kept JSON first and refuses
one that is not a sweep's or that was run with other settings.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.bench.agents import agent_kind, cached_agent
from electroloc_gym.bench.bench_command import MAX_PARTICLES, MAX_TRIALS, ascii_int
from electroloc_gym.bench.config import BenchConfig
from electroloc_gym.bench.runner import _check_agents as check_bench_agents  # the bench's own agent checks
from electroloc_gym.demo import figure_suffixes
from electroloc_gym.engines.numba_core.track_task import CAPTURE_DISTANCE_MM, MAX_TARGET_SPEED_MM
from electroloc_gym.registry import bench_env
from electroloc_gym.utils.agentspec import split_specs
from electroloc_gym.utils.checks import check_float, check_int
from electroloc_gym.utils.fileio import atomic_write_text, check_output_path, save_figure_atomic
from electroloc_gym.utils.runtime import pin_threads

#: The moving target's env and its bench row's controllers (from the env table).
ENTRY, ROW = bench_env("track")
ENV_ID = ENTRY.env_id
DEFAULT_SPEEDS_MM = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 20.0)
#: The settings a resumed sweep must share with the kept one (they decide every episode).
SAME_SETTINGS = ("trials", "seed", "motion", "motion_model", "motion_step_mm", "sensor_model", "n_particles")
#: The bench command's ``--seed`` range.
MAX_SEED = 2**63 - 1


def episode_seeds(seed: int, trials: int) -> list[tuple[int, int]]:
    """(env seed, agent seed) of every trial, the same at every speed and for every agent."""
    children = np.random.SeedSequence(seed).generate_state(2 * trials)
    return [(int(children[2 * k]), int(children[2 * k + 1])) for k in range(trials)]


def run_cell(agent: str, speed_mm: float, seeds: list[tuple[int, int]], env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """Every trial of one controller at one speed: tracking errors (mm), captures, the condition drawn."""
    # built once and re-seeded every trial, as the benchmark runs it; its own env needs (a learned policy's
    # observation mode) on top of the sweep's settings
    controller = cached_agent(agent)
    needs = dict(getattr(controller, "env_kwargs", {}))
    env = gym.make(ENV_ID, target_speed_mm=speed_mm, **{**env_kwargs, **needs})
    out: dict[str, Any] = {"agent": agent, "speed_mm": speed_mm, "tracking_error_mm": [], "captured": []}
    out["condition"] = []
    t0 = time.perf_counter()
    for env_seed, agent_seed in seeds:
        ep = run_episode(env, controller, env_seed, agent_seed=agent_seed)
        out["tracking_error_mm"].append(float(ep.info["tracking_error_mm"]))
        out["captured"].append(bool(ep.info["captured"]))
        out["condition"].append(env.unwrapped.condition.name)
    out["wall_s"] = time.perf_counter() - t0
    env.close()
    return out


def summarize(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Median, quartiles and capture rate of every (agent, speed) cell, and each agent's losing speed."""
    rows = []
    for c in cells:
        e = np.asarray(c["tracking_error_mm"])
        q25, q50, q75 = (float(q) for q in np.quantile(e, [0.25, 0.5, 0.75]))
        rows.append(
            {
                "agent": c["agent"],
                "speed_mm": c["speed_mm"],
                "trials": int(e.size),
                "median_mm": q50,
                "q25_mm": q25,
                "q75_mm": q75,
                "capture_rate": float(np.mean(c["captured"])),
            }
        )
    return sorted(rows, key=lambda r: (r["agent"], r["speed_mm"]))


def losing_speed(rows: list[dict[str, Any]], agent: str) -> float | None:
    """The first speed (mm per reading) at which ``agent``'s median tracking error exceeds the capture distance."""
    for r in rows:
        if r["agent"] == agent and r["median_mm"] > CAPTURE_DISTANCE_MM:
            return float(r["speed_mm"])
    return None


def verdict(rows: list[dict[str, Any]], agent: str) -> str:
    """One line: where ``agent`` loses its prey, or that it never did up to the fastest speed it ran."""
    lost = losing_speed(rows, agent)
    if lost is not None:
        return f"{agent}: median tracking error above {CAPTURE_DISTANCE_MM:g} mm from {lost:g} mm per reading"
    top = max(float(r["speed_mm"]) for r in rows if r["agent"] == agent)
    return (
        f"{agent}: never lost its prey up to {top:g} mm per reading (median tracking error at most "
        f"{CAPTURE_DISTANCE_MM:g} mm at every speed)"
    )


def draw(rows: list[dict[str, Any]], path: str, title: str) -> None:
    """The medians with their interquartile ranges (left) and the capture rates (right) against the speed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    for j, agent in enumerate(dict.fromkeys(r["agent"] for r in rows)):
        rs = [r for r in rows if r["agent"] == agent]
        v = np.array([r["speed_mm"] for r in rs])
        med = np.array([r["median_mm"] for r in rs])
        lo, hi = np.array([r["q25_mm"] for r in rs]), np.array([r["q75_mm"] for r in rs])
        ax.plot(v, med, "o-", color=f"C{j}", label=agent)
        ax.fill_between(v, lo, hi, color=f"C{j}", alpha=0.15)
        bx.plot(v, [100 * r["capture_rate"] for r in rs], "o-", color=f"C{j}", label=agent)
    ax.axhline(CAPTURE_DISTANCE_MM, color="k", ls=":", lw=1, label="capture distance (10 mm)")
    ax.axvline(10.0, color="grey", ls="--", lw=1, label="carriage's largest move per axis")
    bx.axvline(10.0, color="grey", ls="--", lw=1)
    for a in (ax, bx):
        a.set_xscale("log")
        a.set_xlabel("target speed (mm per reading)")
    ax.set_yscale("log")
    ax.set_ylabel("tracking error, second half (mm): median, IQR")
    bx.set_ylabel("capture rate (%)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)
    bx.legend(fontsize=7)
    fig.tight_layout()
    save_figure_atomic(fig, path, dpi=110)
    plt.close(fig)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options, every one checked before any work (module docstring); a bad one is ``prog: error: …``
    (one line naming it) and exit status 2.
    """
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--speeds",
        type=float,
        nargs="+",
        default=list(DEFAULT_SPEEDS_MM),
        help=f"target speeds, mm per reading, each in [0, {MAX_TARGET_SPEED_MM:g}] (default: %(default)s)",
    )
    p.add_argument(
        "--agents",
        default=",".join(ROW.agents or ()),
        help="comma-separated agent specs as electroloc bench --agents takes them for --env track (controllers, "
        "policy folders) (default: %(default)s)",
    )
    p.add_argument(
        "--trials", type=ascii_int, default=16, help=f"episodes per speed and agent, 1–{MAX_TRIALS} (default: 16)"
    )
    p.add_argument("--seed", type=ascii_int, default=0, help="root seed of the episodes' seeds, ≥ 0 (default: 0)")
    p.add_argument(
        "--motion",
        default="swimmer",
        choices=["swimmer", "random_walk"],
        help="the target's motion (default: %(default)s)",
    )
    p.add_argument(
        "--motion-model",
        default="random_walk",
        choices=["random_walk", "static"],
        help="what the filter is told (default: %(default)s)",
    )
    p.add_argument(
        "--motion-step-mm",
        type=float,
        default=None,
        help=f"the filter's RMS step, mm, in [0, {MAX_TARGET_SPEED_MM:g}] (default: the target's speed)",
    )
    p.add_argument(
        "--sensor-model",
        default=ENTRY.sensor_models[0],
        choices=list(ENTRY.sensor_models),
        help="the filter's sensor model (default: %(default)s)",
    )
    p.add_argument("--n-particles", type=ascii_int, default=2500, help=f"particles, 2–{MAX_PARTICLES} (default: 2500)")
    p.add_argument(
        "--out",
        default=None,
        help="the JSON of every episode's result (kept; --resume reads it) (default: none written)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the cells already in --out, run the others (default: run every cell)",
    )
    p.add_argument("--figure", default=None, help="the figure to write (PNG, PDF, SVG, ...) (default: none drawn)")
    args = p.parse_args(argv)
    try:
        args.kept_cells = check_args(args)
    except ValueError as exc:
        p.error(str(exc))
    return args


def check_args(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Every option as ``electroloc bench`` checks its own (module docstring); returns the cells a ``--resume``
    keeps (none without it).

    Raises:
        ValueError: the first bad option, one line naming it.
    """
    for v in args.speeds:
        check_float("--speeds", v, 0.0, inclusive=True, high=MAX_TARGET_SPEED_MM)
    twice = sorted({float(v) for v in args.speeds if [float(u) for u in args.speeds].count(float(v)) > 1})
    if twice:
        raise ValueError(f"--speeds names {', '.join(f'{v:g}' for v in twice)} more than once")
    check_int("--trials", args.trials, 1, MAX_TRIALS)
    check_int("--seed", args.seed, 0, MAX_SEED)
    check_int("--n-particles", args.n_particles, 2, MAX_PARTICLES)
    if args.motion_step_mm is not None:
        check_float("--motion-step-mm", args.motion_step_mm, 0.0, inclusive=True, high=MAX_TARGET_SPEED_MM)
    if args.out is not None:
        check_output_path("--out", args.out, ("json",))
    if args.figure is not None:
        check_output_path("--figure", args.figure, figure_suffixes())
    if args.resume and args.out is None:
        raise ValueError("--resume needs --out, the JSON of the sweep to continue")
    check_agents(args)
    kwargs = env_kwargs(args)
    try:  # the env's own checks of the sweep's settings together
        gym.make(ENV_ID, target_speed_mm=float(max(args.speeds)), **kwargs).close()
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{ENV_ID} refuses the sweep's settings: {exc}") from None
    return kept_cells(args) if args.resume and Path(args.out).exists() else []


def check_agents(args: argparse.Namespace) -> None:
    """``--agents`` as ``electroloc bench --env track --agents`` resolves and checks it (the same messages).

    Raises:
        ValueError: an agent the bench would refuse there, or a list it would refuse.
    """
    try:
        specs = split_specs(args.agents)
    except ValueError as exc:
        raise ValueError(f"--agents: {exc}") from None
    if not any(specs):
        raise ValueError(f"--agents names no agent (got {args.agents!r})")
    if not all(specs):
        raise ValueError(f"--agents has an empty item in {args.agents!r}")
    try:
        for spec in specs:
            agent_kind(spec)
        config = BenchConfig.build(
            specs,
            env=ROW.name,
            trials=args.trials,
            seed=args.seed,
            sensor_model=args.sensor_model,
            n_particles=args.n_particles,
        )
        _, warnings = check_bench_agents(config, trust_pickle=False)
    except ValueError as exc:
        raise ValueError(f"--agents: {exc}") from None
    for line in warnings:
        print(line, file=sys.stderr)


def env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The sweep's env settings (the speed aside)."""
    return {
        "condition": "random",
        "target_motion": args.motion,
        "motion_model": args.motion_model,
        "motion_step_mm": args.motion_step_mm,
        "sensor_model": args.sensor_model,
        "n_particles": args.n_particles,
    }


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    return {k: v for k, v in vars(args).items() if k not in ("out", "resume", "figure", "kept_cells")}


def _is_cell(c: Any, trials: int) -> bool:
    """A kept cell of ``trials`` episodes, as :func:`run_cell` writes it."""
    if not isinstance(c, dict) or not isinstance(c.get("agent"), str) or not c["agent"]:
        return False
    speed = c.get("speed_mm")
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not 0 <= speed <= MAX_TARGET_SPEED_MM:
        return False
    lists = [c.get(k) for k in ("tracking_error_mm", "captured", "condition")]
    if not all(isinstance(v, list) and len(v) == trials for v in lists):
        return False
    errors, captured, conditions = lists
    return (
        all(not isinstance(e, bool) and isinstance(e, (int, float)) and math.isfinite(e) and e >= 0 for e in errors)
        and all(isinstance(b, bool) for b in captured)
        and all(isinstance(n, str) for n in conditions)
    )


def kept_cells(args: argparse.Namespace) -> list[dict[str, Any]]:
    """The cells of the sweep ``--out`` holds, for ``--resume``: refused unless it is a sweep's JSON of the same
    :data:`SAME_SETTINGS` with every cell whole.

    Raises:
        ValueError: one line naming ``--out`` and what is wrong.
    """
    path = Path(args.out)
    try:
        kept = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else f"{type(exc).__name__}"
        raise ValueError(f"--out {str(path)!r} cannot be resumed: not JSON that can be read ({why})") from None
    settings = _settings(args)
    cells = kept.get("cells") if isinstance(kept, dict) else None
    stored = kept.get("settings") if isinstance(kept, dict) else None
    if not isinstance(stored, dict) or not isinstance(cells, list) or not all(_is_cell(c, args.trials) for c in cells):
        raise ValueError(
            f"--out {str(path)!r} cannot be resumed: not a speed sweep's JSON of {args.trials} trials per cell "
            "(settings, cells); choose another --out or run without --resume to replace it"
        )
    differ = {k: (stored.get(k), settings[k]) for k in SAME_SETTINGS if stored.get(k) != settings[k]}
    if differ:
        raise ValueError(
            f"--out {str(path)!r} holds a sweep of other settings (kept, now): {differ}; resume with its settings, "
            "choose another --out or run without --resume to replace it"
        )
    keys = [(c["agent"], float(c["speed_mm"])) for c in cells]
    if len(set(keys)) != len(keys):
        raise ValueError(f"--out {str(path)!r} cannot be resumed: it holds a (agent, speed) cell more than once")
    return cells


def main(argv: list[str] | None = None) -> dict[str, Any]:
    pin_threads()
    args = parse_args(argv)
    try:
        return sweep(args)
    except OSError as exc:  # the disk refused a write after the checks: which file, and why
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{Path(sys.argv[0]).name}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        raise SystemExit(2) from None


def sweep(args: argparse.Namespace) -> dict[str, Any]:
    """Run the cells not kept, write the JSON after each, summarise, print and draw."""
    kwargs = env_kwargs(args)
    settings = _settings(args)
    cells: list[dict[str, Any]] = list(args.kept_cells)
    seeds = episode_seeds(args.seed, args.trials)
    done = {(c["agent"], float(c["speed_mm"])) for c in cells}
    for agent in split_specs(args.agents):
        for v in args.speeds:
            if (agent, float(v)) in done:
                continue
            cells.append(run_cell(agent, float(v), seeds, kwargs))
            c = cells[-1]
            print(
                f"{agent:>8} {v:5.1f} mm/reading: median {np.median(c['tracking_error_mm']):6.1f} mm, "
                f"captures {sum(c['captured'])}/{len(c['captured'])} ({c['wall_s']:.0f} s)",
                flush=True,
            )
            if args.out:  # after every cell: an interrupted sweep resumes
                atomic_write_text(args.out, json.dumps({"settings": settings, "cells": cells}, indent=1))
    settings["speeds"] = sorted({c["speed_mm"] for c in cells})  # a resumed sweep: every cell's
    settings["agents"] = ",".join(dict.fromkeys(c["agent"] for c in cells))
    rows = summarize(cells)
    agents = list(dict.fromkeys(r["agent"] for r in rows))
    lost = {a: losing_speed(rows, a) for a in agents}
    result = {"settings": settings, "rows": rows, "losing_speed_mm": lost, "cells": cells}
    if args.out:
        atomic_write_text(args.out, json.dumps(result, indent=1))
    for a in agents:
        print(verdict(rows, a))
    if args.figure:
        draw(rows, args.figure, f"{ENV_ID}, {args.motion}, {args.trials} episodes per point (8 conditions)")
    for path in (args.out, args.figure):
        if path:
            print(f"wrote: {path}", file=sys.stderr)
    return result


if __name__ == "__main__":
    main()
