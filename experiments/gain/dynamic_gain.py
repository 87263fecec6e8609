"""When does choosing the amplifier gain pay? min-var over moves × gains against min-var at the preset gain.

§7 proposes a high gain for long-range detection and a low one for precise localisation near the
target. Under the paper's own noise model (all noise referred to the electrodes, σ = G·σ_s) a reading
at f·G carries exactly the information of one at G until it clips at ±10 V, so the gain can only
lose (by saturating). It pays when a noise that does not scale with the gain (the data-acquisition
card's own, ``Amplifier.output_noise_mV``) is comparable to the amplified tank noise — a quieter tank
(§7's shielding, noise factor 1/32) — and the signal near the target is strong enough to clip at the
high gain. This script runs both controllers on the paper's eight conditions in three tanks:

* ``paper``: the default simulation (noise factor 1, no output noise);
* ``quiet``: noise factor 1/32, no output noise;
* ``quiet+daq``: noise factor 1/32 and an output noise of ``--daq-mV`` (default 1 mV RMS);
* ``paper+daq``: noise factor 1 and an output noise of ``--daq-mV`` (e.g. 100 mV, comparable to the
  amplified tank noise G·σ_s = 44–692 mV of the presets: a hypothetical card, where the gain matters).

    python experiments/gain/dynamic_gain.py --trials 20 --seed 0 --plot docs/dynamic_gain.png

Trial k of a condition uses the benchmark's seeds (:func:`electroloc_gym.bench.config.trial_seeds`), so
both controllers meet the same starts and noise draws.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent  # noqa: E402
from electroloc_gym.baselines.min_variance import MinVarianceAgent  # noqa: E402
from electroloc_gym.baselines.rollout import run_episode  # noqa: E402
from electroloc_gym.bench.config import trial_seeds  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options  # noqa: E402
from electroloc_gym.utils.markdown import markdown_table  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, Condition, get_condition  # noqa: E402

AGENTS = (MinVarianceAgent.name, f"{MinVarianceAgent.name}[gain=preset]")


def tank(condition: Condition, setting: str, daq_mV: float) -> Condition:
    """The condition in one of the three tanks of the module docstring."""
    if setting == "paper":
        return condition
    amp = dataclasses.replace(
        condition.amplifier,
        noise_factor=1.0 if setting == "paper+daq" else 1.0 / 32.0,
        output_noise_mV=daq_mV if setting.endswith("+daq") else 0.0,
    )
    return condition.replace(amplifier=amp)


def run(
    setting: str, levels: tuple[float, ...], trials: int, seed: int, daq_mV: float, bar: tqdm
) -> dict[str, dict[str, list[tuple[bool, int]]]]:
    """{agent: {condition: [(success, readings), ...]}}."""
    out: dict[str, dict[str, list[tuple[bool, int]]]] = {a: {} for a in AGENTS}
    for name in PRESET_NAMES:
        env = gym.make(PAPER_ENV_ID, condition=tank(get_condition(name), setting, daq_mV), gain_levels=levels)
        for spec in AGENTS:
            agent = make_agent(spec)
            rows = out[spec].setdefault(name, [])
            for k in range(trials):
                env_seed, agent_seed = trial_seeds(seed, name, k)
                ep = run_episode(env, agent, env_seed, agent_seed=agent_seed)
                rows.append((bool(ep.terminated and ep.info["success"]), int(ep.info["n_observations"])))
                bar.update()
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trials", type=int, default=20, help="trials per condition and controller")
    p.add_argument("--seed", type=int, default=0, help="root seed of the trial seeds")
    p.add_argument("--levels", type=float, nargs="+", default=[1.0, 4.0, 16.0], help="gain factors")
    p.add_argument("--daq-mV", type=float, default=1.0, help="output noise of the quiet+daq tank, mV RMS")
    p.add_argument("--settings", nargs="+", default=["paper", "quiet", "quiet+daq"])
    p.add_argument("--plot", default=None, help="write a figure of the median readings per condition")
    args = p.parse_args()
    check_output_options(p, files={"--plot": args.plot})
    levels = tuple(args.levels)
    results = {}
    with tqdm(total=len(args.settings) * len(PRESET_NAMES) * len(AGENTS) * args.trials, desc="episodes") as bar:
        for setting in args.settings:
            results[setting] = run(setting, levels, args.trials, args.seed, args.daq_mV, bar)
    print(
        f"gain levels {levels} × the preset gain; {args.trials} trials per condition, seed {args.seed}; "
        f"median readings (successes) per condition, then the mean of the eight medians"
    )
    for setting, res in results.items():
        print(f"\n{setting}:")
        rows = [
            (
                name,
                *(f"{np.median([n for _, n in res[a][name]]):.1f} ({sum(s for s, _ in res[a][name])})" for a in AGENTS),
            )
            for name in PRESET_NAMES
        ]
        means = [np.mean([np.median([n for _, n in res[a][c]]) for c in PRESET_NAMES]) for a in AGENTS]
        succ = [sum(s for c in PRESET_NAMES for s, _ in res[a][c]) for a in AGENTS]
        rows.append(("mean of medians (successes)", *(f"{m:.2f} ({s})" for m, s in zip(means, succ))))
        for line in markdown_table(("condition", *AGENTS), rows):
            print(line)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(results), figsize=(4.2 * len(results), 3.8), sharey=True)
        axes = np.atleast_1d(axes)
        x = np.arange(len(PRESET_NAMES))
        for ax, (setting, res) in zip(axes, results.items(), strict=True):
            for j, a in enumerate(AGENTS):
                med = [np.median([n for _, n in res[a][c]]) for c in PRESET_NAMES]
                ax.bar(x + (j - 0.5) * 0.38, med, 0.38, label=a)
            ax.set_xticks(
                x, [c.replace("fresh-", "f-").replace("salt-", "s-") for c in PRESET_NAMES], rotation=60, fontsize=7
            )
            ax.set_title(setting)
        axes[0].set_ylabel("median readings to localise")
        axes[0].legend(fontsize=7)
        fig.suptitle(f"min-var choosing the gain (× {', '.join(f'{g:g}' for g in levels)}) vs the preset gain")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"wrote: {args.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()
