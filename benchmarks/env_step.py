"""Single-env step throughput vs the cost of the core's bare reading-and-update.

Prints env steps/s for ElectroLoc-v0 in belief mode at 2500 particles with the analytic and the
calibrated sensor model, the cost of the simulation core's bare reading and belief update for the
env (draws, true reading, sensor model on all particles, weights, resampling, jitter, statistics:
``Simulation._observe``), and their ratio. Numeric libraries are pinned to one thread.

    python benchmarks/env_step.py [--steps 3000] [--particles 2500]
"""

from __future__ import annotations

import argparse
import time

from electroloc_gym.utils.runtime import pin_threads

pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise

import numpy as np  # noqa: E402

from electroloc_gym.envs import ElectroLocEnv  # noqa: E402
from electroloc_gym.envs.localize import LocalizeEnv  # noqa: E402
from electroloc_gym.protocol import N_PARTICLES  # noqa: E402


def best_of(fn, n: int, repeats: int = 5) -> float:
    """Best mean seconds per call over ``repeats`` blocks of ``n`` calls (robust to a busy machine)."""
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t) / n)
    return best


def bare_update_cost(env: LocalizeEnv, n: int) -> float:
    """Seconds for the core's reading and belief update of the env (no motion, observation or info)."""
    sim = env._sim
    ids = np.arange(1)
    return best_of(lambda: sim._observe(ids), n)


def env_step_cost(env: LocalizeEnv, n: int) -> float:
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    actions = rng.uniform(-1, 1, size=(n, 2)).astype(np.float32)
    i = 0

    def one() -> None:
        nonlocal i
        env.step(actions[i % n])
        i += 1

    return best_of(one, n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--particles", type=int, default=N_PARTICLES)
    args = ap.parse_args()
    print(f"{'sensor model':<12} {'env steps/s':>12} {'env step ms':>12} {'bare update ms':>15} {'ratio':>7}")
    for model in ("analytic", "calibrated"):
        # Never terminate, so every step does the full work.
        env = ElectroLocEnv(
            sensor_model=model, n_particles=args.particles, max_observations=10**9, success_spread_mm=1e-9
        )
        env.reset(seed=0)
        bare = bare_update_cost(env, args.steps)
        step = env_step_cost(env, args.steps)
        print(f"{model:<12} {1 / step:>12.0f} {step * 1e3:>12.3f} {bare * 1e3:>15.3f} {step / bare:>7.2f}")


if __name__ == "__main__":
    main()
