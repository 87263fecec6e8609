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
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.bench.agents import cached_agent
from electroloc_gym.engines.numba_core.track_task import CAPTURE_DISTANCE_MM
from electroloc_gym.registry import bench_env
from electroloc_gym.utils.fileio import atomic_write_text
from electroloc_gym.utils.runtime import pin_threads

#: The moving target's env and its bench row's controllers (from the env table).
ENTRY, ROW = bench_env("track")
ENV_ID = ENTRY.env_id
DEFAULT_SPEEDS_MM = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 20.0)


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
        out["condition"].append(str(ep.info["condition"]))
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
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    pin_threads()
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--speeds", type=float, nargs="+", default=list(DEFAULT_SPEEDS_MM), help="mm per reading")
    p.add_argument(
        "--agents",
        default=",".join(ROW.agents or ()),
        help="comma-separated agent specs as electroloc bench --agents takes them (controllers, policy folders)",
    )
    p.add_argument("--trials", type=int, default=16, help="episodes per speed and agent")
    p.add_argument("--seed", type=int, default=0, help="root seed of the episodes' seeds")
    p.add_argument("--motion", default="swimmer", choices=["swimmer", "random_walk"], help="the target's motion")
    p.add_argument(
        "--motion-model", default="random_walk", choices=["random_walk", "static"], help="what the filter is told"
    )
    p.add_argument(
        "--motion-step-mm", type=float, default=None, help="the filter's RMS step (default: the target's speed)"
    )
    p.add_argument("--sensor-model", default="calibrated", choices=["calibrated", "analytic"])
    p.add_argument("--n-particles", type=int, default=2500)
    p.add_argument("--out", default=None, help="the JSON of every episode's result (kept; --resume reads it)")
    p.add_argument("--resume", action="store_true", help="keep the cells already in --out, run the others")
    p.add_argument("--figure", default=None, help="the PNG to write")
    args = p.parse_args(argv)
    env_kwargs = {
        "condition": "random",
        "target_motion": args.motion,
        "motion_model": args.motion_model,
        "motion_step_mm": args.motion_step_mm,
        "sensor_model": args.sensor_model,
        "n_particles": args.n_particles,
    }
    settings = {k: v for k, v in vars(args).items() if k not in ("out", "resume", "figure")}
    cells: list[dict[str, Any]] = []
    if args.resume and args.out and Path(args.out).exists():
        kept = json.loads(Path(args.out).read_text())
        same = ("trials", "seed", "motion", "motion_model", "motion_step_mm", "sensor_model", "n_particles")
        if all(kept.get("settings", {}).get(k) == settings[k] for k in same):
            cells = kept["cells"]
    seeds = episode_seeds(args.seed, args.trials)
    done = {(c["agent"], c["speed_mm"]) for c in cells}
    for agent in args.agents.split(","):
        for v in args.speeds:
            if (agent, float(v)) in done:
                continue
            cells.append(run_cell(agent, float(v), seeds, env_kwargs))
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
        print(f"{a}: median tracking error above {CAPTURE_DISTANCE_MM:g} mm from {lost[a]} mm per reading")
    if args.figure:
        draw(rows, args.figure, f"{ENV_ID}, {args.motion}, {args.trials} episodes per point (8 conditions)")
    return result


if __name__ == "__main__":
    main()
