"""Does a learned policy use the amplifier gain when the tank makes the gain matter?

In the default simulation a reading at f·G carries exactly the information of one at G until it clips
(docs/extensions.md, "Dynamic gain"), so no policy can gain anything from choosing the gain. With a
noise that does not scale with the gain — a data-acquisition card's own, ``Amplifier.output_noise_mV``
— a high gain lifts a weak far signal above that floor and a low one keeps a near signal out of the
±10 V clip. This script compares, on one condition with such a floor:

* three PPO policies trained at one fixed gain each (f·G for every f of ``--levels``), and
* one PPO policy trained with ``gain_levels=levels``, choosing the gain of every reading,

with min-var choosing over moves × gains and min-var at the preset gain, on the same seeded trials
(the benchmark's per-trial seeds of ``--condition``). Train the four policies first (each ~3 min on one
core; they are not shipped, they are this experiment's):

    python experiments/gain/learned_gain.py --print-train-commands | bash
    python experiments/gain/learned_gain.py --trials 50 --seed 0
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shlex

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.bench.agents import make_bench_agent  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import Condition, get_condition  # noqa: E402

TRAIN_SEED = 7000


def floor_tank(name: str, output_noise_mV: float, factor: float = 1.0) -> Condition:
    """Preset ``name`` with a gain-independent output noise, its amplifier gain × ``factor``."""
    c = get_condition(name)
    amp = dataclasses.replace(c.amplifier.with_gain(c.amplifier.gain * factor), output_noise_mV=output_noise_mV)
    suffix = f"-out{output_noise_mV:g}mV" + (f"-x{factor:g}" if factor != 1.0 else "")
    return c.replace(name=c.name + suffix, amplifier=amp)


def runs(args: argparse.Namespace) -> list[tuple[str, dict[str, object], str]]:
    """(label, env kwargs, run folder) of the four policies."""
    out = []
    for k, f in enumerate(args.levels):
        out.append(
            (
                f"ppo fixed ×{f:g}",
                {"condition": floor_tank(args.condition, args.output_noise_mV, f)},
                f"runs/gain-floor-{args.condition}-fixed{f:g}-s{TRAIN_SEED + k}",
            )
        )
    out.append(
        (
            "ppo choosing the gain",
            {"condition": floor_tank(args.condition, args.output_noise_mV), "gain_levels": list(args.levels)},
            f"runs/gain-floor-{args.condition}-choice-s{TRAIN_SEED + len(args.levels)}",
        )
    )
    return out


def train_commands(args: argparse.Namespace) -> list[str]:
    lines = []
    for k, (_, kwargs, folder) in enumerate(runs(args)):
        kv = [f"condition={json.dumps(kwargs['condition'].to_dict())}"]  # JSON is YAML's flow syntax
        if "gain_levels" in kwargs:
            kv.append(f"gain_levels={json.dumps(kwargs['gain_levels'])}")
        cmd = [
            "python",
            "-m",
            "electroloc_gym.train",
            "--algo",
            "ppo",
            "--env",
            PAPER_ENV_ID,
            "--env-kwargs",
            *kv,
            "observation=belief",
            "randomize_target=true",
            "--timesteps",
            str(args.timesteps),
            "--n-envs",
            "16",
            "--vec-env",
            "native",
            "--seed",
            str(TRAIN_SEED + k),
            "--hyperparams",
            "electroloc_gym/train/hyperparams/ppo.yml",
            "--out",
            folder,
            "--eval-freq",
            "50000",
            "--eval-episodes",
            "64",
            "--eval-env-kwargs",
            "randomize_target=false",
            "--no-progress",
        ]
        lines.append(" ".join(shlex.quote(a) for a in cmd))
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--condition", default="fresh-steel-12.7", help="the preset the tank is built on")
    p.add_argument("--output-noise-mV", type=float, default=100.0, help="the gain-independent noise, mV RMS")
    p.add_argument("--levels", type=float, nargs="+", default=[1.0, 4.0, 16.0], help="gain factors")
    p.add_argument("--timesteps", type=int, default=300_000, help="training steps per policy")
    p.add_argument("--trials", type=int, default=50, help="evaluation trials per agent")
    p.add_argument("--seed", type=int, default=0, help="root seed of the trial seeds")
    p.add_argument("--print-train-commands", action="store_true", help="print the four training commands")
    args = p.parse_args()
    args.levels = tuple(args.levels)
    if args.print_train_commands:
        print("\n".join(train_commands(args)))
        return
    gain_env = {"condition": floor_tank(args.condition, args.output_noise_mV), "gain_levels": args.levels}
    agents = [(label, f"{folder}/best", kwargs) for label, kwargs, folder in runs(args)]
    agents += [
        ("min-var choosing the gain", MinVarianceAgent.name, gain_env),
        ("min-var at the preset gain", f"{MinVarianceAgent.name}[gain=preset]", gain_env),
    ]
    rows = []
    for label, spec, kwargs in tqdm(agents, desc="agents"):
        agent = make_bench_agent(spec)
        env = gym.make(PAPER_ENV_ID, **kwargs)
        res = []
        for k in range(args.trials):
            env_seed, agent_seed = trial_seeds(args.seed, args.condition, k)
            ep = run_episode(env, agent, env_seed, agent_seed=agent_seed)
            res.append((bool(ep.terminated), int(ep.info["n_observations"])))
        n = np.array([r for _, r in res])
        rows.append((label, sum(s for s, _ in res), np.median(n), n.mean()))
    print(
        f"{args.condition} with a {args.output_noise_mV:g} mV output noise, gain levels {args.levels} × G; "
        f"{args.trials} trials, seed {args.seed} (readings: failures count at the cap)"
    )
    for line in markdown_table(
        ("agent", "successes", "median readings", "mean readings"),
        [(label, f"{s}/{args.trials}", f"{med:.1f}", f"{mean:.2f}") for label, s, med, mean in rows],
    ):
        print(line)


if __name__ == "__main__":
    main()
