r"""EEDI against the information-greedy controllers, with D ∈ {0, 1, 2} distractors in the tank.

Miller, Silverman, MacIver & Murphey (IEEE T-RO 32(1), 2016) report that ergodic exploration of the
expected information density (EEDI) beats information-greedy controllers, particularly when distractors
are present. This script runs the agents on the paper's eight conditions with ``electroloc bench
--distractors D`` for each D and writes a table (Markdown) and a figure (mean readings and far successes
against D per agent):

    python experiments/distractors/distractor_comparison.py --trials 50 --seed 0 --out results/distractors \
        --table docs/distractor_comparison.md --plot docs/distractor_comparison.png

It is resumable and grows evenly: every (D, agent) pair is its own benchmark folder under ``--out``
(``D<d>/<agent>``, each resumed by the benchmark's own ``--resume``), filled in rounds of increasing trial
counts (``--rounds``), so a run stopped early still has every agent and D at the same number of trials.
The table uses, for every pair, the first N trials of every condition, N the largest count all pairs
reached (a learned policy shipped while the run went on may have fewer: its rows give their own count).
One process, one thread, the benchmark's serial backend: the machine is shared.

A *far success* is :func:`electroloc_gym.bench.schema.is_far_success` (the benchmark records it): a
success whose estimate is more than 15 mm from the target. Readings are the observations fused, the
first one (at reset) included; decision time is the median per-decision time of the agent, ms.
"""

from __future__ import annotations

import argparse
import calendar
import json
import os
import sys
import time
from pathlib import Path

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

from electroloc_gym.baselines.agent import belief_agents  # noqa: E402
from electroloc_gym.baselines.eedi import EEDIAgent  # noqa: E402
from electroloc_gym.baselines.infotaxis import InfotaxisAgent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.bench.agents import shipped_models  # noqa: E402
from electroloc_gym.bench.records import TRIALS_FILE, read_trials  # noqa: E402
from electroloc_gym.bench.runner import BenchConfig, run_benchmark  # noqa: E402
from electroloc_gym.protocol import FAR_ERROR_MM  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES  # noqa: E402

AGENTS = (*belief_agents(), "ppo-belief", "ppo-belief-distractors")
DISTRACTORS = (0, 1, 2)


def _pairs(agents: list[str], ds: list[int]) -> list[tuple[int, str]]:
    return [(d, a) for d in ds for a in agents]


def run(agents: list[str], ds: list[int], rounds: list[int], seed: int, out: Path, deadline: float | None) -> None:
    """Fill every (D, agent) folder round by round until the last round or the deadline (Unix time)."""
    for n in rounds:
        for d, agent in _pairs(agents, ds):
            if agent.startswith("ppo-") and agent not in shipped_models():
                print(f"round {n}: D={d} {agent} not shipped yet; later rounds catch up", flush=True)
                continue
            if deadline is not None and time.time() > deadline:
                print(f"deadline reached before round {n} of D={d} {agent}", flush=True)
                return
            config = BenchConfig(agents=(agent,), conditions=PRESET_NAMES, trials=n, seed=seed, distractors=d)
            t = time.perf_counter()
            run_benchmark(
                config, out / f"D{d}" / agent, workers=1, backend="serial", resume=True, progress=False, log=None
            )
            print(f"round {n}: D={d} {agent} done ({time.perf_counter() - t:.0f} s)", flush=True)


def _records(out: Path, d: int, agent: str) -> list[dict]:
    """The (D, agent) folder's valid records, read through the benchmark's record schema in the current key names
    (:func:`electroloc_gym.bench.records.read_trials`; none where the folder has no records yet).
    """
    return read_trials(out / f"D{d}" / agent / TRIALS_FILE)


