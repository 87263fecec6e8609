"""Env steps/s: single env vs SyncVectorEnv vs the native batched vector env.

ElectroLoc-v0 by default, ElectroLocGlobal-v0 with ``--env``.

Prints, side by side in one run, env steps per second (every sub-env step counts; autoresets
included, random actions, so episodes end and reset as in training) of

* one single env (``gym.make``, reset on episode end),
* ``gym.make_vec(..., vectorization_mode="sync")`` (SyncVectorEnv) at each N,
* ``gym.make_vec(..., vectorization_mode="vector_entry_point")`` (native) at each N,

and the native/sync ratio. Every row runs in a fresh interpreter. The host's speed drifts by ±20 %
over minutes, so the rows are measured in interleaved passes (all rows, then all rows again; each
a fresh process timing a few short rounds) and each row's best is kept. Throughput is reported per
CPU-second of the measuring process (``time.process_time``, insensitive to other processes taking
the cores) and per wall second. Numeric libraries are pinned to one thread.

    python benchmarks/vector_env.py [--n-envs 16 64] [--particles 2500] [--observation belief]
        [--sensor-model calibrated] [--env ElectroLoc-v0] [--seconds 1.5] [--rounds 2] [--passes 3] [--json out.json]
        [--before DIR] [--now-kwargs JSON] [--beside ENV_ID] [--profile]

``--beside ENV_ID`` also measures that env's native vector env at the same N, particles, observation and
sensor model, interleaved with the others, and prints both envs' CPU cost per env-step and their ratio
(e.g. ``--env ElectroLocTrack-v0 --beside ElectroLoc-v0``: the moving target's cost against the paper's env).

``--profile`` instead prints where a native vector step's time goes (cProfile, the first N, sorted
by own time, per env-step).
"""

from __future__ import annotations

import os

from electroloc_gym.utils.runtime import pin_threads

pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402, F401  (registers the ids)
from electroloc_gym.protocol import N_PARTICLES  # noqa: E402
from electroloc_gym.registry import ENV_IDS, PAPER_ENV_ID, env_entry  # noqa: E402
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options  # noqa: E402


class _Single:
    """A single env driven like a vector env of one (reset on episode end)."""

    def __init__(self, env_id: str, kwargs: dict[str, Any]) -> None:
        self.env = gym.make(env_id, **kwargs)
        self.num_envs = 1

    def reset(self, seed: int) -> None:
        self.env.reset(seed=seed)

    def step(self, actions: np.ndarray) -> None:
        _, _, term, trunc, _ = self.env.step(actions[0])
        if term or trunc:
            self.env.reset()


def _round(env: Any, n_steps: int, rng: np.random.Generator) -> tuple[float, float]:
    """(CPU seconds, wall seconds) for ``n_steps`` vector steps with random actions."""
    actions = rng.uniform(-1, 1, size=(n_steps, env.num_envs, 2)).astype(np.float32)
    c0, w0 = time.process_time(), time.perf_counter()
    for a in actions:
        env.step(a)
    return time.process_time() - c0, time.perf_counter() - w0


def measure(make: Callable[[], Any], seconds: float, rounds: int, seed: int = 0) -> dict[str, float]:
    """Best-of-``rounds`` env steps/s (CPU and wall) of a freshly made env."""
    env = make()
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    _round(env, 3, rng)  # warm-up (first calibrations, caches)
    cpu, _ = _round(env, 5, rng)
    n_steps = max(5, int(seconds / max(cpu / 5, 1e-6)))
    best_cpu = best_wall = float("inf")
    for _ in range(rounds):
        c, w = _round(env, n_steps, rng)
        best_cpu, best_wall = min(best_cpu, c / n_steps), min(best_wall, w / n_steps)
    if hasattr(env, "close"):
        env.close()
    n = env.num_envs
    return {"steps_per_s_cpu": n / best_cpu, "steps_per_s_wall": n / best_wall, "vector_steps": n_steps}


