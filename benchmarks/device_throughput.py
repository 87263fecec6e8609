"""Env-steps/s of ElectroLoc-v0's torch backend on a device: the one command of a GPU's figures.

One command, the same on an accelerator and on the CPU (the GPU's: ``experiments/on_device/run_gpu.sh``)::

    python benchmarks/device_throughput.py --device cuda --compile --profile --out results/cuda.json
    python benchmarks/device_throughput.py --device cpu --n-envs 64 256 1024 --compile --ppo-n 64 --out /tmp/cpu.json

It needs only torch, numpy, numba, scipy, gymnasium and msgspec (the package installed with ``pip install
--no-deps``; no SB3, no internet). For each N of ``--n-envs`` (on an accelerator 1024 … 524288 by
default; a size the device cannot hold is reported as such and skipped), the torch backend's env-steps
per second (every sub-env step counts; random actions, so episodes end and reset as in training), eager
and, with ``--compile``, through ``torch.compile`` (inductor; the first steps' wall time, code generation
included, is the row's ``warmup_s``); beside it the numba native vector env at ``--numba-n`` on one CPU
core. Rates are wall-clock on an accelerator (synchronised) and per CPU-second on the CPU. Each row has
the state's bytes per env and the peak bytes per env (the device's peak allocation over the row's
steps, state included, divided by N; on the CPU traced by ``torch.profiler``'s memory timeline over one
step, when ``--cpu-peak``). Then the on-device PPO of ``examples/ppo_torch.py`` at each N of ``--ppo-n``
(two updates; its training env-steps/s, rollouts and updates), and with ``--profile`` the ten most
expensive kernels of three steps at the largest N (``torch.profiler``, device time).

The order: the numba row, the eager rows (smallest N first), the PPO rows, then the compiled rows from
the largest N down. Every row, the numba one first, checks the time left before it starts: one that would
pass ``--budget-s`` seconds (a row is expected to take twice ``--seconds``, a compiled row the longest
compilation so far on top) is listed as skipped in the JSON and the table, so the command ends in a
bounded time on a bare machine; ``--seconds`` is therefore at most half of ``--budget-s`` (more could
time no row at all). Every option is checked before any work: the sizes asked for against the engines'
own memory refusals (the numba env's at ``--numba-n``, the torch engine's at each N of ``--n-envs`` and
``--ppo-n``; a default N the device cannot hold is a row saying so), the output paths by
:func:`electroloc_gym.utils.fileio.check_output_path`. Writes JSON and a markdown table naming the
device, torch and CUDA (atomically; ``--md`` defaults to the JSON's path with ``.md``). Numeric
libraries run on ``--threads`` threads (:func:`electroloc_gym.utils.runtime.pin_threads`: default
``$ELECTROLOC_THREADS``, else 1 — the documented per-core figures).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # before numpy, numba and torch start their pools; then --threads pins them

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import electroloc_gym  # noqa: E402, F401  (registers the ids)
from electroloc_gym.cli import HelpFormatter  # noqa: E402
from electroloc_gym.engines.torch_core.device import check_fits  # noqa: E402
from electroloc_gym.envs.torch_vector import MAX_NUM_ENVS  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options  # noqa: E402
from electroloc_gym.utils.runtime import add_threads_argument, pin_threads  # noqa: E402

CPU_N = (64, 256, 1024)
DEVICE_N = (1024, 4096, 16384, 65536, 262144, 524288)
CPU_PPO_N = (64,)
DEVICE_PPO_N = (4096, 65536)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: The longest ``--budget-s``: a day, seconds.
MAX_BUDGET_S = 86_400.0
#: A row is expected to take about twice its timed ``--seconds`` (building the env, warm-up steps, timing):
#: the time left a row needs before it starts, and why ``--seconds`` is at most half of ``--budget-s``.
ROW_COST = 2.0


def _clock(device: torch.device) -> float:
    """Wall time after the device's queue drained (accelerator), or this process's CPU time (CPU)."""
    if device.type == "cpu":
        return time.process_time()
    torch.accelerator.synchronize(device)
    return time.perf_counter()


def _peak_reset(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)


def _peak_bytes(device: torch.device) -> int | None:
    return int(torch.cuda.max_memory_allocated(device)) if device.type == "cuda" else None


def make_env(
    n: int, device: torch.device, compile_step: bool, kwargs: dict[str, Any], backend: str = "inductor"
) -> gym.vector.VectorEnv:
    """The torch backend's vector env of N envs on ``device`` (``backend``: ``torch.compile``'s)."""
    extra = {"compile_backend": backend} if compile_step else {}
    return gym.make_vec(
        PAPER_ENV_ID,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        backend="torch",
        device=str(device),
        compile=compile_step,
        **extra,
        **kwargs,
    )


def _actions(n: int, device: torch.device) -> list[torch.Tensor]:
    gen = torch.Generator(device=device).manual_seed(0)
    return [torch.rand(n, 2, generator=gen, device=device) * 2 - 1 for _ in range(8)]


def cpu_step_peak_bytes(env: Any, action: torch.Tensor) -> int | None:
    """Peak bytes alive during one CPU step (the state, the step's temporaries, its outputs), traced by
    ``torch.profiler``'s memory timeline; None where this torch has no timeline.
    """
    try:
        from torch.profiler import ProfilerActivity, profile
        from torch.profiler._memory_profiler import MemoryProfileTimeline

        with profile(activities=[ProfilerActivity.CPU], profile_memory=True, record_shapes=True, with_stack=True) as p:
            env.step(action)
        _, sizes = MemoryProfileTimeline(p._memory_profile())._coalesce_timeline(torch.device("cpu"))
        traced = int(np.asarray(sizes).sum(axis=1).max()) if len(sizes) else 0
    except Exception:  # noqa: BLE001 - a private API: no figure rather than no benchmark
        return None
    return max(traced, env.unwrapped.memory_bytes_per_env() * env.num_envs)


def torch_rate(
    n: int,
    device: torch.device,
    seconds: float,
    compile_step: bool,
    kwargs: dict[str, Any],
    cpu_peak: bool,
    backend: str = "inductor",
) -> tuple[dict[str, Any], Any]:
    """Env-steps/s of the torch backend at N = ``n`` (three warm-up steps, then ``seconds`` of steps, at
    least four); returns the row and the env (for the profile).
    """
    _peak_reset(device)
    env = make_env(n, device, compile_step, kwargs, backend)
    env.reset(seed=0)
    actions = _actions(n, device)
    t0 = time.perf_counter()
    for a in actions[:3]:
        env.step(a)
    _clock(device)
    warm_s = time.perf_counter() - t0
    steps, start = 0, _clock(device)
    while True:
        env.step(actions[steps % len(actions)])
        steps += 1
        if steps % 4 == 0 and _clock(device) - start >= seconds:
            break
    elapsed = _clock(device) - start
    row: dict[str, Any] = {
        "n_envs": n,
        "compile": compile_step,
        "env_steps_per_s": n * steps / elapsed,
        "steps": steps,
        "warmup_s": warm_s,
        "state_bytes_per_env": env.unwrapped.memory_bytes_per_env(),
    }
    peak = _peak_bytes(device)
    if peak is None and cpu_peak:
        peak = cpu_step_peak_bytes(env, actions[0])
    if peak is not None:
        row["peak_bytes_per_env"] = peak / n
    return row, env


def numba_rate(n: int, seconds: float, kwargs: dict[str, Any]) -> dict[str, Any]:
    """Env-steps per CPU-second of the numba native vector env at N = ``n``."""
    env = gym.make_vec(PAPER_ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    env.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
    steps, start = 0, time.process_time()
    while time.process_time() - start < seconds:
        env.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
        steps += 1
    env.close()
    return {"n_envs": n, "env_steps_per_s": n * steps / (time.process_time() - start), "steps": steps}


def _ppo_module() -> Any:
    import importlib.util
    import sys

    sys.path.insert(0, str(EXAMPLES))
    spec = importlib.util.spec_from_file_location("ppo_torch", EXAMPLES / "ppo_torch.py")
    ppo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ppo)
    return ppo


def ppo_rate(n: int, device: torch.device, threads: int, num_steps: int = 16, updates: int = 2) -> dict[str, Any]:
    """Training env-steps/s of examples/ppo_torch.py (rollouts on ``device`` and updates), ``updates`` updates."""
    ppo = _ppo_module()
    total = n * num_steps * updates
    args = ppo.parse_args(
        ["--device", str(device), "--num-envs", str(n), "--num-steps", str(num_steps), "--total-timesteps", str(total)]
        + ["--update-epochs", "4", "--threads", str(threads)]
    )
    t0 = _clock(device)
    ppo.train(args)
    seconds = _clock(device) - t0
    return {"n_envs": n, "timesteps": total, "seconds": seconds, "train_steps_per_s": total / seconds}


def profile_top(env: Any, device: torch.device, top: int = 10) -> list[dict[str, Any]]:
    """The ``top`` most expensive kernels (self device time on an accelerator, self CPU time on the CPU) of
    three steps of ``env``.
    """
    from torch.profiler import ProfilerActivity, profile

    acts = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device.type == "cuda" else [])
    actions = _actions(env.num_envs, device)
    with profile(activities=acts) as prof:
        for a in actions[:3]:
            env.step(a)
        _clock(device)
    key = "self_device_time_total" if device.type == "cuda" else "self_cpu_time_total"
    events = sorted(prof.key_averages(), key=lambda e: getattr(e, key), reverse=True)
    total = sum(getattr(e, key) for e in events) or 1.0
    return [
        {"kernel": e.key, "self_ms": getattr(e, key) / 1e3, "share": getattr(e, key) / total, "calls": e.count}
        for e in events[:top]
    ]


def device_description(device: torch.device) -> dict[str, Any]:
    """The device's name, torch's version and CUDA's (None on the CPU)."""
    if device.type == "cuda":
        props = torch.cuda.get_device_properties(device)
        name, memory = props.name, int(props.total_memory)
    else:
        name, memory = f"cpu ({platform.processor() or platform.machine()}, {torch.get_num_threads()} thread(s))", None
    return {
        "device": str(device),
        "device_name": name,
        "device_memory_bytes": memory,
        "torch": torch.__version__,
        "cuda": torch.version.cuda,
        "python": platform.python_version(),
    }


def markdown(result: dict[str, Any]) -> str:
    """The result as a markdown page: the device line, the rows, the PPO rows and the profile."""
    d = result["device_info"]
    mem = f", {d['device_memory_bytes'] / 2**30:.0f} GiB" if d["device_memory_bytes"] else ""
    numba = result["numba"]
    lines = [
        f"# ElectroLoc-v0 torch backend on {d['device_name']}",
        "",
        f"Device {d['device']} ({d['device_name']}{mem}); torch {d['torch']}, CUDA {d['cuda'] or '—'}; "
        f"rates per {result['rate_clock']}; env arguments {json.dumps(result['env_kwargs'])}.",
        "",
        "| backend | N | env-steps/s | × numba | steps timed | warm-up s | state B/env | peak B/env |",
        "|---|---|---|---|---|---|---|---|",
    ]
    rate = numba["env_steps_per_s"] if numba is not None and "skipped" not in numba else None
    if numba is not None:
        cells = [numba["skipped"], "", ""] if rate is None else [f"{rate:,.0f}", "1", str(numba["steps"])]
        lines.append(f"| numba native vector env (1 CPU core) | {numba['n_envs']} | {' | '.join(cells)} | | | |")
    for r in result["torch_rows"]:
        kind = "torch, compiled" if r["compile"] else "torch, eager"
        if "error" in r or "skipped" in r:
            lines.append(f"| {kind} | {r['n_envs']} | {r.get('error') or r['skipped']} | | | | | |")
            continue
        ratio = f"{r['env_steps_per_s'] / rate:.2f}" if rate else ""
        peak = f"{r['peak_bytes_per_env']:,.0f}" if "peak_bytes_per_env" in r else "—"
        lines.append(
            f"| {kind} | {r['n_envs']} | {r['env_steps_per_s']:,.0f} | {ratio} | {r['steps']} "
            f"| {r['warmup_s']:.1f} | {r['state_bytes_per_env']:,} | {peak} |"
        )
    if result["ppo"]:
        lines += [
            "",
            "| on-device PPO (examples/ppo_torch.py) | N | training env-steps/s | seconds |",
            "|---|---|---|---|",
        ]
        for p in result["ppo"]:
            cell = p.get("error") or p.get("skipped")
            lines.append(
                f"| two updates | {p['n_envs']} | {cell or format(p['train_steps_per_s'], ',.0f')} "
                f"| {'' if cell else format(p['seconds'], '.1f')} |"
            )
    if result["profile"]:
        prof = result["profile"]
        lines += [
            "",
            f"Ten most expensive kernels, three steps at N = {prof['n_envs']} "
            f"({'compiled' if prof['compile'] else 'eager'}):",
            "",
            "| kernel | self ms | share | calls |",
            "|---|---|---|---|",
        ]
        for k in prof["top"]:
            lines.append(f"| `{k['kernel'][:90]}` | {k['self_ms']:.2f} | {k['share']:.1%} | {k['calls']} |")
    lines += ["", f"Total wall time {result['wall_s']:.0f} s.", ""]
    return "\n".join(lines)


def _bad_kwargs(text: str) -> dict[str, Any]:
    value = json.loads(text)
    if not isinstance(value, dict):
        raise ValueError(f"must be a JSON object of ElectroLoc-v0 arguments, got {text!r}")
    reserved = {"num_envs", "vectorization_mode", "backend", "device", "compile"} & set(value)
    if reserved:
        raise ValueError(f"sets {sorted(reserved)}, which the benchmark chooses; use its own options")
    return value


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options, each checked before any timing (one ``prog: error: …`` line, exit 2)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=HelpFormatter)
    ap.add_argument("--device", default="cpu", help="the torch device: cpu, cuda, cuda:1, …")
    add_threads_argument(ap)
    ap.add_argument(
        "--n-envs",
        type=int,
        nargs="+",
        default=None,
        help=f"the N of the torch rows (default: {' '.join(map(str, CPU_N))} on the CPU, "
        f"{' '.join(map(str, DEVICE_N))} on an accelerator)",
    )
    ap.add_argument("--numba-n", type=int, default=256, help="N of the numba row (0: skip it)")
    ap.add_argument(
        "--seconds", type=float, default=3.0, help="timed seconds per row (after 3 warm-up steps; ≤ --budget-s / 2)"
    )
    ap.add_argument("--compile", action="store_true", help="also time the torch.compile'd step (default: off)")
    ap.add_argument(
        "--compile-backend",
        default="inductor",
        choices=("inductor", "aot_eager", "eager"),
        help="torch.compile's backend (eager / aot_eager: the capture without code generation, for checks)",
    )
    ap.add_argument(
        "--cpu-peak", action="store_true", help="on the CPU, trace each row's peak bytes (slow; default: off)"
    )
    ap.add_argument("--env-kwargs", default="{}", help="JSON object of ElectroLoc-v0 arguments (both backends)")
    ap.add_argument(
        "--ppo-n",
        type=int,
        nargs="*",
        default=None,
        help=f"N of the on-device PPO rows (default: {' '.join(map(str, CPU_PPO_N))} on the CPU, "
        f"{' '.join(map(str, DEVICE_PPO_N))} on an accelerator; none: skip them)",
    )
    ap.add_argument(
        "--profile", action="store_true", help="torch.profiler's top 10 kernels at the largest N (default: off)"
    )
    ap.add_argument(
        "--budget-s",
        type=float,
        default=420.0,
        help="start no row that would end after this many seconds (at most 86400: a day)",
    )
    ap.add_argument(
        "--out", type=Path, default=None, help="write the JSON here, and the markdown beside it (default: not written)"
    )
    ap.add_argument("--md", type=Path, default=None, help="write the markdown table here (default: --out's .md)")
    args = ap.parse_args(argv)
    if not 0 <= args.numba_n <= MAX_NUM_ENVS:
        ap.error(f"argument --numba-n: must be an integer in [0, {MAX_NUM_ENVS}], got {args.numba_n}")
    if not (math.isfinite(args.budget_s) and 0 < args.budget_s <= MAX_BUDGET_S):
        ap.error(
            f"argument --budget-s: must be a finite number > 0 and ≤ {MAX_BUDGET_S:g} (a day), got {args.budget_s!r}"
        )
    high = args.budget_s / ROW_COST
    if not (math.isfinite(args.seconds) and 0 < args.seconds <= high):
        ap.error(
            f"argument --seconds: must be a finite number > 0 and ≤ --budget-s / {ROW_COST:g} = {high:g} (a row "
            f"takes about {ROW_COST:g}× its timed seconds; rows that would pass --budget-s {args.budget_s:g} are "
            f"skipped), got {args.seconds!r}"
        )
    try:
        args.env_kwargs = _bad_kwargs(args.env_kwargs)
    except ValueError as exc:
        ap.error(f"argument --env-kwargs: {exc}")
    try:  # the device and the arguments as the engine checks them: one env built, nothing stepped
        probe = make_env(1, torch.device("cpu") if args.device == "cpu" else args.device, False, args.env_kwargs)
        args.device = torch.device(probe.unwrapped.device)
        consts = probe.unwrapped.consts
        probe.close()
    except (ValueError, TypeError, RuntimeError, AssertionError) as exc:
        ap.error(f"argument --device / --env-kwargs: {_first_line(exc)}")
    if args.device.type == "meta":
        ap.error("argument --device: meta holds shapes and no data; use cpu or an accelerator")
    cpu = args.device.type == "cpu"
    given = {"--n-envs": args.n_envs, "--ppo-n": args.ppo_n}
    args.n_envs = list(args.n_envs or (CPU_N if cpu else DEVICE_N))
    args.ppo_n = list(args.ppo_n if args.ppo_n is not None else (CPU_PPO_N if cpu else DEVICE_PPO_N))
    if any(not 1 <= n <= MAX_NUM_ENVS for n in args.n_envs + args.ppo_n):
        ap.error(
            f"arguments --n-envs and --ppo-n: each N must be an integer in [1, {MAX_NUM_ENVS}], "
            f"got {args.n_envs + args.ppo_n}"
        )
    for option, sizes in given.items():  # sizes asked for that cannot fit (a default that cannot is a row saying so)
        for n in sizes or ():
            try:
                check_fits(consts, n)  # the torch engine's own refusal, without allocating
            except ValueError as exc:
                ap.error(f"argument {option}: N = {n} cannot fit: {_first_line(exc)}")
    if args.numba_n:
        try:  # the numba engine's own memory refusal; the state is not touched until reset
            gym.make_vec(
                PAPER_ENV_ID, num_envs=args.numba_n, vectorization_mode="vector_entry_point", **args.env_kwargs
            ).close()
        except ValueError as exc:
            ap.error(f"argument --numba-n: N = {args.numba_n} cannot fit: {_first_line(exc)}")
    if args.md is None and args.out is not None:
        args.md = args.out.with_suffix(".md")
    check_output_options(ap, files={"--out": args.out, "--md": args.md})
    return args


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _fits_error(exc: BaseException) -> str:
    return f"does not fit: {type(exc).__name__}: {_first_line(exc)[:160]}"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.threads = pin_threads(args.threads)
    device, t_start = args.device, time.perf_counter()

    def over_budget(expected_s: float = 0.0) -> bool:
        return time.perf_counter() - t_start + expected_s > args.budget_s

    skipped = f"skipped: the time budget ({args.budget_s:g} s) would be passed"
    numba: dict[str, Any] | None = None
    if args.numba_n and over_budget(ROW_COST * args.seconds):  # every row, the first too, checks the time left
        numba = {"n_envs": args.numba_n, "skipped": skipped}
        print(f"numba native vector env, N = {args.numba_n}: {skipped}")
    elif args.numba_n:
        numba = numba_rate(args.numba_n, args.seconds, args.env_kwargs)
        print(
            f"numba native vector env, N = {numba['n_envs']}, 1 CPU core: {numba['env_steps_per_s']:,.0f} env-steps/s"
        )
    rate = numba["env_steps_per_s"] if numba is not None and "skipped" not in numba else None
    rows: list[dict[str, Any]] = []
    profile: dict[str, Any] | None = None
    compile_s = 0.0  # the longest compiled warm-up so far: what the next compiled row is expected to need

    def time_row(n: int, comp: bool) -> None:
        nonlocal profile, compile_s
        if over_budget((compile_s if comp else 0.0) + ROW_COST * args.seconds):
            rows.append({"n_envs": n, "compile": comp, "skipped": skipped})
            print(f"torch N = {n:7d} compile={comp!s:5}: {skipped}")
            return
        env = None
        try:
            row, env = torch_rate(n, device, args.seconds, comp, args.env_kwargs, args.cpu_peak, args.compile_backend)
        except (torch.OutOfMemoryError, MemoryError, ValueError, RuntimeError) as exc:
            row = {"n_envs": n, "compile": comp, "error": _fits_error(exc)}
        rows.append(row)
        if "error" in row:
            print(f"torch N = {n:7d} compile={comp!s:5}: {row['error']}")
        else:
            compile_s = max(compile_s, row["warmup_s"]) if comp else compile_s
            ratio = f" ({row['env_steps_per_s'] / rate:.2f}× numba)" if rate else ""
            peak = f", peak {row['peak_bytes_per_env']:,.0f} B/env" if "peak_bytes_per_env" in row else ""
            print(
                f"torch N = {n:7d} compile={comp!s:5}: {row['env_steps_per_s']:12,.0f} env-steps/s{ratio}, "
                f"warm-up {row['warmup_s']:.1f} s, state {row['state_bytes_per_env']:,} B/env{peak}",
                flush=True,
            )
            largest = profile is None or n > profile["n_envs"] or (comp and not profile["compile"])
            if args.profile and comp == args.compile and largest and not over_budget():
                profile = {"n_envs": n, "compile": comp, "top": profile_top(env, device)}
        del env
        if device.type == "cuda":
            torch.cuda.empty_cache()

    for n in sorted(args.n_envs):  # eager, smallest first
        time_row(n, False)
    ppo_rows: list[dict[str, Any]] = []
    for n in args.ppo_n:
        if over_budget(ROW_COST * args.seconds):
            ppo_rows.append({"n_envs": n, "skipped": skipped})
            continue
        try:
            p = ppo_rate(n, device, args.threads)
            print(f"on-device PPO (examples/ppo_torch.py), N = {n}: {p['train_steps_per_s']:,.0f} training env-steps/s")
        except (torch.OutOfMemoryError, MemoryError, ValueError, RuntimeError) as exc:
            p = {"n_envs": n, "error": _fits_error(exc)}
            print(f"on-device PPO, N = {n}: {p['error']}")
        ppo_rows.append(p)
    if args.compile:  # compiled, largest first: the headline row before the budget runs out
        for n in sorted(args.n_envs, reverse=True):
            time_row(n, True)
    if profile:
        print(f"top kernels, three steps at N = {profile['n_envs']}:")
        for k in profile["top"]:
            print(f"  {k['self_ms']:10.2f} ms {k['share']:6.1%}  {k['kernel'][:100]}")
    result = {
        "device_info": device_description(device),
        "env_kwargs": args.env_kwargs,
        "compile_backend": args.compile_backend,
        "threads": args.threads,
        "numba": numba,
        "torch_rows": rows,
        "ppo": ppo_rows,
        "profile": profile,
        "rate_clock": "wall second (synchronised)" if device.type != "cpu" else "process CPU-second",
        "wall_s": time.perf_counter() - t_start,
    }
    print(f"total wall time {result['wall_s']:.0f} s")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, json.dumps(result, indent=2) + "\n")
    if args.md is not None:
        args.md.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.md, markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
