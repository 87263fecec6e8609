"""Env-steps/s of ElectroLoc-v0's torch backend on a device, beside the numba native vector env.

One command, the same on the CPU and on CUDA::

    python benchmarks/device_throughput.py --device cuda --out results/device_throughput_cuda.json
    python benchmarks/device_throughput.py --device cpu --n-envs 64 256 1024 --out /tmp/cpu.json

For each N of ``--n-envs`` (default 64 … 65536; sizes that do not fit in the device's memory are
reported as such and skipped), the torch backend's env-steps per second (every sub-env step counts;
random actions, so episodes end and reset as in training), eager and, with ``--compile``, through
``torch.compile`` (inductor); beside it the numba native vector env at ``--numba-n`` on one CPU core
(per CPU-second of this process). Rates are wall-clock on CUDA (after ``torch.cuda.synchronize``) and
per CPU-second on the CPU. Also the state's bytes per env and, on CUDA, the peak allocated bytes per
env of a step. Then the on-device PPO of ``examples/ppo_torch.py`` at ``--ppo-n`` envs (0: skipped):
its training env-steps per second (rollouts and updates) over two updates. Prints a table and writes
JSON (atomically). Numeric libraries run on one thread.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import electroloc_gym  # noqa: E402, F401  (registers the ids)
from electroloc_gym.fileio import atomic_write_text  # noqa: E402

DEFAULT_N = (64, 256, 1024, 4096, 16384, 65536)


def _clock(device: torch.device) -> float:
    if device.type == "cuda":
        torch.cuda.synchronize(device)
        return time.perf_counter()
    return time.process_time()


def torch_rate(
    n: int, device: torch.device, seconds: float, compile_step: bool, kwargs: dict[str, Any]
) -> dict[str, Any]:
    """Env-steps/s of the torch backend at N = ``n`` (warm-up steps first, then ``seconds`` of steps)."""
    env = gym.make_vec(
        "ElectroLoc-v0",
        num_envs=n,
        vectorization_mode="vector_entry_point",
        backend="torch",
        device=str(device),
        compile=compile_step,
        **kwargs,
    )
    env.reset(seed=0)
    gen = torch.Generator(device=device).manual_seed(0)
    actions = [torch.rand(n, 2, generator=gen, device=device) * 2 - 1 for _ in range(8)]
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    t0 = time.perf_counter()
    for a in actions[:3]:
        env.step(a)
    warm_s = time.perf_counter() - t0
    steps, start = 0, _clock(device)
    while True:
        env.step(actions[steps % len(actions)])
        steps += 1
        if steps % 4 == 0 and _clock(device) - start >= seconds:
            break
    elapsed = _clock(device) - start
    out = {
        "n_envs": n,
        "compile": compile_step,
        "env_steps_per_s": n * steps / elapsed,
        "steps": steps,
        "warmup_s": warm_s,
        "state_bytes_per_env": env.memory_bytes_per_env(),
    }
    if device.type == "cuda":
        out["peak_bytes_per_env"] = torch.cuda.max_memory_allocated(device) / n
    return out


def numba_rate(n: int, seconds: float, kwargs: dict[str, Any]) -> dict[str, Any]:
    """Env-steps per CPU-second of the numba native vector env at N = ``n``."""
    env = gym.make_vec("ElectroLoc-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    env.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
    steps, start = 0, time.process_time()
    while time.process_time() - start < seconds:
        env.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
        steps += 1
    return {"n_envs": n, "env_steps_per_s": n * steps / (time.process_time() - start), "steps": steps}


def ppo_rate(n: int, device: torch.device, num_steps: int = 16, updates: int = 2) -> dict[str, Any]:
    """Training env-steps/s of examples/ppo_torch.py (rollouts on ``device`` and updates), ``updates`` updates."""
    import importlib.util
    import sys

    examples = Path(__file__).resolve().parents[1] / "examples"
    sys.path.insert(0, str(examples))
    spec = importlib.util.spec_from_file_location("ppo_torch", examples / "ppo_torch.py")
    ppo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ppo)
    args = ppo.parse_args(
        [
            "--device",
            str(device),
            "--num-envs",
            str(n),
            "--num-steps",
            str(num_steps),
            "--total-timesteps",
            str(n * num_steps * updates),
            "--update-epochs",
            "4",
        ]
    )
    t0 = _clock(device)
    ppo.train(args)
    seconds = _clock(device) - t0
    return {
        "n_envs": n,
        "timesteps": n * num_steps * updates,
        "seconds": seconds,
        "train_steps_per_s": n * num_steps * updates / seconds,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--n-envs", type=int, nargs="+", default=list(DEFAULT_N))
    ap.add_argument("--numba-n", type=int, default=256)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--compile", action="store_true", help="also time the torch.compile'd step")
    ap.add_argument("--env-kwargs", default="{}", help="JSON of ElectroLoc-v0 arguments (both backends)")
    ap.add_argument("--ppo-n", type=int, default=256, help="envs of the on-device PPO row (0: skip it)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    try:
        device = torch.device(args.device)
        kwargs = json.loads(args.env_kwargs)
    except (RuntimeError, ValueError) as exc:
        ap.error(f"--device / --env-kwargs: {exc}")
    if any(n < 1 for n in args.n_envs) or args.numba_n < 1 or args.seconds <= 0 or args.ppo_n < 0:
        ap.error("--n-envs and --numba-n must be ≥ 1, --seconds > 0, --ppo-n ≥ 0")
    torch.set_num_threads(1)
    rows: list[dict[str, Any]] = []
    numba = numba_rate(args.numba_n, args.seconds, kwargs)
    print(f"numba native vector env, N = {numba['n_envs']}, 1 CPU core: {numba['env_steps_per_s']:,.0f} env-steps/s")
    for n in args.n_envs:
        for comp in (False, True) if args.compile else (False,):
            try:
                row = torch_rate(n, device, args.seconds, comp, kwargs)
            except (torch.OutOfMemoryError, MemoryError, RuntimeError) as exc:
                row = {"n_envs": n, "compile": comp, "error": f"{type(exc).__name__}: {str(exc)[:200]}"}
            rows.append(row)
            if "error" in row:
                print(f"torch N = {n:6d} compile={comp!s:5}: {row['error']}")
                continue
            print(
                f"torch N = {n:6d} compile={comp!s:5}: {row['env_steps_per_s']:12,.0f} env-steps/s "
                f"({row['env_steps_per_s'] / numba['env_steps_per_s']:.2f}× numba), "
                f"state {row['state_bytes_per_env']:,} B/env"
                + (f", peak {row['peak_bytes_per_env']:,.0f} B/env" if "peak_bytes_per_env" in row else "")
            )
    ppo = None
    if args.ppo_n > 0:
        ppo = ppo_rate(args.ppo_n, device)
        print(
            f"on-device PPO (examples/ppo_torch.py), N = {ppo['n_envs']}: {ppo['train_steps_per_s']:,.0f} "
            f"training env-steps/s"
        )
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu (1 thread)"
    result = {
        "device": str(device),
        "device_name": name,
        "torch": torch.__version__,
        "env_kwargs": kwargs,
        "numba": numba,
        "torch_rows": rows,
        "ppo": ppo,
        "rate_clock": "wall (synchronised)" if device.type == "cuda" else "process CPU time",
    }
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
