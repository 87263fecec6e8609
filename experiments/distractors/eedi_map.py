"""The expected information density eedi follows, and the carriage's path, along one episode.

One ElectroLoc-v0 episode (``--condition``, ``--seed``, calibrated sensor model) run by ``eedi``; after each
of the first ``--panels`` readings the panel shows the EID the agent computed for its next move
(``last_density``, 1/mm², on its grid), the belief's particles, the carriage's path so far and the
true target (for the reader; the agent never sees it). The EID concentrates on the ring of carriage
positions where the reading is steepest in the believed target's position, and the SMC law drives
the path around it.

    python experiments/distractors/eedi_map.py [--condition fresh-steel-12.7] [--seed 101] [--panels 4]
        [--out docs/eedi_map.png]
"""

from __future__ import annotations

import argparse

from electroloc_gym.utils.runtime import pin_threads

pin_threads()

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.baselines.eedi import EEDIAgent  # noqa: E402
from electroloc_gym.protocol import MAX_STEP_MM  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--condition", default="fresh-steel-12.7")
    parser.add_argument("--seed", type=int, default=101, help="env and agent seed (validation seeds: 101, 102)")
    parser.add_argument("--panels", type=int, default=4, help="readings shown (one panel each), 1–8")
    parser.add_argument("--out", default="docs/eedi_map.png")
    args = parser.parse_args()
    check_output_options(parser, files={"--out": args.out})
    if not 1 <= args.panels <= 8:
        parser.error("--panels must be in [1, 8]")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env = gym.make(PAPER_ENV_ID, condition=args.condition)
    obs, _ = env.reset(seed=args.seed)
    agent = make_agent(EEDIAgent.name, seed=args.seed)
    agent.reset(env)
    core = env.unwrapped
    h = core.condition.allowed_half_width_mm
    fig, axes = plt.subplots(1, args.panels, figsize=(3.2 * args.panels, 3.4), squeeze=False)
    for k, ax in enumerate(axes[0]):
        particles = np.asarray(core.belief.particles).copy()
        path = core.path_mm.copy()
        spread = core.belief.spread()
        action, _ = agent.predict(obs)
        grid, eid = agent.last_grid_mm, agent.last_density
        n = int(round(np.sqrt(len(grid))))
        ax.imshow(eid.reshape(n, n).T, origin="lower", extent=(-h, h, -h, h), cmap="magma")
        ax.scatter(particles[::5, 0], particles[::5, 1], s=1, c="c", alpha=0.4, lw=0)
        ax.plot(path[:, 0], path[:, 1], "w.-", lw=1, ms=4)
        nxt = path[-1] + np.asarray(action, dtype=np.float64) * MAX_STEP_MM
        ax.annotate("", xy=nxt, xytext=path[-1], arrowprops={"arrowstyle": "->", "color": "lime"})
        ax.plot(*core.target_mm, "g+", ms=10, mew=2)
        ax.set_title(f"reading {core.n_observations}: spread {spread:.0f} mm", fontsize=9)
        ax.set_xlim(-h, h)
        ax.set_ylim(-h, h)
        ax.set_xticks([])
        ax.set_yticks([])
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            for extra in axes[0][k + 1 :]:
                extra.axis("off")
            break
    fig.suptitle(
        f"{EEDIAgent.name} on {args.condition} (seed {args.seed}): EID (colour), particles (cyan), path (white), "
        "next move (green arrow), target (+)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
