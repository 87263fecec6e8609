"""Env-steps/s of ElectroLoc-v0 with K sensing pairs against the paper's one pair, and the cost per extra pair.

One seeded single env per layout (2500 particles, ``success_spread_mm`` tiny and the cap large, so every step is a
full step: K readings and K filter updates), a warm-up, then ``--steps`` timed steps of random moves; the best of
``--repeats`` runs. Cost per extra pair = (t_K − t_1) / (K − 1) per step.

    python benchmarks/array_speed.py --steps 300 --out docs/array_speed.json
"""

from __future__ import annotations

import argparse
import time

from electroloc_gym.utils.runtime import pin_threads

pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import electroloc_gym  # noqa: E402, F401
from electroloc_gym.protocol import N_PARTICLES  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options, write_json_atomic  # noqa: E402

LAYOUTS = ("single", "grid-2x2", "line-4", "ring-8")


def seconds_per_step(layout: str, sensor_model: str, steps: int, repeats: int, n_particles: int) -> float:
    """Best-of-``repeats`` wall seconds per env step."""
    env = gym.make(
        PAPER_ENV_ID,
        sensor_layout=layout,
        sensor_model=sensor_model,
        n_particles=n_particles,
        success_spread_mm=1e-9,
        max_observations=10**9,
    ).unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, 2)).astype(np.float32)
    for a in actions[:20]:
        env.step(a)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for a in actions:
            env.step(a)
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--n-particles", type=int, default=N_PARTICLES)
    p.add_argument("--out", default=None)
    args = p.parse_args()
    check_output_options(p, files={"--out": args.out})
    rows = []
    for model in ("calibrated", "analytic"):
        base = None
        for lay in LAYOUTS:
            t = seconds_per_step(lay, model, args.steps, args.repeats, args.n_particles)
            k = gym.make(PAPER_ENV_ID, sensor_layout=lay, n_particles=10).unwrapped.sensor_layout.n_pairs
            base = t if lay == "single" else base
            extra = (t - base) / (k - 1) * 1e3 if k > 1 else None
            rows.append(
                {
                    "sensor_model": model,
                    "layout": lay,
                    "K": k,
                    "steps_per_s": 1.0 / t,
                    "ms_per_step": t * 1e3,
                    "ms_per_extra_pair": extra,
                }
            )
            print(
                f"{model:10s} {lay:9s} K={k}  {1.0 / t:8.1f} steps/s  {t * 1e3:6.2f} ms/step"
                + ("" if extra is None else f"  {extra:5.2f} ms per extra pair"),
                flush=True,
            )
    if args.out:
        write_json_atomic(args.out, {"n_particles": args.n_particles, "steps": args.steps, "rows": rows})


if __name__ == "__main__":
    main()
