"""Every agent on the moving target's benchmark in one table: tracking error IQM, capture, P(improvement over min-var).

    python experiments/track/track_table.py experiments/learned/results/ElectroLocTrack-v0/_baselines/bench \
        --learned "sac=experiments/learned/results/ElectroLocTrack-v0/sac/seed-*/bench" \
        --reference min-var --out experiments/track/results/track_table.md

Reads benchmark folders of ``electroloc bench --env track`` (their ``trials.jsonl`` or ``trials.jsonl.gz``, the
package's record reader) on the same trials (seed 0, the eight conditions × 50). A controller is one run; a
learned label pools its seeds' runs (each seed's export benchmarked on the same trials). Per agent, over its
trials (the episode's tracking error: the belief mean's distance to the target averaged over the second half, mm):

* **IQM** of the tracking error, with a 95 % bootstrap interval stratified by condition (the trials of each
  condition resampled, 2 000 replications, seeded);
* **capture**: the share of trials that end with the carriage within 10 mm of the target, with its 95 % Wilson
  interval;
* **P(improvement over the reference)**: the probability that a trial of the agent tracks with a lower error
  than a trial of the reference agent in the same condition (the Mann–Whitney probability, ties counted half,
  averaged over the conditions: rliable's probability of improvement with trials in the place of runs), with
  the same stratified bootstrap interval. The trials are not paired one to one: the two agents' episodes start
  alike (the trial's seed) but the filter's motion model draws from the episode's stream, so the prey swims
  differently under each belief.

Learned rows from ``learned_report.py`` (rliable over seeds × conditions) say how the seeds spread; this table puts
every agent, learned or not, on one footing.
"""

from __future__ import annotations

import argparse
import glob
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.bench.records import read_trials
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import atomic_write_text, check_output_options

REPS = 2000
#: The moving target's declared score (the tracking error, mm) and rate (the capture), read from its task.
SCORE = env_entry("ElectroLocTrack-v0").task_class.metrics.score
RATE = env_entry("ElectroLocTrack-v0").task_class.metrics.rate


def _trials_file(folder: Path) -> Path:
    for name in ("trials.jsonl", "trials.jsonl.gz"):
        if (folder / name).is_file():
            return folder / name
    raise ValueError(f"{folder}: no trials.jsonl(.gz) (a benchmark folder of electroloc bench --env track)")


def load(folders: Sequence[Path], label: str | None = None) -> dict[str, dict[str, np.ndarray]]:
    """Agent → condition → (tracking errors mm, captured) arrays, pooled over ``folders`` (``label``: one agent)."""
    out: dict[str, dict[str, list[tuple[float, bool]]]] = {}
    for folder in folders:
        for r in read_trials(_trials_file(folder)):
            shape = r.get("shape") or {}
            if SCORE.key not in shape:
                raise ValueError(f"{folder}: a record without a {SCORE.label} (not a moving-target run)")
            agent = label or str(r["agent"])
            out.setdefault(agent, {}).setdefault(r["condition"], []).append(
                (float(shape[SCORE.key]), bool(shape[RATE.key]))
            )
    return {a: {c: np.asarray(v, dtype=float) for c, v in by.items()} for a, by in out.items()}


def _iqm(x: np.ndarray) -> float:
    return float(stats.trim_mean(x, 0.25))


def _p_lower(x: np.ndarray, y: np.ndarray) -> float:
    """P(a draw of x < a draw of y), ties half."""
    less = (x[:, None] < y[None, :]).mean()
    ties = (x[:, None] == y[None, :]).mean()
    return float(less + 0.5 * ties)


