"""The unknown-target env's radius estimates against the exact posterior of the whole reading history.

Runs an agent on ElectroLocUnknownTarget-v0 over the paper's eight sphere/water pairs (the sphere hidden,
the benchmark's per-trial seeds, :func:`electroloc_gym.bench.config.trial_seeds`) and, at the end of every
episode, compares the belief's radius estimates (the particles' median, the env's estimate, and their
mean) with the exact posterior of the readings the episode took: a grid over x, y (``--grid-mm`` steps
over the allowed box), the radius (0.25 mm steps over the prior's 5–20 mm) and both materials, with the
theoretical EEV and the uniform prior the env uses. Prints the median relative radius error of each
estimate over the successful trials (docs/extensions.md, "The radius estimate").

    python experiments/unknown_target/radius_posterior.py --agent min-var --seed 101 --trials 6
"""

from __future__ import annotations

import argparse
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.bench.agents import make_bench_agent  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.engines.numba_core.unknown import CONDUCTOR_CHI, INSULATOR_CHI  # noqa: E402
from electroloc_gym.registry import task_entry  # noqa: E402
from electroloc_gym.sensor_models.shape import TheoreticalShapeModel  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, get_condition  # noqa: E402

RADII_MM = np.arange(5.0, 20.0 + 1e-9, 0.25)


def grid_posterior(env: gym.Env, history: list[tuple[np.ndarray, float]], step_mm: float) -> np.ndarray:
    """The posterior of the radius (over :data:`RADII_MM`) given the readings ``history`` (carriage
    position mm, reading V), marginalised over x, y on a grid and both materials.
    """
    core = env.unwrapped
    model = TheoreticalShapeModel(core.condition)
    half = float(np.asarray(core.allowed_box_mm[1])[0])
    xs = np.arange(-half, half + 1e-9, step_mm)
    x, y, r = np.meshgrid(xs, xs, RADII_MM, indexing="ij")
    chis = (CONDUCTOR_CHI, INSULATOR_CHI)
    logs = [np.zeros(x.shape) for _ in chis]
    for pos, reading in history:
        off = np.stack([x - pos[0], y - pos[1]], axis=-1)
        for ll, chi in zip(logs, chis, strict=True):
            ll += model.log_likelihood(reading, off, r, np.full(r.shape, chi))
    top = max(v.max() for v in logs)
    p = sum(np.exp(v - top).sum(axis=(0, 1)) for v in logs)
    return p / p.sum()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--agent", default=MinVarianceAgent.name, help="an agent spec as electroloc bench takes it")
    ap.add_argument("--seed", type=int, default=101, help="root seed of the trial seeds")
    ap.add_argument("--trials", type=int, default=6, help="trials per condition")
    ap.add_argument("--grid-mm", type=float, default=2.0, help="x–y step of the posterior grid, mm")
    args = ap.parse_args()
    agent = make_bench_agent(args.agent)
    errors: dict[str, list[float]] = {
        "the particles' median (the env's estimate)": [],
        "the particles' mean": [],
        "the exact posterior's median": [],
        "the exact posterior's mode": [],
    }
    for name in tqdm(PRESET_NAMES, desc="conditions"):
        env = gym.make(task_entry("unknown").env_id, condition=get_condition(name), target_draw="condition")
        for t in range(args.trials):
            env_seed, agent_seed = trial_seeds(args.seed, name, t)
            history: list[tuple[np.ndarray, float]] = []

            def record(info: dict, history: list = history) -> None:
                history.append((np.asarray(info["position_mm"], dtype=float), float(info["reading_V"])))

            episode = run_episode(env, agent, env_seed, agent_seed=agent_seed, on_step=record)
            if not episode.terminated:
                continue
            info, truth = episode.info, float(episode.info["target_radius_mm"])
            p = grid_posterior(env, history, args.grid_mm)
            estimates = (
                info["radius_estimate_mm"],
                info["radius_mean_mm"],
                RADII_MM[np.searchsorted(np.cumsum(p), 0.5)],
                RADII_MM[np.argmax(p)],
            )
            for key, est in zip(errors, estimates, strict=True):
                errors[key].append(abs(float(est) - truth) / truth)
    n = len(next(iter(errors.values())))
    print(f"{args.agent}, seed {args.seed}, {args.trials} trials per condition: {n} successes")
    for line in markdown_table(
        ("radius estimate", "median relative error", "within 20 %"),
        [
            (key, f"{100 * np.median(e):.1f} %", f"{100 * np.mean(np.asarray(e) <= 0.2):.0f} %")
            for key, e in errors.items()
        ],
    ):
        print(line)


if __name__ == "__main__":
    main()
