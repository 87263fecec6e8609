"""Figure of an ``electroloc bench --env unknown-target`` run: readings to localise, and the size estimates.

    python experiments/unknown_target/unknown_target_report.py results/bench_unknown --out docs/unknown_target.png

Left: median readings per condition and agent (failures count at the cap, as the table's medians).
Right: the radius estimate of every successful trial against the true radius (the paper's 6.35 and
19.05 mm spheres), marked by whether the material was identified; the dotted band is ±20 %.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from electroloc_gym.bench.stored_run import read_run_records
from electroloc_gym.utils.fileio import check_output_options
from electroloc_gym.world.conditions import PRESET_NAMES


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", help="the bench output folder (its config.json and trials.jsonl)")
    p.add_argument("--out", default="unknown_target.png", help="the PNG to write")
    args = p.parse_args()
    check_output_options(p, files={"--out": args.out})
    try:  # the folder as ``--resume`` reads it: its config, its records through their schema, current key names
        run = read_run_records(args.run)
    except ValueError as exc:  # one line naming the file
        p.exit(2, f"unknown_target_report: error: {exc}\n")
    for line in run.messages():
        print(f"unknown_target_report: set aside {line}", file=sys.stderr)
    recs = run.records
    agents = list(dict.fromkeys(r["agent"] for r in recs if r.get("table_layout", "table4") == "table4"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    x = np.arange(len(PRESET_NAMES))
    width = 0.8 / max(len(agents), 1)
    for j, a in enumerate(agents):
        med = [
            np.median([r["readings"] for r in recs if r["agent"] == a and r["condition"] == c] or [np.nan])
            for c in PRESET_NAMES
        ]
        ax.bar(x + (j - (len(agents) - 1) / 2) * width, med, width, label=a)
    ax.set_xticks(x, [c.replace("fresh-", "f-").replace("salt-", "s-") for c in PRESET_NAMES], rotation=60, fontsize=7)
    ax.set_ylabel("median readings (failures at the cap)")
    ax.set_title("readings to localise, sphere hidden")
    ax.legend(fontsize=7)
    rng = np.random.default_rng(0)
    for j, a in enumerate(agents):
        shapes = [r["shape"] for r in recs if r["agent"] == a and r["success"] and r.get("shape")]
        if not shapes:
            continue
        t = np.array([s["target_radius_mm"] for s in shapes])
        e = np.array([s["radius_estimate_mm"] for s in shapes])
        ok = np.array([s["material_correct"] for s in shapes], dtype=bool)
        jitter = t + (j - (len(agents) - 1) / 2) * 1.2 + rng.uniform(-0.3, 0.3, t.size)
        bx.scatter(jitter[ok], e[ok], s=8, alpha=0.5, label=f"{a} (material right)", color=f"C{j}")
        bx.scatter(jitter[~ok], e[~ok], s=22, marker="x", color=f"C{j}", label=f"{a} (material wrong)")
    for r0 in (6.35, 19.05):
        bx.plot([r0 - 3, r0 + 3], [r0, r0], "k-", lw=0.8)
        bx.fill_between([r0 - 3, r0 + 3], 0.8 * r0, 1.2 * r0, color="0.85", zorder=0)
    bx.set_xlabel("true radius (mm; agents offset for legibility)")
    bx.set_ylabel("radius estimate at success (mm)")
    bx.set_title("size estimates (grey: ±20 %)")
    bx.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
