"""Training speed of the off-policy learners: env steps per second once learning has started, one thread.

For each (algorithm, env) it starts ``electroloc train`` (the shipped hyper-parameter file, one thread per
library, validation pushed past the run so that none interrupts the measurement), waits until the run is
past its ``learning_starts`` random steps (read from the training monitor's episodes), counts the env steps
the monitor records over the next ``--seconds`` of wall time, and stops the run. What it reports is the
steady-state rate of the gradient phase, the one that sets a run's wall time (the random warm-up steps are
far cheaper). Evaluation is not included: a run adds its validation episodes on top
(``summary.json``'s ``evaluation_time_s`` once it ran).

    python experiments/learned/offpolicy_fps.py --out /tmp/fps            # sac and crossq on the moving target,
                                                                         # crossq on ElectroLoc-v0; 60 s each
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import yaml

#: (algorithm, env id) pairs measured by default.
PAIRS = (("sac", "ElectroLocTrack-v0"), ("crossq", "ElectroLocTrack-v0"), ("crossq", "ElectroLoc-v0"))
#: The validation callback for the measurement: one evaluation at the start, none during the window.
QUIET_CALLBACK = "[{'electroloc_gym.train.callbacks.BenchEvalCallback': {'eval_freq': 1000000000, 'n_episodes': 1}}]"


def monitor_steps(folder: Path) -> tuple[float, int] | None:
    """(seconds since the monitor started, env steps) at the last episode the run's monitor files record."""
    files = sorted(folder.glob("**/*monitor.csv"))
    if not files:
        return None
    t, steps = 0.0, 0
    for f in files:
        lines = f.read_text(encoding="utf-8").splitlines()[1:]  # the first line is the monitor's JSON header
        rows = list(csv.DictReader(lines))
        for row in rows:
            try:
                steps += int(row["l"])
                t = max(t, float(row["t"]))
            except (KeyError, ValueError):
                continue  # a row being written
    return t, steps


def measure(algo: str, env_id: str, out: Path, seconds: float) -> dict[str, object]:
    """One (algorithm, env): the steady-state training rate (env steps / s) over ``seconds`` of wall time."""
    from electroloc_gym.train.run import hyperparams_file

    file = yaml.safe_load(hyperparams_file(algo).read_text(encoding="utf-8"))[env_id]
    start_after = int(file.get("learning_starts", 0)) + 2 * int(file.get("n_envs", 1)) * 70  # past the warm-up
    folder = out / f"{algo}-{env_id}"
    argv = [sys.executable, "-m", "electroloc_gym.train", "--algo", algo, "--env", env_id, "--seed", "0"]
    argv += ["--timesteps", str(10**7), "--log-folder", str(folder), "--threads", "1"]
    argv += ["--hyperparams", f"callback={QUIET_CALLBACK}"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    log = (out / f"{algo}-{env_id}.log").open("w", encoding="utf-8")
    proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    t_start = time.time()
    try:
        first = None
        while first is None:
            if proc.poll() is not None:
                raise RuntimeError(f"{algo} on {env_id} stopped (exit {proc.returncode}); see {log.name}")
            got = monitor_steps(folder)
            if got is not None and got[1] >= start_after:
                first = (time.time(), got[1])
            time.sleep(1.0)
        time.sleep(seconds)
        last = monitor_steps(folder)
        t_end = time.time()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=60)
        log.close()
    assert last is not None
    steps = last[1] - first[1]
    return {
        "algo": algo,
        "env_id": env_id,
        "window_s": round(t_end - first[0], 1),
        "env_steps": steps,
        "fps": round(steps / (t_end - first[0]), 1),
        "warm_up_s": round(first[0] - t_start, 1),
        "load_average_1min_at_end": os.getloadavg()[0],
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="a scratch folder for the runs and fps.json")
    parser.add_argument("--seconds", type=float, default=60.0, help="measurement window per pair (s, > 0)")
    parser.add_argument("--only", default="", help="comma-separated algo/env-id pairs (default: all of PAIRS)")
    args = parser.parse_args(argv)
    if not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    pairs = [tuple(p.split("/", 1)) for p in args.only.split(",") if p.strip()] or list(PAIRS)
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for algo, env_id in pairs:
        r = measure(algo, env_id, args.out, args.seconds)
        print(json.dumps(r), flush=True)
        results.append(r)
    (args.out / "fps.json").write_text(json.dumps(results, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