def summarize(agents: list[str], ds: list[int], out: Path) -> tuple[int, list[dict]]:
    """(N, rows): N the trials per condition every pair has; one row per (agent, D) over those trials."""
    recs = {(d, a): _records(out, d, a) for d, a in _pairs(agents, ds)}
    have = {k: min(sum(1 for r in rs if r["condition"] == c) for c in PRESET_NAMES) for k, rs in recs.items()}
    n = min((v for v in have.values() if v), default=0)  # an agent shipped late may have fewer: its rows say so
    rows = []
    for (d, a), rs in recs.items():
        if not have[(d, a)]:
            continue
        rs = [r for r in rs if r["trial"] < min(n, have[(d, a)])]
        ok = [r for r in rs if r["success"]]
        obs = np.array([r["readings"] for r in rs], dtype=float)
        ok_obs = np.array([r["readings"] for r in ok], dtype=float)
        err = np.array([r["error_mm"] for r in ok], dtype=float)
        dms = np.array([r["decision_ms_median"] for r in rs if r["decision_ms_median"] is not None], dtype=float)
        rows.append(
            {
                "agent": a,
                "distractors": d,
                "trials": len(rs),
                "successes": len(ok),
                "far_successes": sum(bool(r.get("far_success")) for r in rs),
                "far_near_distractor": sum(near_distractor(r) for r in rs),
                "readings_mean_success": float(ok_obs.mean()) if ok_obs.size else None,
                "readings_median_all": float(np.median(obs)) if obs.size else None,
                "readings_mean_all": float(obs.mean()) if obs.size else None,
                "error_median_mm": float(np.median(err)) if err.size else None,
                "decision_ms_median": float(np.median(dms)) if dms.size else None,
            }
        )
    return n, rows


def _distractors_of(rec: dict) -> np.ndarray:
    """The trial's distractor centres (D, 2), mm: its env reset again with the trial's seed (the draws are the
    reset's; evaluation only).
    """
    import gymnasium as gym

    from electroloc_gym.world.conditions import get_condition

    env = gym.make(
        PAPER_ENV_ID,
        condition=get_condition(rec["condition"], rec["signal"]),
        distractors=rec["distractors"],
        n_particles=rec["n_particles"],
        sensor_model=rec["sensor_model"],
    )
    _, info = env.reset(seed=rec["seed"])
    assert np.allclose(env.unwrapped.target_mm, rec["target"])
    return np.asarray(info["distractors_mm"], dtype=float).reshape(-1, 2)


def near_distractor(rec: dict) -> bool:
    """A far success whose estimate is nearer a distractor's centre than the target's."""
    if not rec.get("far_success") or not rec.get("distractors"):
        return False
    est, tgt = np.asarray(rec["estimate"]), np.asarray(rec["target"])
    xy = _distractors_of(rec)
    return bool(np.min(np.hypot(*(xy - est).T)) < np.hypot(*(tgt - est)))


def paired(agents: list[str], ds: list[int], out: Path, n: int, ref: str = EEDIAgent.name) -> list[str]:
    """``ref`` against each other agent on the same trials (same seeds): correct localisations (a success that is
    not far) where exactly one of the two got it, and the exact two-sided binomial (sign) test of those.
    """
    from scipy.stats import binomtest

    cells = []
    for d in ds:
        mine = {(r["condition"], r["trial"]): r for r in _records(out, d, ref) if r["trial"] < n}
        for other in agents:
            if other == ref:
                continue
            theirs = {(r["condition"], r["trial"]): r for r in _records(out, d, other) if r["trial"] < n}
            keys = sorted(set(mine) & set(theirs))
            ok = {
                k: (
                    mine[k]["success"] and not mine[k].get("far_success"),
                    theirs[k]["success"] and not theirs[k].get("far_success"),
                )
                for k in keys
            }
            win = sum(a and not b for a, b in ok.values())
            loss = sum(b and not a for a, b in ok.values())
            p = binomtest(win, win + loss).pvalue if win + loss else 1.0
            cells.append((d, other, len(keys), win, loss, f"{p:.2f}"))
    return [
        f"Paired on the same trials: {ref} against each agent — trials where only {ref} / only the other "
        f"localised correctly (a success that is not far), and the sign test's two-sided p.",
        "",
        *markdown_table(("D", "against", "trials", f"only {ref}", "only the other", "p"), cells),
    ]


