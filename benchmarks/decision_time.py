"""Decision time of eedi and infotaxis beside min-var's, on the same belief states, in one run.

Belief states are taken along min-var episodes over the eight presets (ElectroLoc-v0, calibrated
sensor model, 2500 particles; 0–5 readings into an episode, so wide and narrow beliefs both occur).
On every state each agent is bound to the env (``agent.reset(env)``) and its decision
(``choose_move_mm``: options or EID, predictions, score) is timed, best of ``--repeats``, so
the agents are compared on identical beliefs. Printed: a Markdown table of the median and 90th
percentile per agent, for the 12.7 mm and the 38.1 mm presets (their calibration grids and boxes
differ) and overall, and each agent's median relative to min-var's.

Numeric libraries are pinned to one thread (:func:`electroloc_gym.utils.runtime.pin_threads`); timings are
best-of-N to resist a busy machine, but they are this machine's: compare the columns, not the values
across machines.

    python benchmarks/decision_time.py [--states 16] [--repeats 3] [--agents min-var,infotaxis,eedi] [--json out.json]
"""

from __future__ import annotations

import argparse
import time

from electroloc_gym.utils.runtime import pin_threads

pin_threads()

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.baselines.eedi import EEDIAgent  # noqa: E402
from electroloc_gym.baselines.infotaxis import InfotaxisAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.agentspec import split_specs  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options, write_json_atomic  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES  # noqa: E402


def collect_envs(n_states: int, seed: int = 101) -> list[tuple[str, object]]:
    """``n_states`` envs frozen at belief states along min-var episodes, cycling over the presets."""
    rng = np.random.default_rng(seed)
    envs = []
    for k in range(n_states):
        cond = PRESET_NAMES[k % len(PRESET_NAMES)]
        env = gym.make(PAPER_ENV_ID, condition=cond)
        obs, _ = env.reset(seed=seed + k)
        agent = make_agent(MinVarianceAgent.name, seed=seed + k)
        agent.reset(env)
        for _ in range(int(rng.integers(0, 6))):
            action, _ = agent.predict(obs)
            obs, _, term, trunc, _ = env.step(action)
            if term or trunc:
                obs, _ = env.reset(seed=seed + 1000 + k)  # ended: a fresh belief of the same condition
                agent.reset(env)
                break
        _ = env.unwrapped.sensor_model  # build the calibrated model outside the timing
        envs.append((cond, env))
    return envs


def time_decisions(spec: str, envs: list[tuple[str, object]], repeats: int) -> list[tuple[str, float]]:
    """(condition, best-of-``repeats`` decision time in s) of agent ``spec`` on every state."""
    out = []
    for k, (cond, env) in enumerate(envs):
        agent = make_agent(spec, seed=k)
        best = float("inf")
        for _ in range(repeats):
            agent.reset(env)
            t = time.perf_counter()
            agent.choose_move_mm()
            best = min(best, time.perf_counter() - t)
        out.append((cond, best))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--states", type=int, default=16, help="belief states (cycling over the 8 presets)")
    parser.add_argument("--repeats", type=int, default=3, help="timings per state (the best is kept)")
    parser.add_argument(
        "--agents",
        default=",".join((MinVarianceAgent.name, InfotaxisAgent.name, EEDIAgent.name)),
        help="agent specs, comma-separated",
    )
    parser.add_argument("--json", default=None, help="also write the timings (ms) to this JSON file")
    args = parser.parse_args()
    check_output_options(parser, files={"--json": args.json})
    if args.states < 1 or args.repeats < 1:
        parser.error("--states and --repeats must be ≥ 1")
    specs = [s.strip() for s in split_specs(args.agents) if s.strip()]
    envs = collect_envs(args.states)
    times = {spec: time_decisions(spec, envs, args.repeats) for spec in specs}
    ref = specs[0]

    def stats(rows: list[tuple[str, float]], size: str | None) -> tuple[float, float]:
        ms = np.array([t for c, t in rows if size is None or c.endswith(size)]) * 1e3
        return float(np.median(ms)), float(np.percentile(ms, 90))

    print(f"Decision time, ms (median / 90th percentile over {args.states} belief states, best of {args.repeats})\n")
    ref_median = stats(times[ref], None)[0]
    rows = []
    for spec in specs:
        cells = [stats(times[spec], size) for size in ("12.7", "38.1", None)]
        rows.append((spec, *(f"{m:.0f} / {p:.0f}" for m, p in cells), f"{cells[2][0] / ref_median:.2f}"))
    for line in markdown_table(("agent", "12.7 mm presets", "38.1 mm presets", "all", f"median / {ref}'s"), rows):
        print(line)
    if args.json:
        write_json_atomic(
            args.json,
            {
                "states": args.states,
                "repeats": args.repeats,
                "ms": {s: [[c, t * 1e3] for c, t in rows] for s, rows in times.items()},
            },
        )


if __name__ == "__main__":
    main()
