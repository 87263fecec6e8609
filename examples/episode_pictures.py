"""Draw one episode of any agent: a grid of belief snapshots (PNG) and an animation (GIF).

    python examples/episode_pictures.py --agent min-var --seed 0 --out min-var.png --gif min-var.gif
    python examples/episode_pictures.py --env ElectroLocGlobal-v0 --agent min-var --out global.png

``--agent`` is anything the benchmark accepts: ``rnd-wlk``, ``min-var``, ``zero-crossing`` (slow: hundreds of
readings), options in brackets (``min-var[n_voters=None]``), or ``random`` for uniform random moves.
The docs' pictures (``docs/demo.png``, ``docs/demo.gif``) are this script's output for
``--agent min-var --seed 0``.
"""

from __future__ import annotations

import argparse

import gymnasium as gym

import electroloc_gym  # noqa: F401  (registers the env ids)
from electroloc_gym.baselines import make_agent
from electroloc_gym.demo import check_output_path, plot_episode, record_episode, save_gif
from electroloc_gym.registry import env_entry
from electroloc_gym.utils.fileio import save_figure_atomic
from electroloc_gym.utils.runtime import pin_threads


def main(argv: list[str] | None = None) -> dict:
    """Record one episode and write its pictures; returns the final info dict."""
    p = argparse.ArgumentParser(
        description=__doc__.split("\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    p.add_argument("--env", default="ElectroLoc-v0", choices=list(electroloc_gym.ENV_IDS))
    p.add_argument("--condition", default="fresh-steel-12.7", help="preset name (ElectroLoc-v0 only)")
    p.add_argument("--agent", default="min-var", help="random, or a baseline name with optional [options]")
    p.add_argument("--seed", type=int, default=0, help="seed of the episode and of the agent")
    p.add_argument("--out", default="episode.png", help="grid of belief snapshots")
    p.add_argument("--gif", default=None, help="also write the episode as a GIF")
    p.add_argument("--fps", type=float, default=2.5, help="GIF frames per second")
    args = p.parse_args(argv)
    try:
        for name in ("out", "gif"):
            if getattr(args, name) is not None:
                check_output_path(name, getattr(args, name))
        agent = None if args.agent == "random" else make_agent(args.agent, seed=args.seed)
    except ValueError as exc:
        p.error(str(exc))
    pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise
    kwargs = {"condition": args.condition} if env_entry(args.env).takes("condition") else {}
    env = gym.make(args.env, render_mode="rgb_array" if args.gif else None, **kwargs)
    episode = record_episode(env, seed=args.seed, agent=agent, frames=args.gif is not None)
    env.close()
    save_figure_atomic(plot_episode(episode), args.out)
    if args.gif:
        save_gif(episode.frames, args.gif, fps=args.fps)
    info = episode.final_info
    print(
        f"{args.agent}: {info['n_observations']} observations, {episode.outcome(info)}, "
        f"error {info['error_mm']:.1f} mm; wrote {args.out}" + (f" and {args.gif}" if args.gif else "")
    )
    return info


if __name__ == "__main__":
    main()
