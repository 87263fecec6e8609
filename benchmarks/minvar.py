"""min-var decision cost: vectorised Algorithm 1 vs a literal loop, and 256 voters vs all voters.

Prints, for M = 2500 particles and C = 16 options on belief states taken from real min-var episodes:

* the decision time with all particles voting and with ``--voters`` (256) voting, for both float32
  kernels ("difference", "expanded"), beside the numpy float32 ``exp`` floor (M·C·voters
  exponentials at this machine's measured exp throughput) and their ratio to it;
* the decision time of each vote form at ``--voters`` (Algorithm 1's resample, drawn from its
  central-limit distribution; the literal roulette-wheel resample; the expected variance), the
  whole decision as the agent makes it (options, sensor-model means, vote);
* the literal per-particle loop
  (:func:`electroloc_gym.baselines.min_variance_reference.literal_predicted_variances`) timed on a
  small M and scaled by (2500/M)² (M·M·C likelihoods in Python), and the speed-up;
* how often 256 voters choose the same option as all 2500 (and, when they differ, how much worse the
  chosen option's all-voter vote count is).

Numeric libraries are pinned to one thread (two threads on a busy 2-core machine run slower).
Timings are best-of-N to resist a busy machine.

    python benchmarks/minvar.py [--states 30] [--voters 256] [--literal-m 40]
"""

from __future__ import annotations

import argparse
import time

from electroloc_gym.utils.runtime import pin_threads

pin_threads()  # one thread per numeric library unless $ELECTROLOC_THREADS says otherwise

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import electroloc_gym  # noqa: E402,F401
from electroloc_gym.baselines.agent import make_agent, move_bounds_mm, sample_options_mm  # noqa: E402
from electroloc_gym.baselines.min_variance import (  # noqa: E402
    VOTES,  # noqa: E402
    MinVarianceAgent,
    choose_voters,
    count_votes,
    option_means_stds,
    predicted_variances,
)
from electroloc_gym.baselines.min_variance_reference import literal_predicted_variances  # noqa: E402
from electroloc_gym.protocol import N_PARTICLES  # noqa: E402
from electroloc_gym.registry import PAPER_ENV_ID  # noqa: E402