def _f(x: float | None, digits: int = 1) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def table_md(n: int, rows: list[dict], seed: int) -> str:
    """The comparison as Markdown."""
    ordered = sorted(rows, key=lambda r: (AGENTS.index(r["agent"]) if r["agent"] in AGENTS else 99, r["distractors"]))
    out = [
        f"Seed {seed}, the paper's eight conditions × {n} trials = {8 * n} trials per agent and D "
        f"(`experiments/distractors/distractor_comparison.py`). *Successes (far)*: √trace Σ ≤ 10 mm within 35 "
        f"readings "
        f"(of which far: the estimate more than {FAR_ERROR_MM:g} mm from the target). *Far on a distractor*: of the "
        f"far ones, those whose estimate is nearer a distractor's centre than the target's. *Readings*: mean over "
        f"successes / median over all trials (a failure counts 35). *Error*: median over successes. "
        f"*Decision*: median ms per decision on the shared 2-core machine.",
        "",
        *markdown_table(
            (
                "Agent",
                "D",
                "Successes (far)",
                "Far on a distractor",
                "Readings mean succ. / median all",
                "Error median mm",
                "Decision ms",
            ),
            [
                (
                    r["agent"],
                    r["distractors"],
                    f"{r['successes']}/{r['trials']} ({r['far_successes']})",
                    r["far_near_distractor"],
                    f"{_f(r['readings_mean_success'], 2)} / {_f(r['readings_median_all'])}",
                    _f(r["error_median_mm"]),
                    _f(r["decision_ms_median"], 1),
                )
                for r in ordered
            ],
        ),
    ]
    return "\n".join(out) + "\n"


def plot(rows: list[dict], n: int, path: Path) -> None:
    """Mean readings of the successes and far successes against D, one line per agent."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    agents = [a for a in AGENTS if any(r["agent"] == a for r in rows)]
    for a in agents:
        rs = sorted((r for r in rows if r["agent"] == a), key=lambda r: r["distractors"])
        d = [r["distractors"] for r in rs]
        style = "-o" if a in (EEDIAgent.name, InfotaxisAgent.name, MinVarianceAgent.name) else "--s"
        axes[0].plot(d, [r["readings_mean_all"] for r in rs], style, label=a)
        axes[1].plot(d, [r["far_successes"] / max(r["trials"], 1) for r in rs], style, label=a)
    axes[0].set(
        xlabel="distractors D",
        ylabel="mean readings (all trials, failure = 35)",
        title=f"readings to localise ({8 * n} trials per point)",
    )
    axes[1].set(
        xlabel="distractors D",
        ylabel=f"far successes (error > {FAR_ERROR_MM:g} mm) / trials",
        title="successes on the wrong place",
    )
    for ax in axes:
        ax.set_xticks(sorted({r["distractors"] for r in rows}))
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--agents", default=",".join(AGENTS))
    p.add_argument("--distractors", default=",".join(map(str, DISTRACTORS)))
    p.add_argument("--trials", type=int, default=50, help="trials per condition (the last round)")
    p.add_argument("--rounds", default="2,5,10,25,50", help="trial counts filled in turn (resumable)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="results/distractors")
    p.add_argument("--deadline", default=None, help="stop starting new work after this UTC time (HH:MM)")
    p.add_argument("--table", default=None)
    p.add_argument("--plot", default=None)
    p.add_argument("--report-only", action="store_true", help="only summarise what is in --out")
    a = p.parse_args()
    check_output_options(p, files={"--table": a.table, "--plot": a.plot}, folders={"--out": a.out})
    agents = [s for s in a.agents.split(",") if s]
    ds = [int(s) for s in a.distractors.split(",")]
    rounds = sorted({int(s) for s in a.rounds.split(",") if int(s) <= a.trials} | {a.trials})
    deadline = None
    if a.deadline:
        hh, mm = (int(v) for v in a.deadline.split(":"))
        now = time.gmtime()
        deadline = calendar.timegm((now.tm_year, now.tm_mon, now.tm_mday, hh, mm, 0))
    out = Path(a.out)
    if not a.report_only:
        run(agents, ds, rounds, a.seed, out, deadline)
    n, rows = summarize(agents, ds, out)
    text = table_md(n, rows, a.seed)
    if EEDIAgent.name in agents and n:
        text += "\n" + "\n".join(paired(agents, ds, out, n)) + "\n"
    print(text)
    out.mkdir(parents=True, exist_ok=True)
    (out / "comparison.json").write_text(json.dumps({"trials_per_condition": n, "rows": rows}, indent=1))
    written = [out / "comparison.json"]
    if a.table:
        Path(a.table).write_text(text, encoding="utf-8")
        written.append(Path(a.table))
    if a.plot and n:
        plot(rows, n, Path(a.plot))
        written.append(Path(a.plot))
    for path in written:
        print(f"wrote: {path}", file=sys.stderr)


if __name__ == "__main__":
    main()