def row(
    agent: dict[str, np.ndarray], reference: dict[str, np.ndarray] | None, rng: np.random.Generator
) -> dict[str, Any]:
    """The statistics of one agent (module docstring): ``iqm``, ``iqm_ci`` and ``median`` of its score, ``count``,
    ``share`` and ``share_ci`` of its rate, ``p_improvement`` and its ``p_improvement_ci`` against ``reference``.
    """
    conditions = sorted(agent)
    err = np.concatenate([agent[c][:, 0] for c in conditions])
    cap = np.concatenate([agent[c][:, 1] for c in conditions])
    n, k = len(err), int(cap.sum())
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="wilson")

    def p_of(samples: dict[str, np.ndarray]) -> float | None:
        if reference is None:
            return None
        return float(np.mean([_p_lower(samples[c], reference[c][:, 0]) for c in conditions]))

    boot_iqm, boot_p = [], []
    for _ in range(REPS):
        draw = {c: agent[c][rng.integers(0, len(agent[c]), len(agent[c])), 0] for c in conditions}
        boot_iqm.append(_iqm(np.concatenate(list(draw.values()))))
        if reference is not None:
            ref = {c: reference[c][rng.integers(0, len(reference[c]), len(reference[c])), 0] for c in conditions}
            boot_p.append(float(np.mean([_p_lower(draw[c], ref[c]) for c in conditions])))
    out: dict[str, Any] = {
        "trials": n,
        "iqm": _iqm(err),
        "iqm_ci": [float(v) for v in np.percentile(boot_iqm, [2.5, 97.5])],
        "median": float(np.median(err)),
        "count": k,
        "share": k / n,
        "share_ci": [float(ci.low), float(ci.high)],
    }
    p = p_of({c: agent[c][:, 0] for c in conditions})
    if p is not None:
        out["p_improvement"] = p
        out["p_improvement_ci"] = [float(v) for v in np.percentile(boot_p, [2.5, 97.5])]
    return out


def markdown(rows: dict[str, dict[str, Any]], reference: str) -> str:
    lines = [
        f"| agent | trials | {SCORE.label} IQM, {SCORE.unit} [95 % CI] | median, {SCORE.unit} | "
        f"{RATE.label} [95 % CI] | P(lower {SCORE.label} than {reference}) [95 % CI] |",
        "|---|---|---|---|---|---|",
    ]
    for agent, r in rows.items():
        lo, hi = r["iqm_ci"]
        clo, chi = r["share_ci"]
        p = (
            f"{r['p_improvement']:.2f} [{r['p_improvement_ci'][0]:.2f}, {r['p_improvement_ci'][1]:.2f}]"
            if "p_improvement" in r
            else "–"
        )
        lines.append(
            f"| {agent} | {r['trials']} | {r['iqm']:.2f} [{lo:.2f}, {hi:.2f}] | "
            f"{r['median']:.2f} | {r['share']:.2f} [{clo:.2f}, {chi:.2f}] | {p} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="track_table.py", description=__doc__.splitlines()[0])
    p.add_argument("bench", nargs="+", type=Path, help="benchmark folders of controllers (every agent in them)")
    p.add_argument(
        "--learned",
        action="append",
        default=[],
        metavar="LABEL=GLOB",
        help="a learned label and the glob of its seeds' bench folders (pooled); repeatable",
    )
    p.add_argument("--reference", default="min-var", help="the agent P(improvement) is stated against")
    p.add_argument("--seed", type=int, default=0, help="the bootstrap's seed")
    p.add_argument("--out", type=Path, required=True, help="the markdown table to write (a .json beside it)")
    a = p.parse_args(argv)
    check_output_options(p, files={"--out": a.out}, suffixes={"--out": ("md",)})
    try:
        agents = load(a.bench)
        for spec in a.learned:
            label, sep, pattern = spec.partition("=")
            folders = sorted(Path(f) for f in glob.glob(pattern))
            if not sep or not label or not folders:
                raise ValueError(f"--learned {spec!r}: expected LABEL=GLOB matching bench folders")
            agents.update(load(folders, f"{label} ({len(folders)} seed{'s' if len(folders) > 1 else ''})"))
        if a.reference not in agents:
            raise ValueError(f"--reference {a.reference!r} is not among the agents: {sorted(agents)}")
    except ValueError as exc:
        p.error(str(exc))
    rng = np.random.default_rng(a.seed)
    rows = {name: row(agents[name], None if name == a.reference else agents[a.reference], rng) for name in agents}
    atomic_write_text(a.out, markdown(rows, a.reference))
    atomic_write_text(a.out.with_suffix(".json"), json.dumps(rows, indent=1) + "\n")
    print(markdown(rows, a.reference), end="")
    print(f"wrote {a.out} and {a.out.with_suffix('.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