def best_of(fn, repeats: int = 5) -> float:
    """Best wall time of ``repeats`` calls, s."""
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def collect_states(n_states: int, n_particles: int, seed: int = 0) -> list[dict]:
    """Belief snapshots along min-var episodes over the eight presets (calibrated model)."""
    from electroloc_gym.world.conditions import PRESET_NAMES

    states = []
    rng = np.random.default_rng(seed)
    k = 0
    while len(states) < n_states:
        cond = PRESET_NAMES[k % len(PRESET_NAMES)]
        env = gym.make(PAPER_ENV_ID, condition=cond, n_particles=n_particles)
        obs, _ = env.reset(seed=1000 + k)
        agent = make_agent(MinVarianceAgent.name, seed=k)
        agent.reset(env)
        for _ in range(int(rng.integers(0, 6))):
            action, _ = agent.predict(obs)
            obs, _, term, trunc, _ = env.step(action)
            if term or trunc:
                break
        core = env.unwrapped
        options = sample_options_mm(np.random.default_rng(k), *move_bounds_mm(core), 16)
        mean, std = option_means_stds(core.sensor_model, core.belief.particles, core.position_mm + options)
        states.append(
            {
                "core": core,
                "particles": core.belief.particles.copy(),
                "options": options,
                "mean": mean,
                "std": std,
                "condition": cond,
            }
        )
        k += 1
    return states


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--states", type=int, default=30, help="belief states for the agreement rate")
    ap.add_argument("--voters", type=int, default=256)
    ap.add_argument("--particles", type=int, default=N_PARTICLES)
    ap.add_argument("--literal-m", type=int, default=200, help="M of the timed literal loop")
    args = ap.parse_args()
    m, c = args.particles, 16

    # exp floor: float32 exp throughput on this machine.
    x = -np.random.default_rng(0).random(4_000_000, dtype=np.float32) * 50
    t_exp = best_of(lambda: np.exp(x, out=np.empty_like(x))) / x.size
    print(f"numpy float32 exp: {1e-9 / t_exp:.2f} G/s")

    states = collect_states(args.states, m)
    s0 = states[0]
    core0 = s0["core"]
    t_means = best_of(lambda: option_means_stds(core0.sensor_model, s0["particles"], core0.position_mm + s0["options"]))
    print(f"\nDecision time at M = {m}, C = {c} (plus the sensor-model means of all options: {t_means * 1e3:.1f} ms)")
    print(f"{'voters':>7} {'kernel':>11} {'ms/decision':>12} {'exp floor ms':>13} {'ratio to floor':>15}")
    results = {}
    for n_vot in (m, args.voters):
        voters = choose_voters(np.random.default_rng(0), m, n_vot)
        floor = n_vot * m * c * t_exp
        for kernel in ("difference", "expanded"):

            def call(voters=voters, kernel=kernel) -> None:
                predicted_variances(s0["particles"], None, s0["mean"], s0["std"], voters, kernel=kernel)

            t = best_of(call, repeats=3 if n_vot == m else 7)
            results[(n_vot, kernel)] = t
            print(f"{n_vot:>7} {kernel:>11} {t * 1e3:>12.1f} {floor * 1e3:>13.1f} {t / floor:>15.2f}")

    # The whole decision per vote form, as the agent makes it, on the collected belief states.
    print(
        f"\nWhole min-var decision at {args.voters} voters (median over {len(states)} belief states; floor = "
        f"the exponentials alone, {args.voters * m * c * t_exp * 1e3:.1f} ms)"
    )
    for vote in VOTES:
        agent = make_agent(f"{MinVarianceAgent.name}[vote={vote!r},n_voters={args.voters}]", seed=0)
        times = []
        for s in states[: (5 if vote == "multinomial" else len(states))]:
            agent._env = s["core"]  # bind without resetting the env: the state's belief is kept
            times.append(best_of(agent.choose_move_mm, repeats=1 if vote == "multinomial" else 3))
        print(f"  vote={vote:<12} {np.median(times) * 1e3:8.1f} ms")

    # Literal loop on a small M, scaled by (M / m_small)² (voters × particles × options calls).
    ms = args.literal_m
    core = states[0]["core"]
    small = states[0]["particles"][np.random.default_rng(1).choice(m, ms, replace=False)]
    pos = core.position_mm + states[0]["options"]
    t_lit = best_of(lambda: literal_predicted_variances(core.sensor_model, small, None, pos, np.arange(ms)), repeats=2)
    t_lit_scaled = t_lit * (m / ms) ** 2
    best_all = min(results[(m, "difference")], results[(m, "expanded")])
    print(
        f"\nLiteral loop (Algorithm 1 as written, one sensor-model call per particle): {t_lit:.2f} s at M = {ms}, "
        f"scaled to M = {m}: {t_lit_scaled:.0f} s per decision"
    )
    best_sub = min(results[(args.voters, "difference")], results[(args.voters, "expanded")])
    print(
        f"speed-up of the vectorised vote (all voters): {t_lit_scaled / best_all:,.0f}×; "
        f"with {args.voters} voters: {t_lit_scaled / best_sub:,.0f}×"
    )

    # Agreement of the subset vote with the all-voter vote.
    same, worse = 0, []
    for i, s in enumerate(states):
        full = predicted_variances(s["particles"], None, s["mean"], s["std"], np.arange(m))
        best_full, votes_full = count_votes(full)
        sub = choose_voters(np.random.default_rng(100 + i), m, args.voters)
        best_sub, _ = count_votes(full[np.searchsorted(np.arange(m), sub)])
        same += best_sub == best_full
        if best_sub != best_full:
            worse.append(votes_full[best_sub] / votes_full[best_full])
    print(
        f"\n{args.voters} voters choose the all-voter option in {same}/{len(states)} decisions "
        f"({100 * same / len(states):.0f} %)"
        + (
            f"; when they differ, the chosen option still has "
            f"{100 * np.mean(worse):.0f} % of the winner's all-voter votes"
            if worse
            else ""
        )
    )


if __name__ == "__main__":
    main()
