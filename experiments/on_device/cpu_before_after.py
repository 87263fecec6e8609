"""The torch backend's CPU rows before and after a change, measured alternately in one run.

    python experiments/on_device/cpu_before_after.py --before <commit> --out experiments/on_device/results/x.json

The package, benchmarks and examples of ``<commit>`` are extracted (``git archive``) to a temporary
folder; then ``benchmarks/device_throughput.py`` of that tree and of this checkout run in turn,
``--reps`` times each (before, after, before, after, …), at the same N, seconds and numba row, on one
thread. On a shared machine the load changes from minute to minute: alternating puts both sides under
the same load, and each run's numba row is its own yardstick (the "× numba" ratio). The load average
is recorded around every run. The first run of each side includes inductor's code generation (the
later ones find it in inductor's cache). Writes every run's JSON and a summary (medians per side).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options  # noqa: E402

#: device_throughput.py's default --budget-s, seconds.
DEFAULT_BUDGET_S = 420.0


def extract(commit: str, folder: Path) -> str:
    """The package, benchmarks and examples of ``commit`` under ``folder``; returns the full hash."""
    full = subprocess.run(["git", "rev-parse", commit], cwd=ROOT, check=True, capture_output=True, text=True)
    archive = subprocess.run(
        ["git", "archive", full.stdout.strip(), "electroloc_gym", "benchmarks", "examples"],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return full.stdout.strip()


def run_side(tree: Path, args: argparse.Namespace, out: Path) -> dict[str, Any]:
    """One run of ``tree``'s benchmark (its own command line) with ``tree``'s package first on the path."""
    script = tree / "benchmarks" / "device_throughput.py"
    new_style = "--budget-s" in script.read_text()
    cmd = [sys.executable, str(script), "--device", "cpu", "--compile", "--seconds", str(args.seconds)]
    cmd += ["--n-envs", *map(str, args.n_envs), "--numba-n", str(args.numba_n), "--out", str(out)]
    cmd += ["--ppo-n"] if new_style else ["--ppo-n", "0"]
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", MKL_NUM_THREADS="1")
    load0, t0 = os.getloadavg(), time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=tree)
    if proc.returncode != 0:
        raise RuntimeError(f"{script} failed:\n{proc.stderr[-2000:]}")
    result = json.loads(out.read_text())
    rows = {f"{r['n_envs']}/{'compiled' if r['compile'] else 'eager'}": r for r in result["torch_rows"]}
    return {
        "load_before": load0,
        "load_after": os.getloadavg(),
        "wall_s": time.perf_counter() - t0,
        "numba": result["numba"]["env_steps_per_s"],
        "rows": {
            k: {
                "env_steps_per_s": r["env_steps_per_s"],
                "warmup_s": r.get("warmup_s"),
                "state_bytes_per_env": r["state_bytes_per_env"],
            }
            for k, r in rows.items()
        },
        "stdout": proc.stdout,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    ap.add_argument("--before", required=True, help="the commit of the 'before' rows")
    ap.add_argument("--reps", type=int, default=2, help="runs of each side, alternating")
    ap.add_argument("--seconds", type=float, default=6.0, help="timed seconds per row")
    ap.add_argument("--n-envs", type=int, nargs="+", default=[1024], help="N of the torch rows")
    ap.add_argument("--numba-n", type=int, default=256, help="N of the numba row")
    ap.add_argument("--out", type=Path, required=True, help="the summary JSON")
    args = ap.parse_args(argv)
    high = DEFAULT_BUDGET_S / 2  # the benchmark's own bound at its default --budget-s
    if args.reps < 1 or not 0 < args.seconds <= high:
        ap.error(f"--reps must be ≥ 1 and --seconds in (0, {high:g}], got {args.reps} and {args.seconds}")
    check_output_options(ap, files={"--out": args.out})
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        before = Path(tmp) / "before"
        before.mkdir()
        commit = extract(args.before, before)
        for rep in range(args.reps):
            for side, tree in (("before", before), ("after", ROOT)):
                r = run_side(tree, args, Path(tmp) / f"{side}-{rep}.json")
                r |= {"side": side, "rep": rep}
                runs.append(r)
                cells = ", ".join(f"{k} {v['env_steps_per_s']:,.0f}" for k, v in r["rows"].items())
                print(
                    f"{side:6s} rep {rep}: numba {r['numba']:,.0f}; {cells}; load {r['load_before'][0]:.1f}", flush=True
                )
    summary: dict[str, Any] = {}
    for side in ("before", "after"):
        mine = [r for r in runs if r["side"] == side]
        summary[side] = {
            "numba_median": statistics.median(r["numba"] for r in mine),
            "rows": {
                k: {
                    "median": statistics.median(r["rows"][k]["env_steps_per_s"] for r in mine),
                    "x_numba_median": statistics.median(r["rows"][k]["env_steps_per_s"] / r["numba"] for r in mine),
                    "state_bytes_per_env": mine[0]["rows"][k]["state_bytes_per_env"],
                }
                for k in mine[0]["rows"]
            },
        }
    print("\nrow               before (× numba)        after (× numba)")
    for k in summary["before"]["rows"]:
        b, a = summary["before"]["rows"][k], summary["after"]["rows"][k]
        cells = [f"{x['median']:10,.0f} ({x['x_numba_median']:.2f})" for x in (b, a)]
        print(f"{k:16s} {cells[0]}  {cells[1]}")
    result = {
        "before_commit": commit,
        "args": {k: str(v) for k, v in vars(args).items()},
        "runs": runs,
        "summary": summary,
        "cpu_count": os.cpu_count(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps(result, indent=2) + "\n")
    print(f"wrote: {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
