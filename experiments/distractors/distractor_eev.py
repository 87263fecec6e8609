"""The EEV of a target with distractors: the target alone, the distractors alone, and their superposition.

The noise-free reading (V) over carriage positions in the allowed box, for ``--condition``'s sphere at the
tank centre and ``--distractors`` objects drawn by :class:`electroloc_gym.world.distractors.DistractorDraw` from
``--seed`` (validation seeds 101, 102), the third panel being
:func:`electroloc_gym.world.distractors.superposed_reading_V` (the reading the robot sees; the agent's sensor
model knows only the first panel). Black contours: |Φ| at 2σ of the reading noise; outlines: the
objects' footprints (target dashed).

    python experiments/distractors/distractor_eev.py [--condition fresh-steel-12.7] [--distractors 2] [--seed 101]
        [--out docs/distractor_eev.png]
"""

from __future__ import annotations

import argparse

import numpy as np

from electroloc_gym.utils.fileio import check_output_options
from electroloc_gym.world.conditions import get_condition
from electroloc_gym.world.distractors import MAX_DISTRACTORS, DistractorDraw, DistractorSet, superposed_reading_V


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--condition", default="fresh-steel-12.7")
    parser.add_argument("--distractors", type=int, default=2, help=f"D, 1–{MAX_DISTRACTORS}")
    parser.add_argument("--seed", type=int, default=101)
    parser.add_argument("--out", default="docs/distractor_eev.png")
    args = parser.parse_args()
    check_output_options(parser, files={"--out": args.out})
    if not 1 <= args.distractors <= MAX_DISTRACTORS:
        parser.error(f"--distractors must be in [1, {MAX_DISTRACTORS}]")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cond = get_condition(args.condition)
    target = np.zeros(2)
    layout = DistractorDraw(count=args.distractors).draw(cond, target, np.random.default_rng(args.seed))
    h = cond.allowed_half_width_mm
    grid = np.arange(-h, h + 1e-9, 1.0)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    carriage = np.stack([gx, gy], axis=-1)
    alone = superposed_reading_V(cond, target, DistractorSet(), carriage)
    others = np.clip(layout.reading_V(cond, carriage), -cond.saturation_V, cond.saturation_V)
    both = superposed_reading_V(cond, target, layout, carriage)
    vmax = float(max(np.abs(alone).max(), np.abs(both).max()))
    thr = 2.0 * cond.noise_std_V
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 4.4))
    titles = ("target alone (the agent's model)", f"{len(layout)} distractors alone", "the reading: superposed")
    for ax, phi, title in zip(axes, (alone, others, both), titles):
        im = ax.pcolormesh(grid, grid, phi.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, shading="auto")
        if thr < np.abs(phi).max():
            ax.contour(grid, grid, np.abs(phi).T, levels=[thr], colors="k", linewidths=0.8)
        ax.add_patch(plt.Circle(target, cond.target.radius_mm, fill=False, ls="--", color="k"))
        for o in layout.objects:
            ax.add_patch(plt.Circle(o.xy_mm, o.radius_mm, fill=False, color="g"))
            ax.annotate(
                f"{o.shape} {o.diameter_mm:g} mm {o.material}",
                o.xy_mm,
                fontsize=7,
                color="g",
                xytext=(0, o.radius_mm + 3),
                textcoords="offset points",
                ha="center",
            )
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("carriage x (mm)")
    axes[0].set_ylabel("carriage y (mm)")
    fig.colorbar(im, ax=axes, label="noise-free reading Φ (V)", shrink=0.85)
    fig.suptitle(
        f"{args.condition}, target at the centre, distractors drawn with seed {args.seed}; black: |Φ| = 2σ", fontsize=10
    )
    fig.savefig(args.out, dpi=100)
    print(
        f"wrote {args.out}: "
        + "; ".join(f"{o.shape} {o.diameter_mm:g} mm {o.material} at {o.xy_mm}" for o in layout.objects)
    )


if __name__ == "__main__":
    main()