def _make(backend: str, n: int, kwargs: dict[str, Any], env_id: str = PAPER_ENV_ID) -> Any:
    if backend == "single":
        return _Single(env_id, kwargs)
    if backend == "sync":
        return gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", **kwargs)
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def measure_isolated(
    backend: str,
    n: int,
    kwargs: dict[str, Any],
    seconds: float,
    rounds: int,
    env_id: str = PAPER_ENV_ID,
    tree: str | None = None,
) -> dict[str, float]:
    """:func:`measure` in a fresh interpreter, so that allocator state and caches of one configuration
    do not leak into another; ``tree``: a checkout of other code to measure instead (its own copy of
    this script, its package first on ``PYTHONPATH``).
    """
    spec = {"backend": backend, "n": n, "kwargs": kwargs, "env_id": env_id, "seconds": seconds, "rounds": rounds}
    script = __file__ if tree is None else str(Path(tree) / "benchmarks" / "vector_env.py")
    env = None if tree is None else dict(os.environ, PYTHONPATH=str(Path(tree).resolve()))
    cmd = [sys.executable, script, "--_one", json.dumps(spec)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    return json.loads(out.strip().splitlines()[-1])


def profile_native(env_id: str, n: int, kwargs: dict[str, Any], n_steps: int = 300) -> None:
    """Print the native env's step profile: own time per env-step of the 15 costliest functions."""
    import cProfile
    import pstats

    env = _make("native", n, kwargs, env_id)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    _round(env, 20, rng)  # warm-up: compiled kernels, first calibrations
    actions = rng.uniform(-1, 1, size=(n_steps, n, 2)).astype(np.float32)
    prof = cProfile.Profile()
    prof.enable()
    for a in actions:
        env.step(a)
    prof.disable()
    st = pstats.Stats(prof)
    rows = sorted(st.stats.items(), key=lambda kv: -kv[1][2])[:15]  # type: ignore[attr-defined]
    total = sum(v[2] for v in st.stats.values())  # type: ignore[attr-defined]
    per = 1e6 / (n_steps * n)
    print(f"native {env_id} N={n}, {n_steps} steps under cProfile: {total * per:.0f} µs per env-step in all")
    print(f"{'own µs/env-step':>16}  function")
    for (file, line, name), v in rows:
        print(f"{v[2] * per:>16.1f}  {name} ({Path(file).name}:{line})")


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-envs", type=int, nargs="+", default=[16, 64])
    ap.add_argument("--particles", type=int, default=N_PARTICLES)
    ap.add_argument("--observation", default="belief", choices=["belief", "raw"])
    ap.add_argument("--sensor-model", default="calibrated", choices=["calibrated", "analytic"])
    ap.add_argument("--condition", default="fresh-steel-12.7", help="ElectroLoc-v0 only")
    ap.add_argument("--env", default=PAPER_ENV_ID, choices=list(ENV_IDS))
    ap.add_argument(
        "--beside",
        default=None,
        choices=list(ENV_IDS),
        help="also measure this env's native vector env at the same N and particles, and print the CPU cost "
        "per env-step of both and their ratio",
    )
    ap.add_argument("--seconds", type=float, default=1.5, help="target CPU seconds per timed round")
    ap.add_argument("--rounds", type=int, default=2, help="timed rounds per process (the best is kept)")
    ap.add_argument("--passes", type=int, default=3, help="interleaved passes over the rows (the best is kept)")
    ap.add_argument("--json", default=None, help="also write the results here")
    ap.add_argument("--profile", action="store_true", help="profile the native env's step instead")
    ap.add_argument(
        "--before",
        default=None,
        metavar="DIR",
        help="also measure the code of this checkout (e.g. a `git worktree` of an older commit), "
        "interleaved with the current code's rows",
    )
    ap.add_argument(
        "--now-kwargs",
        default="{}",
        metavar="JSON",
        help="extra env arguments for the current code's rows only (e.g. an older default)",
    )
    ap.add_argument("--_one", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    check_output_options(ap, files={"--json": args.json})
    if args._one:
        spec = json.loads(args._one)
        res = measure(
            lambda: _make(spec["backend"], spec["n"], spec["kwargs"], spec["env_id"]), spec["seconds"], spec["rounds"]
        )
        print(json.dumps(res))
        return res

    def env_kwargs(env_id: str) -> dict[str, Any]:
        out = {"n_particles": args.particles, "observation": args.observation, "sensor_model": args.sensor_model}
        if env_entry(env_id).takes("condition"):
            out["condition"] = args.condition
        return out

    kwargs = env_kwargs(args.env)
    if args.profile:
        profile_native(args.env, args.n_envs[0], kwargs)
        return {}
    results: dict[str, Any] = {"env": args.env, "kwargs": kwargs, "rows": []}
    now_kwargs = dict(kwargs, **json.loads(args.now_kwargs))
    trees: list[tuple[str, str | None]] = [("now", None)] + ([("before", args.before)] if args.before else [])
    rows = [("single", 1)] + [(b, n) for n in args.n_envs for b in ("sync", "native")]
    configs = [(code, tree, b, n, args.env) for code, tree in trees for b, n in rows]
    if args.beside:
        configs += [("beside", None, "native", n, args.beside) for n in args.n_envs]
    print(
        f"{args.env} {kwargs}, random actions, autoreset; {args.passes} interleaved passes over the rows, each "
        f"row in a fresh process timing the best of {args.rounds} rounds; the best pass is kept",
        flush=True,
    )
    # The host's speed drifts by ±20 % over minutes: the rows are measured in interleaved passes
    # (single, sync 16, native 16, sync 64, ... , then again), so that every row sees the same phases.
    best: dict[tuple[str, str, int], dict[str, float]] = {}
    for _ in tqdm(range(args.passes), desc="passes", leave=False, disable=None):
        for code, tree, backend, n, env_id in configs:
            run_kwargs = env_kwargs(env_id) if code == "beside" else now_kwargs if tree is None else kwargs
            r = measure_isolated(backend, n, run_kwargs, args.seconds, args.rounds, env_id, tree)
            old = best.get((code, backend, n))
            best[(code, backend, n)] = {
                "steps_per_s_cpu": max(r["steps_per_s_cpu"], old["steps_per_s_cpu"] if old else 0),
                "steps_per_s_wall": max(r["steps_per_s_wall"], old["steps_per_s_wall"] if old else 0),
                "vector_steps": r["vector_steps"],
            }
    print(f"{'code':<7} {'backend':<8} {'N':>4} {'steps/s (CPU)':>14} {'steps/s (wall)':>15} {'vs sync (CPU)':>14}")
    for code, _, backend, n, _ in configs:
        r = best[(code, backend, n)]
        base = best[(code, "sync", n)]["steps_per_s_cpu"] if backend == "native" and (code, "sync", n) in best else None
        ratio = r["steps_per_s_cpu"] / base if base else None
        rs = f"{ratio:>13.2f}x" if ratio else f"{'':>14}"
        print(
            f"{code:<7} {backend:<8} {n:>4} {r['steps_per_s_cpu']:>14.0f} {r['steps_per_s_wall']:>15.0f} {rs}",
            flush=True,
        )
        results["rows"].append({"code": code, "backend": backend, "n_envs": n, **r, "ratio_vs_sync_cpu": ratio})
    if args.beside:
        results["beside"] = {"env": args.beside, "kwargs": env_kwargs(args.beside), "rows": []}
        print(f"native vector env, CPU µs per env-step: {args.env} beside {args.beside}")
        for n in args.n_envs:
            us, us_beside = (1e6 / best[(c, "native", n)]["steps_per_s_cpu"] for c in ("now", "beside"))
            print(f"N={n:<5} {args.env} {us:8.1f}   {args.beside} {us_beside:8.1f}   ratio {us / us_beside:.2f}x")
            results["beside"]["rows"].append({"n_envs": n, "us_per_env_step": us, "beside_us_per_env_step": us_beside})
    if args.json:
        atomic_write_text(args.json, json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main()
